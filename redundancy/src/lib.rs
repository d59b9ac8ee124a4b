//! # duocan-redundancy
//!
//! Redundancy for duocan on two CAN buses: one logical bus from two ports, primary/standby
//! board pairs, and strong/weak master failover.
//!
//! ## Layers
//!
//! Each folder is one layer; a module imports only from its own layer and the ones below it.
//! Layers 0 to 3 are the sans-IO, `no_std` crate `duocan-redundancy-core`, which this crate
//! re-exports module by module under the same names (`duocan_redundancy::link::…`,
//! `duocan_redundancy::DualBus`): it depends on the protocol core `duocan-core` alone, so the
//! compiler keeps those layers from naming the runtime, the simulator or the doors above
//! them. Layers 4 and 5 are this crate's, on the root crate `duocan` (`.ci/check-architecture.py`
//! checks the order within each crate).
//!
//! | Layer | Module | What it holds |
//! | --- | --- | --- |
//! | 0 | [`pair`] | the shared vocabulary: [`PairId`], [`Member`], [`PairSpec`] |
//! | 1 | [`link`] | the **dual-bus layer** [`DualBus`]: a [`BusLink`](duocan::BusLink) with two ports below and one logical bus above |
//! | 2 | [`supervisor`] | slave-pair supervision, the CiA 302-2 flying master, the audit trail; [`Supervisor`] composes them with the CiA 302-2 master |
//! | 3 | [`station`] | [`SupervisedStation`]: a supervisor on a dual bus (a [`Station`](duocan::Station)), with its status table |
//! | 4 | [`logical`] | [`LogicalNetwork`]: what the application holds per dual-bus network, built from named settings by [`RedundantNetworkBuilder`] |
//! | 5 | `net` | the front doors (feature `tokio`): `RedundantNetwork`, duocan's `Network` over the logical network on two ports (its SDO, NMT and flat event stream, plus role, pairs, status); `DualLink` and `open_dual`/`open_dual_named`, duocan's plain front door (`duocan::net::Network`, no master) on two buses, with a simulated redundant station (`"sim-station"`, `"sim-station:faults"`) |
//!
//! Each layer's page opens with a short example that runs as a test: a pair described and
//! handed to the layer ([`pair`]), one frame received on both buses and delivered once
//! ([`link`]), a pair's active board losing power and the switch-over exactly the consumer time
//! after its last heartbeat ([`supervisor`]), the status table of a redundant master with a bus
//! cut ([`station`]), and an SDO read through the logical network ([`logical`]). The last three
//! run on duocan's simulated buses, in virtual time.
//!
//! The dual-bus layer has one type and three policies ([`LinkMode`]):
//!
//! - **Active-active** (default): transmit fan-out to every port not failed; receive
//!   [merge](link::merge) delivering each frame occurrence exactly once, its window following a
//!   [lagging bus](link::lag) (measured, reported, distrusted beyond a maximum); [same-function
//!   merge](link::same_function) of A/B board pairs with discrepancy events.
//! - **CiA 302-6** active-standby ([`link::channel::cia302_6`]): 0x1F60, heartbeats on both
//!   channels, evaluation windows, 0x7F indicate-active-interface, transmit-error counter.
//! - **ECSS bus toggle** ([`link::channel::ecss`]): 0x2000 Bdefault/Ttoggle/Ntoggle/Ctoggle,
//!   toggling on loss of the redundancy master's heartbeat.
//!
//! Around them: [port health](link::health) (counters, error causes, ok / suspect / failed /
//! recovering, silence limit, re-initialisation with back-off), [per-node per-bus
//! reachability](link::reach), [heartbeat plausibility](link::plausible) per node and bus
//! (babbling identifiers, duplicate node-IDs, impostors on one bus), and [events](link::events)
//! with reasons and timestamps for every change. Configuration comes from code ([`DualBusConfig`]) or from the dictionary
//! ([`link::config`]).
//!
//! The supervisor runs on top of the layer and the stack:
//!
//! - [slave-pair supervision](supervisor::pairs): the pair table, joining on boot-up,
//!   event-driven evaluation with per-member deadlines (reaction = the consumer time), the four
//!   cases of the published railway design and the single-member ones, non-revertive or
//!   revertive, manual switch-over, a watchdog for members that never speak, members whose
//!   heartbeats lie handled like silent ones, standbys started by someone else sent back;
//! - [CiA 302-2 flying master](supervisor::flying_master): strong/weak master by priority,
//!   takeover at the master-heartbeat timeout, multiple-master detection and conflict resolution
//!   after a partition, planned hand-over;
//! - the [audit trail](supervisor::audit) of every role change, switch and toggle;
//! - [`Supervisor`] (feature `alloc`), the [`Machine`](duocan::Machine) composing them with the
//!   CiA 302-2 [`Master`](duocan::master::Master) of the root crate, and [`SupervisedStation`]
//!   ([`RedundantMaster`] for the common shape), which runs it over a [`DualBus`]: the
//!   supervisor's [`LinkCommand`]s tell the layer which pair member is active, the way any
//!   machine's commands reach the link of a [`Station`](duocan::Station);
//! - [`LogicalNetwork`] (feature `alloc`): dictionary, SDO client access to any node, NMT, PDO
//!   values, one typed event stream, the status table and the audit export, as a sans-IO
//!   [`Device`](duocan::Device) that the simulator and the tokio runtime drive alike; built
//!   from named settings with defaults by [`LogicalNetwork::builder`]
//!   ([`RedundantNetworkBuilder`]: node-ID, heartbeat, master timeout, SYNC, pairs, peers),
//!   every bad setting a [`RedundantError`];
//! - `net::RedundantNetwork` (feature `tokio`): the front door, the builder's network on two
//!   ports (`open(port1, port2)`, `open_named("can0,can1")`, or `open_named("sim-pairs")`: the
//!   builder's pairs and peer masters on simulated buses, with a script of faults) as the root crate's `duocan::net::Network`
//!   itself (it dereferences to one, run over the logical network as its core): typed SDO to
//!   any node, NMT, and one flat event stream on which lag is an item, where the bus, pair and
//!   master failovers come too; plus the role, the pairs, the status table and a switch-over;
//! - `net::open_dual` / `net::open_dual_named` (feature `tokio`): duocan's plain front door
//!   (`duocan::net::Network`: an observer and an SDO client that sends only NMT commands and SDO
//!   requests) on two buses through `net::DualLink`, for tools that must not become a master on
//!   somebody's network: requests fan out, answers merge exactly, and `ports()` and
//!   `heard_on()` show each bus's health and each node's reach; `"sim-station"` opens it on a simulated
//!   redundant station (two masters, two pairs, three slaves with a 1 MiB DOMAIN and program
//!   download), `"sim-station:faults"` with a repeating fault script.
//!
//! Everything is bounded (fixed-capacity tables and queues, counted overflow) and builds for
//! `no_std` targets; the supervisor needs `alloc` (as the root crate's master does). The layer's
//! capacities are part of its type (`DualBus<C, K>`, `K` a [`Capacity<SLOTS, FUNCTIONS>`](Capacity)
//! or a board's own [`MergeCapacity`]) so that it needs no allocator; the `alloc` types above it (supervisor, station, network) are spelled with a
//! dictionary and an identifier profile only: their capacities are configuration values
//! (the master's PDOs, SDO sessions and queues in
//! [`MasterConfig`](duocan::master::MasterConfig), the supervisor's event queue in
//! [`SupervisorConfig`]), allocated once when they are built and never grown.
//!
//! ## Quick start
//!
//! A redundant master is the [`LogicalNetwork`] of the [`logical`] page: a [`Supervisor`]
//! (the CiA 302-2 master and its pairs) on a [`DualBus`], which the simulator or the tokio
//! runtime drives like any other device; its example builds one with one pair of boards from
//! [`LogicalNetwork::builder`]'s named settings. Under tokio, the same builder opens the
//! redundant network's front door (`net::RedundantNetwork`, feature `tokio`): SDO to any node,
//! NMT and one stream of bus, pair and master failovers, as the starter example
//! `examples/redundant_master.rs` shows in under twenty lines (`cargo run --example
//! redundant_master`, a simulated station, no hardware). To try
//! the stack on one bus first, start at duocan's front door, `duocan::net` (feature `tokio`),
//! and its starter examples in the root crate: `examples/read_sdo.rs` (read one object of one
//! node) and `examples/heartbeat_monitor.rs` (watch nodes listen-only);
//! `examples/dual_vcan_failover.rs` (feature `socketcan`) runs the dual-bus layer over two
//! SocketCAN interfaces.
//!
//! ## Features
//!
//! Read from `Cargo.toml`, so this list is the manifest's. With none, the crate is the dual-bus
//! layer for `no_std` without an allocator.
//!
#![doc = document_features::document_features!()]
#![cfg_attr(not(feature = "std"), no_std)]
// On docs.rs, each feature-gated item says which feature it needs.
#![cfg_attr(docsrs, feature(doc_cfg))]

