//! Layer 4 beside [`cia301`](crate::cia301), CiA 304 (EN 50325-5) safety communication: safety-relevant data objects (SRDO) and
//! the global fail-safe command (GFC), sans-IO and without allocation like the CiA 301 services
//! beside them.
//!
//! | Object | Module | Identifiers |
//! | --- | --- | --- |
//! | SRDO communication parameters, mapping, configuration valid, checksums (0x1301…, 0x1381…, 0x13FE, 0x13FF) | [`srdo::config`] | |
//! | SRDO producer | [`srdo::producer`] | 0x101–0x180 (normal odd, inverted even) |
//! | SRDO consumer: SRVT, SCT, inversion, safe state | [`srdo::consumer`] | 0x101–0x180 |
//! | The SRDOs of a node, bound to its dictionary | [`srdo`] | |
//! | Global fail-safe command (0x1300) | [`gfc`] | 0x001 |
//!
//! An SRDO carries its data twice, plain and bitwise inverted, on two identifiers; the consumer
//! takes it only as a complete pair within its validation time (SRVT) and expects a new pair
//! within its safety cycle time (SCT). Anything else puts it in its safe state. The node
//! ([`crate::node::Node`]) runs [`srdo::NODE_SRDOS`] of them and refuses to enter operational
//! while their configuration is not marked valid or its checksum does not match.
//!
//! A consumer on its own, with the frames on the wire:
//!
//! ```
//! use duocan_core::cia304::srdo::consumer::{ConsumerStep, SrdoCause, SrdoConsumer};
//! use duocan_core::{Duration, Frame, Id, Instant};
//!
//! let ms = Instant::from_millis;
//! let (sct, srvt) = (Duration::from_millis(50), Duration::from_millis(10));
//! let mut c = SrdoConsumer::new(0x101, 0x102, sct, srvt, 2);
//! c.start(ms(0));
//! // The normal frame, then its inverse 1 ms later: the value is delivered.
//! c.handle_frame(ms(5), &Frame::from_array(Id::Standard(0x101), [0x12, 0x34]));
//! let step = c.handle_frame(ms(6), &Frame::from_array(Id::Standard(0x102), [0xED, 0xCB]));
//! assert_eq!(step, Some(ConsumerStep::Deliver([0x12, 0x34, 0, 0, 0, 0, 0, 0])));
//! // No further pair: 50 ms after the last one the consumer is in its safe state.
//! assert_eq!(c.poll_timeout(), Some(ms(56)));
//! let Some(ConsumerStep::Trip(fault)) = c.handle_timeout(ms(56)) else { panic!() };
//! assert_eq!((fault.cause, fault.measured), (SrdoCause::CycleTime, sct));
//! ```

pub mod gfc;
pub mod srdo;
