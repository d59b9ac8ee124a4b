//! The boot process of one slave (CiA 302-2 "boot slave"): identity check, configuration,
//! error control start, as a pure state machine. It names the SDO access to do next and is told
//! how each ended; the master carries the accesses over its SDO client and decides about
//! starting (`boot_run.rs`).
//!
//! Order: 0x1000 (always read: a slave that does not answer is missing, status B), then 0x1018
//! sub 1–4 where 0x1F85–0x1F88 expect a value (0 = not checked); where 0x1F26/0x1F27 expect a
//! configuration date and time, 0x1020 sub 1 and 2 (both equal: configured already, nothing is
//! written); then every configuration step, then the producer heartbeat time (0x1017) so that
//! the heartbeat starts from a configured slave; then, unless a write was refused, the expected
//! date and time into 0x1020 and, if asked for, 0x1010 sub 1 "save".
//!
//! `status.rs` holds what the rest of the master and the application see of it: the CiA 302-2
//! error status letters, why a step failed, the phase a slave is in. `process.rs` holds the
//! process itself; `tests.rs` runs it against scripted answers.

mod process;
mod status;
#[cfg(test)]
mod tests;

pub(crate) use process::{Access, Outcome, Process};
pub use status::{BootError, BootPhase, ErrorStatus, IdentityMismatch};
