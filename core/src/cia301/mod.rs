//! Layer 4, the CiA 301 communication services: one module per communication object, each a
//! sans-IO machine or codec that the [node](crate::node) composes.
//!
//! | Object | Module | Identifiers (predefined set) |
//! | --- | --- | --- |
//! | NMT module control, NMT state machine | [`nmt`] | 0x000 |
//! | Heartbeat producer and consumer (0x1016/0x1017) | [`heartbeat`] | 0x700 + node |
//! | Node and life guarding (0x100C/0x100D) | [`guarding`] | 0x700 + node (RTR) |
//! | SYNC producer and consumer (0x1005/0x1006/0x1019) | [`sync`] | 0x080 |
//! | TIME (time stamp object, 0x1012) | [`time_stamp`] | 0x100 |
//! | EMCY producer and consumer (0x1014/0x1015/0x1028) | [`emcy`] | 0x080 + node |
//! | SDO server and client: expedited, segmented, block | [`sdo`] | 0x580/0x600 + node |
//! | PDO engine, mapping and parameters | [`pdo`] | 0x180…0x500 + node |
//! | Multiplexed PDOs, scanner and dispatcher lists (0x1FA0/0x1FD0; `mpdo`) | `mpdo` | a PDO's |
//!
//! The timed services share one shape ([`service`]): `poll_timeout` for the next deadline,
//! `handle_timeout(now, &mut out)` writing frames and events into a [`service::ServiceOutput`].
//!
//! Everything here sits on the [object dictionary](crate::od) and the [frame](crate::frame)
//! primitives only: no service knows the node that composes it, and none knows about the master
//! or the ports. The crate root re-exports each module, so `duocan_core::sdo` is
//! `duocan_core::cia301::sdo` (and `duocan::sdo` in `duocan`, which re-exports the core).
//!
//! Each service is driven the same way, here the SDO client: a request gives a frame to send,
//! the server's answer goes in with the time it arrived, the result comes out as an event; with
//! no answer, the deadline it reported is where it aborts.
//!
//! ```
//! use duocan_core::sdo::{SdoClient, SdoOptions};
//! use duocan_core::{AbortCode, Duration, Frame, Id, Instant, Machine, NodeId};
//!
//! let mut client: SdoClient = SdoClient::new(1024);
//! let (node, opts) = (NodeId::must(5), SdoOptions::default().with_timeout(Duration::from_millis(100)));
//! // Read 0x1018 sub 1 (vendor-ID): an expedited upload request to node 5.
//! client.upload(Instant::ZERO, node, 0x1018, 1, opts)?;
//! let req = client.poll_transmit().unwrap();
//! assert_eq!((req.id(), req.data()), (Id::Standard(0x605), &[0x40, 0x18, 0x10, 1, 0, 0, 0, 0][..]));
//! // The node answers 3 ms later with four bytes.
//! let answer = Frame::from_array(Id::Standard(0x585), [0x43, 0x18, 0x10, 1, 0x23, 1, 0, 0]);
//! client.handle_frame(Instant::from_millis(3), &answer);
//! assert_eq!(client.poll_event().unwrap().data(), Some(&[0x23, 1, 0, 0][..]));
//!
//! // A second read that nobody answers: at its deadline the client aborts on the bus.
//! client.upload(Instant::from_millis(10), node, 0x1000, 0, opts)?;
//! let _request = client.poll_transmit();
//! let deadline = client.poll_timeout().unwrap();
//! assert_eq!(deadline, Instant::from_millis(110));
//! client.handle_timeout(deadline);
//! assert_eq!(client.poll_transmit().unwrap().data(), [0x80, 0, 0x10, 0, 0, 0, 4, 5]);
//! let err = client.poll_event().unwrap().result.unwrap_err();
//! assert_eq!(err.code(), Some(AbortCode::TIMEOUT));
//! # Ok::<(), duocan_core::sdo::SdoError>(())
//! ```

pub mod emcy;
pub mod guarding;
pub mod heartbeat;
#[cfg(feature = "mpdo")]
pub mod mpdo;
pub mod nmt;
pub mod pdo;
pub mod sdo;
pub mod service;
pub mod sync;
pub mod time_stamp;
