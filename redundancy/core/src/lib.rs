//! # duocan-redundancy-core
//!
//! The sans-IO, `no_std` redundancy layers of [duocan](https://docs.rs/duocan) on two CAN
//! buses: one logical bus from two ports, primary/standby board pairs, strong/weak master
//! failover, and the supervised station that runs them. Every layer takes frames and the
//! current time and yields frames, deadlines and events: no clocks, sockets, threads or tasks,
//! so the same code runs on a bare-metal board, in duocan's deterministic simulation and under
//! tokio.
//!
//! Applications add `duocan-redundancy`, which re-exports every module of this crate under the
//! same name (`duocan_redundancy::link`, `duocan_redundancy::supervisor`,
//! `duocan_redundancy::DualBus`, …) and adds the logical network object and the front doors on
//! top. This crate is the part that knows nothing of those: it sits on the protocol core
//! `duocan-core` alone, so no module here can import from the layers above it, and Cargo
//! refuses any attempt.
//!
//! ## Layers
//!
//! Each folder is one layer; a module imports only from its own layer and the ones below it
//! (`.ci/check-architecture.py` checks this within the crate), and everything sits on the
//! protocol core `duocan-core`.
//!
//! | Layer | Module | What it holds |
//! | --- | --- | --- |
//! | 0 | [`pair`] | the shared vocabulary: [`PairId`], [`Member`], [`PairSpec`] |
//! | 1 | [`link`] | the **dual-bus layer** [`DualBus`]: a [`BusLink`](duocan_core::BusLink) with two ports below and one logical bus above |
//! | 2 | [`supervisor`] | slave-pair supervision, the CiA 302-2 flying master, the audit trail; [`Supervisor`] composes them with the CiA 302-2 master |
//! | 3 | [`station`] | [`SupervisedStation`]: a supervisor on a dual bus (a [`Station`](duocan_core::Station)), with its status table |
//!
//! Layers 4 and 5 (the logical network object `logical`, with its builder and its one error,
//! and the front doors `net` under tokio) are in `duocan-redundancy`: the logical network is
//! the core of duocan's runtime and front door, so it implements their traits and carries their
//! errors, which needs the root crate `duocan`.
//!
//! ## The guard
//!
//! This crate depends on neither `duocan-redundancy`, the crate above it, nor tokio, nor the
//! root crate `duocan` (its ports, simulator, runtime and front door), so the layers cannot
//! name them: an upward import does not compile. These examples prove it for the door and
//! the runtime (they fail to build, as they must):
//!
//! ```compile_fail,E0433
//! // A layer reaching for the front door above it: the door's crate is no dependency here.
//! use duocan_redundancy::net::RedundantNetwork;
//! ```
//!
//! ```compile_fail,E0433
//! // Nor is tokio: no layer here spawns, sleeps or awaits.
//! use tokio::time::sleep;
//! ```
//!
//! while the same kind of line on a layer of this crate, or of the protocol core below it,
//! builds:
//!
//! ```
//! use duocan_redundancy_core::link::dual_bus::DualBus;
//! use duocan_core::node::Node;
//! ```
//!
//! The module examples of [`supervisor`] and [`station`] run the layers on duocan's simulated
//! buses, which they reach as a development dependency, so an example (a doctest sees the
//! development dependencies) can name `duocan::sim`; the library cannot, since `duocan` is no
//! dependency of it (`cargo tree -p duocan-redundancy-core -e normal` shows none), and every
//! build of the library that names it fails.
//!
//! ## What is in it
//!
//! The dual-bus layer has one type and three policies ([`LinkMode`]): active-active (transmit
//! fan-out, receive [merge](link::merge) delivering each frame occurrence exactly once,
//! [same-function merge](link::same_function) of A/B board pairs), CiA 302-6 active-standby
//! and the ECSS bus toggle; around them [port health](link::health), [per-node per-bus
//! reachability](link::reach), [heartbeat plausibility](link::plausible) and
//! [events](link::events). The [`supervisor`] runs slave-pair supervision, the CiA 302-2
//! flying master and the audit trail on top of it; [`SupervisedStation`] runs the
//! [`Supervisor`] over a [`DualBus`]. The `duocan-redundancy` crate documentation tells the
//! whole story, with the logical network and the front door.
//!
//! Everything is bounded (fixed-capacity tables and queues, counted overflow) and builds for
//! `no_std` targets; the supervisor needs `alloc` (as the protocol core's master does).
//!
//! ## Features
//!
//! Read from `Cargo.toml`, so this list is the manifest's; `duocan-redundancy`'s features of
//! the same names turn them on. With none, the crate is the dual-bus layer for `no_std`
//! without an allocator.
//!
#![doc = document_features::document_features!()]
#![cfg_attr(not(feature = "std"), no_std)]
// On docs.rs, each feature-gated item says which feature it needs.
#![cfg_attr(docsrs, feature(doc_cfg))]

#[cfg(feature = "alloc")]
extern crate alloc;

pub mod link;
pub mod pair;
#[cfg(feature = "alloc")]
pub mod station;
pub mod supervisor;

// Short paths for what users name most (`duocan-redundancy` re-exports the same).
pub use link::capacity::{Capacity, MergeCapacity};
#[cfg(feature = "cia302-6")]
pub use link::channel::Cia3026Config;
pub use link::channel::ModeKind;
#[cfg(feature = "ecss")]
pub use link::channel::{EcssConfig, EcssRole};
pub use link::classify::FrameClassifier;
pub use link::dual_bus::{
    DualBus, DualBusConfig, DualBusNode, LinkCommand, LinkMode, LinkStats, MergePolicy,
    DEFAULT_MERGE_SLOTS,
};
pub use link::events::{LinkEvent, LinkEventKind, PortReason, Suspicion, SwitchReason};
pub use link::health::{HealthConfig, PortState};
pub use link::merge::{Merger, Verdict};
pub use link::outbox::{Outbox, EVENT_QUEUE, FRAME_QUEUE, MACHINE_QUEUE, REQUEST_QUEUE};
pub use pair::{Member, PairId, PairSpec};
#[cfg(feature = "alloc")]
pub use station::{RedundantMaster, SupervisedLink, SupervisedStation};
#[cfg(feature = "alloc")]
pub use supervisor::{
    AddPairError, JoinRefusal, NotJoined, Supervisor, SupervisorConfig, SupervisorEvent,
};

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
