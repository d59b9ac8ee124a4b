//! Layer 2, the **supervisor** of a redundant master, on top of the stack's CiA 302-2 master.
//!
//! | Part | Module |
//! | --- | --- |
//! | Slave-pair supervision: the pair table, joining, per-member deadlines, switch-over | [`pairs`] |
//! | CiA 302-2 flying master: strong/weak by priority, takeover, conflict resolution | [`flying_master`] |
//! | The audit trail of every role change, switch and toggle | [`audit`] |
//! | [`Supervisor`] (feature `alloc`): the machine composing them with the master | `machine` |
//!
//! The supervisor decides; the dual-bus layer below is told the outcome (which board of a pair
//! is active) through [`LinkCommand`]s.
//!
//! # The clock contract
//!
//! The supervisor keeps [duocan's clock contract](duocan::frame::instant#the-clock-contract), as
//! the [dual-bus layer](crate::link#the-clock-contract) does:
//!
//! - **A step back** is noticed by one [`TimeWatch`](duocan::frame::instant::TimeWatch) in the
//!   `Supervisor`, on every input that carries a time (a frame, `handle_timeout`, a request of
//!   the layer, an application command), measured from the latest time it was given. It then
//!   moves back by the step every time held: the pair table's last heartbeats, phase starts,
//!   silence deadlines and adoption hold-offs ([`PairSupervisor::step_back`](pairs::PairSupervisor::step_back));
//!   the flying master's peers' last heartbeats and the deadlines of its phase — detection,
//!   negotiation, takeover, the active master's detection cycle, suspension and hand-back
//!   ([`FlyingMaster::step_back`](flying_master::FlyingMaster::step_back)); the last SYNC and
//!   a planned hand-over. The CiA 302-2 master watches the clock itself (its node and SDO
//!   client too): it is not shifted by the supervisor but shown the latest time and then the
//!   new one, so that it measures the same step once. A board or a master that dies right
//!   after a step is failed over exactly when it would have been on a clock that never stepped,
//!   in the new time line. The [audit trail](audit) keeps the instants things happened at, as
//!   reported, like events already queued.
//! - **A jump ahead** is time that passed: what is due in between is handled once (a pair
//!   member's silence, the flying master's detection cycle on its grid, a planned switch on the
//!   SYNC grid computed rather than stepped through).
//! - **At [`Instant::MAX`](duocan::Instant::MAX)** no deadline is reported, so nothing stays
//!   due.

pub mod audit;
#[cfg(feature = "alloc")]
mod config;
#[cfg(feature = "alloc")]
mod events;
pub mod flying_master;
#[cfg(feature = "alloc")]
mod machine;
pub mod pairs;

// Defined with the layer that takes it (the layer cannot look up here); the supervisor's
// vocabulary all the same.
pub use crate::link::dual_bus::LinkCommand;
#[cfg(feature = "alloc")]
pub use config::{SupervisorConfig, EVENT_QUEUE};
#[cfg(feature = "alloc")]
pub use events::{AddPairError, JoinRefusal, SupervisorEvent, SupervisorStats};
#[cfg(feature = "alloc")]
pub use machine::Supervisor;
