//! # duocan
//!
//! A CANopen stack (CiA 301, CiA 302-2 master) built for redundant dual-bus networks, in the
//! sans-IO style: every protocol machine takes frames and the current time and yields frames,
//! deadlines and events. No clocks, sockets, threads or allocation on the frame path, so the same
//! code runs on a bare-metal board, in a deterministic simulation and under tokio.
//!
//! ## Layers
//!
//! Each module is one layer; a module imports only from its own layer and the ones below it.
//! Layers 0 to 7 are the crate `duocan-core`, re-exported here under the same names; 8 to 11
//! are this crate's own. From the bottom up:
//!
//! | Layer | Module | What it holds |
//! | --- | --- | --- |
//! | 0 | [`frame`] | frames and identifiers, COB-IDs and node-IDs, time as an input, bounded queues and tables (inline or heap) |
//! | 1 | [`machine`] | the shapes: [`Machine`], [`BusLink`], [`Device`], [`Station`] |
//! | 2 | [`od`] | the object dictionary: types, values, static and dynamic dictionaries, abort codes, the power-on image and parameter storage (0x1010/0x1011) |
//! | 3 | [`eds`] | device descriptions (CiA 306): EDS and DCF files read into a description with name lookup and a node's dictionary; any dictionary written as an EDS or DCF; a `no_std` node's static dictionary generated from an EDS at build time |
//! | 4 | [`cia301`] · [`cia304`] · [`cia305`] · `cia1301` (`fd`) | the CiA 301 services, one module per object: [`nmt`], [`heartbeat`], [`guarding`], [`sync`], [`time_stamp`], [`emcy`], [`sdo`], [`pdo`]; the CiA 304 safety objects (SRDO, GFC); the layer setting services (LSS, CiA 305): slave, master, fastscan; the CANopen FD services of CiA 1301 (USDO) |
//! | 5 | [`profile`] | identifier profiles: the predefined connection set, the railway 29-bit scheme |
//! | 6 | [`node`] | [`Node`]: the services composed into one CANopen device |
//! | 7 | [`cia302`] | the CiA 302-2 [`master`] (with the CiA 302-3 configuration manager and program download), the master-side [PDO configuration](cia302::pdo_config), and [program download](cia302::program) on a node |
//! | 8 | [`port`] | ports: SocketCAN, python-can's UDP bus, in-memory, any `embedded-can` controller |
//! | 9 | [`capture`] · [`sim`] | candump and pcap captures, frames decoded into CANopen-aware lines; the simulated multi-bus network (virtual time) |
//! | 10 | [`runtime`] | the tokio driver: ports and the monotonic clock around any [`Device`] |
//! | 11 | [`net`] | the front door: a network handle and remote nodes, typed and async (SDO, NMT, events, listen-only monitor) |
//!
//! Each layer's page opens with a short example that runs as a test: a frame built and read
//! back ([`frame`]), a node run by hand as a driver runs it ([`machine`]), a dictionary
//! refusing a bad write with its abort code ([`od`]), a device description read ([`eds`]), an
//! SDO transfer driven by frames and time ([`cia301`]), the predefined identifiers
//! ([`profile`]), a node started by NMT and its heartbeat ([`node`]), a master booting a
//! simulated slave ([`cia302`]), two in-memory ports ([`port`]), candump and pcap written and
//! read back ([`capture`]), two devices on the simulated buses ([`sim`]), a node under the tokio
//! driver ([`runtime`]) and the front door ([`net`]).
//!
//! ## Crates
//!
//! The cut between `duocan-core` and `duocan` is the line the design already draws, between the
//! machines and what drives them. Below it, the whole protocol: sans-IO and `no_std` (an
//! allocator only for the master and the dynamic dictionary, `std` only for device description
//! files), the same on a board, in the simulator and under tokio. Above it, what does I/O or
//! stands in for it: ports, captures, the simulator and the fault bridge, the tokio runtime, the
//! front door. Cargo enforces the layering between the two: `duocan-core` does not depend on
//! `duocan`, so the core cannot name the simulator, a port or the runtime (a `compile_fail`
//! example in its crate docs proves it); `cargo tree -p duocan --depth 1` shows `duocan-core`
//! among this crate's dependencies. Within each crate, `.ci/check-architecture.py` checks the
//! order of the layers. Applications add only `duocan`: every path (`duocan::frame::Frame`,
//! `duocan::node::Node`, `duocan::Node`) is the core's item, re-exported.
//!
//! The redundancy crate (`duocan-redundancy`) adds its dual-bus layer as one more
//! [`BusLink`], and its supervisor as one more [`Machine`]: the stack above a bus link does not
//! know there are two wires.
//!
//! ## Quick start
//!
//! An application that talks to nodes starts at the front door, [`net`] (feature `tokio`): a
//! network handle on a port and remote nodes with typed SDO, NMT and events, as python
//! `canopen` users know them. `"sim-nodes"` is an in-memory bus with simulated nodes 1–10, so this
//! runs without hardware; `"can0"` (feature `socketcan`) or `"udp"` (feature `udp`) is a real
//! bus.
//!
//! ```
//! # #[cfg(feature = "tokio")]
//! # #[tokio::main]
//! # async fn main() -> Result<(), duocan::net::NetError> {
//! use duocan::net::Network;
//!
//! let net = Network::open_named("sim-nodes")?;
//! let vendor: u32 = net.node(5).sdo().read(0x1018, 1).await?;
//! assert_eq!(vendor, duocan::net::SIM_VENDOR);
//! # Ok(())
//! # }
//! # #[cfg(not(feature = "tokio"))]
//! # fn main() {}
//! ```
//!
//! The starter examples run the same way (`cargo run --example NAME`, against the simulated
//! nodes unless `DUOCAN_BUS` names a port):
//!
//! - `examples/read_sdo.rs`: read 0x1018 sub 1 of node 5 and print it;
//! - `examples/heartbeat_monitor.rs`: watch nodes 1–10 listen-only and print boot-ups, state
//!   changes and lost heartbeats.
//!
//! To build a device rather than talk to one, start with [`Node`] (one CANopen device on one
//! logical bus), [`machine`] (how machines compose and what a driver does with them) and, with
//! the `std` feature, [`sim`] (the simulated multi-bus network every test and the demo run on);
//! on a board without `std`, the [`embedded`](port::embedded) driver runs it.
//!
//! ## Features
//!
//! Read from `Cargo.toml`, so this list is the manifest's. With none, the crate is the
//! sans-IO core for `no_std` without an allocator.
//!
#![doc = document_features::document_features!()]
#![cfg_attr(not(feature = "std"), no_std)]
// On docs.rs, each feature-gated item says which feature it needs.
#![cfg_attr(docsrs, feature(doc_cfg))]

