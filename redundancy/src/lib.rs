//! # duocan-redundancy
//!
//! Redundancy for duocan on two CAN buses. This crate's first part is the **dual-bus
//! abstraction layer**: [`DualBus`], a sans-IO [`BusLink`](duocan::BusLink) with two ports
//! below and one logical bus above, so that a node of the standard stack runs on top unchanged.
//!
//! One type, three policies ([`Mode`]):
//!
//! - **Active-active** (default): transmit fan-out to every port not failed; receive
//!   [merge] delivering each frame occurrence exactly once; [same-function
//!   merge](pairs_merge) of A/B board pairs with discrepancy events.
//! - **CiA 302-6** active-standby ([`channel::cia302_6`]): 0x1F60, heartbeats on both channels,
//!   evaluation windows, 0x7F indicate-active-interface, transmit-error counter.
//! - **ECSS bus toggle** ([`channel::ecss`]): 0x2000 Bdefault/Ttoggle/Ntoggle/Ctoggle, toggling
//!   on loss of the redundancy master's heartbeat.
//!
//! Around them: [port health](health) (counters, error causes, ok / suspect / failed /
//! recovering, silence limit, re-initialisation with back-off), [per-node per-bus
//! reachability](reach), and [events] with reasons and timestamps for every change.
//! Configuration comes from code ([`DualBusConfig`]) or from the dictionary ([`config`]).
//!
//! The second part is the **supervisor** of a redundant master, on top of the layer and the
//! stack:
//!
//! - [slave-pair supervision](pairs): the pair table, joining on boot-up, event-driven
//!   evaluation with per-member deadlines (reaction = the consumer time), the seed's four cases
//!   and the single-member ones, non-revertive or revertive, manual switch-over, a watchdog for
//!   members that never speak;
//! - [CiA 302-2 flying master](flying_master): strong/weak master by priority, takeover at the
//!   master-heartbeat timeout, multiple-master detection and conflict resolution after a
//!   partition, planned hand-over;
//! - the [audit trail](audit) of every role change, switch and toggle;
//! - [`Supervisor`] (feature `alloc`), the [`Machine`](duocan::Machine) composing them with the
//!   CiA 302-2 [`Master`](duocan::master::Master) of the root crate (boot, identity check and
//!   configuration of every slave, NMT, active/standby), and [`SupervisedStation`], which runs it
//!   over a [`DualBus`] and tells the layer which pair member is active; its
//!   [status](station::Status) prints as a table;
//! - [`LogicalNetwork`] (feature `alloc`), what the application holds per dual-bus network:
//!   dictionary, SDO client access to any node, NMT, PDO values, one typed event stream, the
//!   status table and the audit export, as a sans-IO [`Device`](duocan::Device) that the
//!   simulator and the tokio runtime drive alike.
//!
//! Everything is bounded (fixed-capacity tables and queues, counted overflow) and builds for
//! `no_std` targets; the supervisor needs `alloc` (as the root crate's master does).
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

#[cfg(feature = "alloc")]
extern crate alloc;

pub mod audit;
pub mod channel;
pub mod classify;
pub mod config;
pub mod dual_bus;
pub mod events;
pub mod flying_master;
pub mod health;
pub mod merge;
#[cfg(feature = "alloc")]
pub mod network;
pub mod outbox;
pub mod pairs;
pub mod pairs_merge;
pub mod reach;
#[cfg(feature = "alloc")]
pub mod station;
#[cfg(feature = "alloc")]
pub mod supervisor;

pub use channel::{Cia3026Config, EcssConfig, EcssRole, ModeKind, NodeSet};
pub use classify::FrameClassifier;
pub use dual_bus::{DualBus, DualBusConfig, LinkStats, Mode, DEFAULT_MERGE_SLOTS};
pub use events::{LinkEvent, LinkEventKind, PortReason, SwitchReason};
pub use health::{HealthConfig, PortState};
pub use merge::{Merger, Verdict};
#[cfg(feature = "alloc")]
pub use network::{LogicalNetwork, NetworkError, NetworkEvent, NetworkEventKind};
pub use outbox::{Outbox, EVENT_QUEUE, FRAME_QUEUE, MACHINE_QUEUE, REQUEST_QUEUE};
pub use pairs_merge::{Member, PairId};
#[cfg(feature = "alloc")]
pub use station::SupervisedStation;
#[cfg(feature = "alloc")]
pub use supervisor::{
    AddPairError, JoinRefusal, LinkCommand, Supervisor, SupervisorConfig, SupervisorEvent,
};
