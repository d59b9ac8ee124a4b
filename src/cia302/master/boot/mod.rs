//! The boot process of one slave (CiA 302-2 "boot slave"): identity check, configuration,
//! error control start, as a pure state machine. It names the SDO access to do next and is told
//! how each ended; the master carries the accesses over its SDO client and decides about
//! starting (`boot_run.rs`).
//!
//! Order: 0x1000 (always read: a slave that does not answer is missing, status B), then 0x1018
//! sub 1–4 where 0x1F85–0x1F88 expect a value (0 = not checked), then every configuration step,
//! then the producer heartbeat time (0x1017) so that the heartbeat starts from a configured slave.
//!
//! `status.rs` holds what the rest of the master and the application see of it: the CiA 302-2
//! error status letters, why a step failed, the phase a slave is in. `process.rs` holds the
//! process itself; `tests.rs` runs it against scripted answers.

mod process;
mod status;
#[cfg(test)]
mod tests;

pub(crate) use process::{Access, Outcome, Process};
pub use status::{BootError, BootPhase, ErrorStatus};
