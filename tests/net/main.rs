//! The front door (`duocan::net`): the network handle and remote nodes on the in-memory bus
//! and the simulated nodes, and the starter examples built on it.

mod concurrent_sdo;
mod door_checks;
mod events;
mod examples;
mod ext;
mod fd_pdo;
mod monitor;
mod named;
mod nmt;
mod own_core;
mod pdo;
mod ports;
mod program;
#[path = "../common/runtime.rs"]
mod rt;
mod sdo;
mod sdo_stream;
mod tap;
mod usdo;
