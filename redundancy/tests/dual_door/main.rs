//! duocan's plain front door (`duocan::net::Network`: an observer and an SDO client, no master)
//! on two buses through the dual-bus layer (`duocan_redundancy::net::DualLink`), and the
//! simulated redundant station behind `open_dual_named("sim-station")`; and the redundant master's
//! door (`RedundantNetwork`) on the same kind of rig. On tokio's paused clock.

#[path = "../../../tests/net/door_checks.rs"]
mod door_checks;
mod doors;
mod link;
mod lss;
mod program;
mod redundant;
mod station;
mod stream;
mod usdo;