#[cfg(feature = "alloc")]
extern crate alloc;

// Layer 0 to 7, the sans-IO protocol core, are the crate `duocan-core`, under the same names.
// Layer 0 to 2: primitives, the machine shapes, the dictionary.
pub use duocan_core::{frame, machine, od};
// Layer 3: device descriptions (EDS/DCF) of a dictionary.
#[cfg(feature = "std")]
pub use duocan_core::eds;
// Layer 4 to 7: the standard's services, identifier profiles, the node, the master.
#[cfg(feature = "fd")]
pub use duocan_core::cia1301;
pub use duocan_core::{cia301, cia302, cia304, cia305, node, profile};
// Layer 8 to 10: I/O around the machines.
#[cfg(feature = "std")]
pub mod bridge;
#[cfg(feature = "std")]
pub mod capture;
#[cfg(feature = "tokio")]
pub mod net;
pub mod port;
#[cfg(feature = "tokio")]
pub mod runtime;
#[cfg(feature = "std")]
pub mod sim;

// Short paths for what users name most (the core's own, re-exported).
#[cfg(feature = "alloc")]
pub use duocan_core::master;
#[cfg(feature = "mpdo")]
pub use duocan_core::mpdo;
#[cfg(feature = "fd")]
pub use duocan_core::FdFrame;
pub use duocan_core::{emcy, guarding, heartbeat, nmt, pdo, sdo, service, sync, time_stamp};
pub use duocan_core::{AbortCode, CobId, Duration, Frame, Id, Instant, NodeId, NodeSet};
pub use duocan_core::{BusLink, Device, Machine, PortStatus, Station};
pub use duocan_core::{NmtCommand, NmtState, NmtTarget};
pub use duocan_core::{Node, NodeConfig, NodeEvent, NodeEventKind};
// The forwarding macros of the machine shapes, for the wrappers above the core (the front
// door's links, the redundancy crate's): internal to duocan, hidden as they are in the core.
#[doc(hidden)]
pub use duocan_core::{forward_bus_link, forward_device_to};

