//! # duocan
//!
//! A CANopen stack (CiA 301, CiA 302-2 master) built for redundant dual-bus networks, in the
//! sans-IO style: every protocol machine takes frames and the current time and yields frames,
//! deadlines and events. No clocks, sockets, threads or allocation on the frame path, so the same
//! code runs on a bare-metal board, in a deterministic simulation and under tokio.
//!
//! Start with [`node::Node`] (one CANopen device on one logical bus), [`machine`] (how machines
//! compose and what a driver does with them) and, with the `std` feature, [`sim`] (the simulated
//! multi-bus network every test and the demo run on).
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

#[cfg(feature = "alloc")]
extern crate alloc;

pub mod abort;
#[cfg(feature = "std")]
pub mod capture;
pub mod cob_id;
pub mod emcy;
pub mod frame;
pub mod guarding;
pub mod heartbeat;
pub mod machine;
#[cfg(feature = "alloc")]
pub mod master;
pub mod nmt;
pub mod node;
pub mod od;
pub mod pdo;
pub mod port;
pub mod profile;
pub mod queue;
#[cfg(feature = "std")]
pub mod report;
#[cfg(feature = "tokio")]
pub mod runtime;
pub mod sdo;
#[cfg(feature = "std")]
pub mod sim;
pub mod sync;
pub mod time;
pub mod time_stamp;

pub use abort::AbortCode;
pub use cob_id::{CobId, NodeId};
pub use frame::{Frame, Id};
pub use machine::{BusLink, Device, Machine, PortStatus, Station};
pub use nmt::{NmtCommand, NmtState, NmtTarget};
pub use node::{Node, NodeConfig, NodeEvent, NodeEventKind};
pub use time::{Duration, Instant};
