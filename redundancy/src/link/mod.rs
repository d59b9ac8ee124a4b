//! Layer 1, the **dual-bus abstraction layer**: [`DualBus`](dual_bus::DualBus), a sans-IO
//! [`BusLink`](duocan::BusLink) with two ports below and one logical bus above, so that a node
//! of the standard stack runs on top unchanged.
//!
//! | Part | Module |
//! | --- | --- |
//! | The layer itself: ports below, logical bus above, one of three policies | [`dual_bus`] |
//! | Exact duplicate merge of the two ports' receptions (active-active) | [`merge`] |
//! | Each port's lag from matched twins: the merge window, distrust beyond the maximum | [`lag`] |
//! | Port health: counters, error causes, ok / suspect / failed / recovering, re-initialisation | [`health`] |
//! | Per-node, per-bus reachability | [`reach`] |
//! | Heartbeat plausibility per node and bus: babbling identifiers, duplicate node-IDs, impostors on one bus | [`plausible`] |
//! | The channel policies: active-active, CiA 302-6, ECSS bus toggle | [`channel`] |
//! | Same-function merge of the two boards of a pair | [`same_function`] |
//! | Which frames carry which node's process data | [`classify`] |
//! | Configuration ([`DualBusConfig`](config::DualBusConfig)), from code or from the dictionary (0x1F60, 0x2000) | [`config`] |
//! | What the layer reports, and the bounded queues it reports through | [`events`], [`outbox`] |
//!
//! Nothing here knows the supervisor: the layer is told which board of a pair is active, and
//! that is all it knows of pairs.

pub mod channel;
pub mod classify;
pub mod config;
pub mod dual_bus;
pub mod events;
pub mod health;
pub mod lag;
pub mod merge;
pub mod outbox;
pub mod plausible;
pub mod reach;
pub mod same_function;