/// The README's and every user-guide chapter's code blocks, compiled (and run where they can
/// run) as doctests, so that what a newcomer copies works. Rust blocks are tested; `sh`, `toml`
/// and `text` blocks are not. A chapter added to `guide/src/SUMMARY.md` is added here.
#[cfg(all(doctest, feature = "tokio"))]
mod doc_examples {
    #[doc = include_str!("../README.md")]
    pub struct Readme;
    #[doc = include_str!("../guide/src/introduction.md")]
    pub struct Introduction;
    #[doc = include_str!("../guide/src/getting-started.md")]
    pub struct GettingStarted;
    #[doc = include_str!("../guide/src/first-real-bus.md")]
    pub struct FirstRealBus;
    #[doc = include_str!("../guide/src/redundant-master.md")]
    pub struct RedundantMasterChapter;
    #[doc = include_str!("../guide/src/process-data.md")]
    pub struct ProcessData;
    #[doc = include_str!("../guide/src/device-descriptions.md")]
    pub struct DeviceDescriptions;
    #[doc = include_str!("../guide/src/lss.md")]
    pub struct Lss;
    #[doc = include_str!("../guide/src/failover-testing.md")]
    pub struct FailoverTesting;
    #[doc = include_str!("../guide/src/station-gateway.md")]
    pub struct StationGateway;
    #[doc = include_str!("../guide/src/firmware.md")]
    pub struct Firmware;
    #[doc = include_str!("../guide/src/tool.md")]
    pub struct Tool;
    #[doc = include_str!("../guide/src/troubleshooting.md")]
    pub struct Troubleshooting;
    #[doc = include_str!("../guide/src/interoperability.md")]
    pub struct Interoperability;
}

#[cfg(test)]
mod doc_sources {
    /// The features `[features]` of a manifest defines (not `default`).
    fn features(manifest: &str) -> impl Iterator<Item = &str> {
        let start = manifest.find("\n[features]\n").expect("a [features] table");
        let table = &manifest[start + "\n[features]\n".len()..];
        let table = &table[..table.find("\n[").unwrap_or(table.len())];
        table
            .lines()
            .filter_map(|l| l.split_once(" = ").map(|(name, _)| name))
            .filter(|name| !name.starts_with('#') && *name != "default")
    }

    /// Every chapter of the user guide is among the doctests (`doc_examples`).
    #[test]
    fn every_guide_chapter_is_a_doctest() {
        let summary = include_str!("../guide/src/SUMMARY.md");
        let here = include_str!("lib.rs");
        for chapter in summary
            .split("](")
            .skip(1)
            .filter_map(|s| s.split_once(')'))
        {
            let path = format!("../guide/src/{}", chapter.0);
            assert!(
                here.contains(&path),
                "{path} is not included in doc_examples"
            );
        }
    }

    /// The README's feature table names every feature of the manifest (the crate documentation
    /// lists them from the manifest itself; the README's words are its own).
    #[test]
    fn the_readme_names_every_feature() {
        let readme = include_str!("../README.md");
        for f in features(include_str!("../Cargo.toml")) {
            assert!(
                readme.contains(&format!("`{f}`")),
                "README.md does not name feature `{f}`"
            );
        }
    }
}
