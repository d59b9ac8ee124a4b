//! # duocan-core
//!
//! The sans-IO, `no_std` protocol core of [duocan](https://docs.rs/duocan): every CANopen
//! machine (CiA 301, 304, 305, the CiA 302-2 master) takes frames and the current time and yields
//! frames, deadlines and events. No clocks, sockets, threads or allocation on the frame path, so
//! the same code runs on a bare-metal board, in a deterministic simulation and under tokio.
//!
//! Applications add `duocan`, which re-exports every module of this crate under the same name
//! (`duocan::frame`, `duocan::node`, `duocan::Node`, …) and adds the ports, captures, the
//! simulator, the tokio runtime and the front door on top. This crate is the part of duocan
//! that knows nothing of those: it does not depend on `duocan`, so no module here can import
//! from the layers above it, and Cargo refuses any attempt.
//!
//! ## Layers
//!
//! Each folder of the crate is one layer; a module imports only from its own layer and the ones
//! below it (`.ci/check-architecture.py` checks this within the crate). From the bottom up:
//!
//! | Layer | Module | What it holds |
//! | --- | --- | --- |
//! | 0 | [`frame`] | frames and identifiers, COB-IDs and node-IDs, time as an input, bounded queues and tables (inline or heap) |
//! | 1 | [`machine`] | the shapes: [`Machine`], [`BusLink`], [`Device`], [`Station`] |
//! | 2 | [`od`] | the object dictionary: types, values, static and dynamic dictionaries, abort codes, the power-on image and parameter storage (0x1010/0x1011) |
//! | 3 | `eds` (`std`) | device descriptions (CiA 306): EDS and DCF files read into a description with name lookup and a node's dictionary; any dictionary written as an EDS or DCF; a `no_std` node's static dictionary generated from an EDS at build time |
//! | 4 | [`cia301`] · [`cia304`] · [`cia305`] · `cia1301` (`fd`) | the CiA 301 services, one module per object: [`nmt`], [`heartbeat`], [`guarding`], [`sync`], [`time_stamp`], [`emcy`], [`sdo`], [`pdo`]; the CiA 304 safety objects (SRDO, GFC); the layer setting services (LSS, CiA 305): slave, master, fastscan; the CANopen FD services of CiA 1301 (USDO) |
//! | 5 | [`profile`] | identifier profiles: the predefined connection set, the railway 29-bit scheme |
//! | 6 | [`node`] | [`Node`]: the services composed into one CANopen device |
//! | 7 | [`cia302`] | the CiA 302-2 master (`alloc`, with the CiA 302-3 configuration manager and program download), the master-side PDO configuration, and program download on a node |
//!
//! Layers 8 to 11 (ports, captures and the simulator, the tokio runtime, the front door) are in
//! `duocan`.
//!
//! ## The guard
//!
//! This crate does not depend on `duocan`, the crate above it, so the core cannot name the
//! runtime, the simulator or the front door: an upward import does not compile. This example
//! proves it (it fails to build, as it must):
//!
//! ```compile_fail,E0433
//! // The core reaching for the front door above it: `duocan` is no dependency of duocan-core.
//! use duocan::net::Network;
//! ```
//!
//! while the same kind of line on a layer of the core itself builds:
//!
//! ```
//! use duocan_core::node::Node;
//! ```
//!
//! ## Features
//!
//! Read from `Cargo.toml`, so this list is the manifest's; `duocan`'s features of the same
//! names turn them on. With none, the crate is the sans-IO core for `no_std` without an
//! allocator.
//!
#![doc = document_features::document_features!()]
#![cfg_attr(not(feature = "std"), no_std)]
// On docs.rs, each feature-gated item says which feature it needs.
#![cfg_attr(docsrs, feature(doc_cfg))]

#[cfg(feature = "alloc")]
extern crate alloc;

// Layer 0 to 2: primitives, the machine shapes, the dictionary.
pub mod frame;
pub mod machine;
pub mod od;
// Layer 3: device descriptions (EDS/DCF) of a dictionary.
#[cfg(feature = "std")]
pub mod eds;
// Layer 4 to 7: the standard's services, identifier profiles, the node, the master.
pub mod cia301;
// CiA 1301 (CANopen FD) services: on CAN FD frames, so only with them.
#[cfg(feature = "fd")]
pub mod cia1301;
pub mod cia302;
pub mod cia304;
pub mod cia305;
pub mod node;
pub mod profile;

// Short paths for what users name most (`duocan` re-exports the same).
#[cfg(feature = "mpdo")]
pub use cia301::mpdo;
pub use cia301::{emcy, guarding, heartbeat, nmt, pdo, sdo, service, sync, time_stamp};
#[cfg(feature = "alloc")]
pub use cia302::master;
pub use frame::cob_id::{CobId, NodeId, NodeSet};
pub use frame::instant::{Duration, Instant};
#[cfg(feature = "fd")]
pub use frame::FdFrame;
pub use frame::{Frame, Id};
pub use machine::{BusLink, Device, Machine, PortStatus, Station};
pub use nmt::{NmtCommand, NmtState, NmtTarget};
pub use node::{Node, NodeConfig, NodeEvent, NodeEventKind};
pub use od::abort::AbortCode;

#[cfg(test)]
mod doc_sources {
    /// The README names every feature of the manifest (the crate documentation lists them from
    /// the manifest itself; the README's words are its own).
    #[test]
    fn the_readme_names_every_feature() {
        let readme = include_str!("../README.md");
        let manifest = include_str!("../Cargo.toml");
        let start = manifest.find("\n[features]\n").expect("a [features] table");
        let table = &manifest[start + "\n[features]\n".len()..];
        let table = &table[..table.find("\n[").unwrap_or(table.len())];
        let features = table
            .lines()
            .filter_map(|l| l.split_once(" = ").map(|(name, _)| name))
            .filter(|name| !name.starts_with('#') && *name != "default");
        let mut n = 0;
        for f in features {
            assert!(
                readme.contains(&format!("`{f}`")),
                "README.md does not name feature `{f}`"
            );
            n += 1;
        }
        assert_eq!(
            n, 8,
            "sdo-block, guarding, time, alloc, fd, mpdo, std and proptest"
        );
    }
}
