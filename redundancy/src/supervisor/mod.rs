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
