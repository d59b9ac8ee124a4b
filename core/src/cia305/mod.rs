//! Layer 4, the Layer Setting Services (CiA 305): a master finds devices by their identity and
//! gives them a node-ID and a bit rate over the bus; a device that arrives without a node-ID
//! (a replacement board, 0xFF) runs LSS only until it has one.
//!
//! | Part | Module |
//! | --- | --- |
//! | the frames on 0x7E5 (master) and 0x7E4 (slaves), decoded and encoded | [`codec`] |
//! | the slave: modes, node-IDs, bit timing, store | [`slave`] |
//! | the stored node-ID and bit timing on a parameter medium | [`store`] |
//! | the master: one request at a time, timeouts, typed results | [`master`] |
//! | fastscan and the assignment plan | [`fastscan`] |
//! | the master's errors | [`error`] |
//!
//! Both sides are sans-IO [`Machine`](crate::Machine)s: the master sits next to a node or a
//! master in a [`Composite`](crate::machine::Composite), the slave in front of the node it gives
//! a node-ID to ([`LssNode`](crate::node::LssNode), which builds the node when the node-ID
//! becomes active); each ignores every frame that is not its business. Over the
//! dual-bus layer LSS frames are frames like any other: requests go out on both buses, answers
//! are merged, so the answer of a slave heard on one bus only still counts.
//!
//! A master gives a non-configured slave node-ID 5, frames and time by hand:
//!
//! ```
//! use duocan_core::cia305::{LssAddress, LssMaster, LssMasterEventKind, LssPlan, LssSlave};
//! use duocan_core::{Instant, Machine, NodeId};
//!
//! let board = LssAddress { vendor: 0x2A, product: 7, revision: 1, serial: 0x1234 };
//! let mut slave = LssSlave::new(board, 0xFF);
//! let mut master: LssMaster = LssMaster::default();
//! master.fastscan(Instant::ZERO, LssPlan::new().with_identity(board, NodeId::must(5)))?;
//! let mut now = Instant::ZERO;
//! while !master.is_idle() {
//!     while let Some(f) = master.poll_transmit() {
//!         slave.handle_frame(now, &f);
//!         while let Some(a) = slave.poll_transmit() {
//!             master.handle_frame(now, &a);
//!         }
//!     }
//!     now = master.poll_timeout().unwrap_or(now);
//!     master.handle_timeout(now);
//! }
//! assert_eq!(slave.node_id(), Some(NodeId::must(5)));
//! let kinds: Vec<_> = std::iter::from_fn(|| master.poll_event()).map(|e| e.kind).collect();
//! assert_eq!(kinds[1], LssMasterEventKind::Assigned { address: board, node: NodeId::must(5) });
//! # Ok::<(), duocan_core::cia305::LssError>(())
//! ```

pub mod codec;
pub mod error;
pub mod fastscan;
pub mod master;
pub mod slave;
pub mod store;

pub use codec::{
    BitTiming, Fastscan, IdentifyRange, Inquiry, LssAddress, LssFrameError, LssMode, LssRequest,
    LssResponse,
};
pub use error::{LssError, LssService};
pub use fastscan::{fastscan_cost, FastscanCost, LssPlan};
pub use master::{
    LssMaster, LssMasterConfig, LssMasterEvent, LssMasterEventKind, LssMasterStats, LssOutcome,
};
pub use slave::{LssSlave, LssSlaveEvent, LssSlaveEventKind, LssSlaveStats};
pub use store::{LssStoreError, NoMedium, StoredLss};
