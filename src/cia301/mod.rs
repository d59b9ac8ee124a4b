//! Layer 3, the CiA 301 communication services: one module per communication object, each a
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
//!
//! The timed services share one shape ([`service`]): `poll_timeout` for the next deadline,
//! `handle_timeout(now, &mut out)` writing frames and events into a [`service::ServiceOutput`].
//!
//! Everything here sits on the [object dictionary](crate::od) and the [frame](crate::frame)
//! primitives only: no service knows the node that composes it, and none knows about the master
//! or the ports. The root re-exports each module, so `duocan::sdo` is `duocan::cia301::sdo`.

pub mod emcy;
pub mod guarding;
pub mod heartbeat;
pub mod nmt;
pub mod pdo;
pub mod sdo;
pub mod service;
pub mod sync;
pub mod time_stamp;