#[cfg(feature = "alloc")]
extern crate alloc;

// The sans-IO layers 0 to 3 are the core crate's, re-exported under the same names so that
// `duocan_redundancy::link::…`, `duocan_redundancy::supervisor::…` and the rest are the paths.
pub use duocan_redundancy_core::link;
#[cfg(feature = "alloc")]
pub mod logical;
#[cfg(feature = "tokio")]
pub mod net;
pub use duocan_redundancy_core::pair;
#[cfg(feature = "alloc")]
pub use duocan_redundancy_core::station;
pub use duocan_redundancy_core::supervisor;

#[cfg(feature = "cia302-6")]
pub use duocan_redundancy_core::Cia3026Config;
pub use duocan_redundancy_core::FrameClassifier;
pub use duocan_redundancy_core::ModeKind;
#[cfg(feature = "alloc")]
pub use duocan_redundancy_core::{
    AddPairError, JoinRefusal, NotJoined, Supervisor, SupervisorConfig, SupervisorEvent,
};
pub use duocan_redundancy_core::{Capacity, MergeCapacity};
pub use duocan_redundancy_core::{
    DualBus, DualBusConfig, DualBusNode, LinkCommand, LinkMode, LinkStats, MergePolicy,
    DEFAULT_MERGE_SLOTS,
};
#[cfg(feature = "ecss")]
pub use duocan_redundancy_core::{EcssConfig, EcssRole};
pub use duocan_redundancy_core::{HealthConfig, PortState};
pub use duocan_redundancy_core::{LinkEvent, LinkEventKind, PortReason, Suspicion, SwitchReason};
pub use duocan_redundancy_core::{Member, PairId, PairSpec};
pub use duocan_redundancy_core::{Merger, Verdict};
pub use duocan_redundancy_core::{Outbox, EVENT_QUEUE, FRAME_QUEUE, MACHINE_QUEUE, REQUEST_QUEUE};
#[cfg(feature = "alloc")]
pub use duocan_redundancy_core::{RedundantMaster, SupervisedLink, SupervisedStation};
#[cfg(feature = "alloc")]
pub use logical::{
    LogicalNetwork, NetProfile, NetworkError, NetworkEvent, NetworkEventKind, RedundantError,
    RedundantNetworkBuilder, Role,
};
#[cfg(feature = "tokio")]
pub use net::{RedundantEvent, RedundantNetwork};

/// The crate's README code block, compiled as a doctest.
#[cfg(all(doctest, feature = "tokio"))]
#[doc = include_str!("../README.md")]
pub struct ReadmeExample;

#[cfg(test)]
mod readme_features {
    /// The crate's README names every feature of its manifest (the crate documentation lists
    /// them from the manifest itself; the README's words are its own).
    #[test]
    fn the_readme_names_every_feature() {
        let manifest = include_str!("../Cargo.toml");
        let readme = include_str!("../README.md");
        let start = manifest.find("\n[features]\n").expect("a [features] table");
        let table = &manifest[start + "\n[features]\n".len()..];
        let table = &table[..table.find("\n[").unwrap_or(table.len())];
        let names = table
            .lines()
            .filter_map(|l| l.split_once(" = ").map(|(n, _)| n));
        for f in names.filter(|n| !n.starts_with('#') && *n != "default") {
            assert!(
                readme.contains(&format!("`{f}`")),
                "README.md does not name feature `{f}`"
            );
        }
    }
}
