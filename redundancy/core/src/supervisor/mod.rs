//! Layer 2, the **supervisor** of a redundant master, on top of the stack's CiA 302-2 master.
//!
//! | Part | Module |
//! | --- | --- |
//! | Slave-pair supervision: the pair table, joining, per-member deadlines, switch-over | [`pairs`] |
//! | CiA 302-2 flying master: strong/weak by priority, takeover, conflict resolution | [`flying_master`] |
//! | The audit trail of every role change, switch and toggle (and board addressed by LSS) | [`audit`] |
//! | Heartbeat-only error control on a CANopen FD network (features `fd`, `alloc`): guarding configured there is refused at start | `fd_guarding` |
//! | [`Supervisor`] (feature `alloc`): the machine composing them with the master; board replacement by LSS (CiA 305): a pair member arriving without node-ID is given its slot's ([`SupervisorConfig::with_lss`]) | `machine` |
//!
//! The supervisor decides; the dual-bus layer below is told the outcome (which board of a pair
//! is active) through [`LinkCommand`]s.
//!
//! One master, one pair of boards on two simulated buses. Board A is active; when it loses
//! power, B takes over exactly the consumer time after A's last heartbeat:
//!
//! ```
//! use duocan_core::machine::StationEvent;
//! use duocan_core::master::{objects, Master, MasterConfig};
//! use duocan_core::od::comm;
//! use duocan::sim::{BusConfig, SimNetwork};
//! use duocan_core::{Duration, Instant, Node, NodeConfig, NodeId, Station};
//! use duocan_redundancy_core::supervisor::pairs::{PairsEvent, RoleReason};
//! use duocan_redundancy_core::{DualBus, DualBusConfig, Member, PairId, PairSpec};
//! use duocan_redundancy_core::{SupervisedStation, Supervisor, SupervisorConfig, SupervisorEvent};
//!
//! let ms = Duration::from_millis;
//! let mut sim = SimNetwork::new(1);
//! let buses = [sim.add_bus(BusConfig::new("can1", 1_000_000)), sim.add_bus(BusConfig::new("can2", 1_000_000))];
//! let od = objects::master_dictionary(1, comm::Identity::default());
//! let master = Master::new(NodeId::must(1), od, MasterConfig::new())?;
//! // Priority 0 at node 1: a 20 ms heartbeat, 50 ms master timeout, SYNC every 10 ms.
//! let mut sup = Supervisor::new(master, SupervisorConfig::new(0, NodeId::must(1), ms(20), ms(50), ms(10)), Instant::ZERO);
//! // Boards 0x10 (A) and 0x50 (B) beat every 20 ms; 50 ms of silence is a failure.
//! sup.add_pair(Instant::ZERO, PairSpec::new(NodeId::must(0x10), NodeId::must(0x50), ms(20), ms(50)))?;
//! let m = sim.add_device("master", SupervisedStation::new(DualBus::new(DualBusConfig::default()), sup)?, &buses)?;
//! let mut boards = Vec::new();
//! for id in [0x10, 0x50] {
//!     let mut n = Node::new(NodeConfig::slave(NodeId::must(id)), comm::standard_dictionary(id, Default::default()));
//!     n.boot(Instant::ZERO);
//!     boards.push(sim.add_device(format!("board {id:#x}"), Station::new(DualBus::new(DualBusConfig::default()), n), &buses)?);
//! }
//! sim.run_until(Instant::from_secs(1));
//! let active = |sim: &SimNetwork| sim.device(m).sup().pair_supervisor().pair(PairId(0)).unwrap().active;
//! assert_eq!(active(&sim), Some(Member::A));
//!
//! sim.power_off(boards[0]);
//! sim.run_until(Instant::from_secs(2));
//! assert_eq!(active(&sim), Some(Member::B));
//! let switch = sim.events(m).iter().find_map(|(_, e)| match e {
//!     StationEvent::Machine(SupervisorEvent::Pairs(PairsEvent::Role(r))) if r.to == Some(Member::B) => Some(*r),
//!     _ => None,
//! }).unwrap();
//! let RoleReason::ActiveSilent { last } = switch.reason else { panic!("{switch}") };
//! assert_eq!((switch.from, switch.at), (Some(Member::A), last + ms(50)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # The clock contract
//!
//! The supervisor keeps [duocan's clock contract](duocan_core::frame::instant#the-clock-contract), as
//! the [dual-bus layer](crate::link#the-clock-contract) does:
//!
//! - **A step back** is noticed by one [`TimeWatch`](duocan_core::frame::instant::TimeWatch) in the
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
//! - **A short jump ahead** is time that passed: what is due in between is handled once (a
//!   pair member's silence, the flying master's detection cycle on its grid, a planned switch
//!   on the SYNC grid computed rather than stepped through).
//! - **A jump ahead the supervisor did not watch** — an input at least
//!   [`PairsConfig::clock_jump`](pairs::PairsConfig::clock_jump) (1 s by default; never less
//!   than twice this master's heartbeat period, since its own heartbeat calls for an input every
//!   period) after the latest time the supervisor was given, or one later than the earliest
//!   deadline it reported by at least the smallest slack of its timeouts (a pair's consumer time
//!   less its producer time, the master timeout less this master's heartbeat period; at least
//!   1 ms): its driver was to call it at that deadline, and a span that long can hold every
//!   heartbeat a watched node sent within its timeout — is not taken for time the supervisor
//!   watched: the network ran on, and the frames that would have met the deadlines in
//!   between were not seen (a clock set forward, or a driver that stalled). Every pair member
//!   whose deadline falls after that latest time is observed again
//!   ([`PairSupervisor::jumped`](pairs::PairSupervisor::jumped)): it is judged silent (or not
//!   running) only if it stays so for its consumer time after the jump, so a board that is alive
//!   is not reset, and one that died is replaced at the jump's end (the first input after it) +
//!   its consumer time, its standby's start on the bus within 1 ms more. The other masters are
//!   observed again likewise ([`FlyingMaster::jumped`](flying_master::FlyingMaster::jumped)): one
//!   heard before the jump is no master returning from a loss, a standby takes over at the
//!   earliest the master timeout after the jump. What was due before that latest time was
//!   watched and is handled as always.
//! - **A silence of the whole network** as long as that slack — no frame handed over from
//!   anyone — is observed again in the same way, once per longest timeout: with every node
//!   beating, nothing at all is a receive path that ran behind (a reader held up, a port queue
//!   behind) or a cut at this master's own connector, not every node dead at once. A node that
//!   really died meanwhile is found one timeout later.
//! - **At [`Instant::MAX`](duocan_core::Instant::MAX)** no deadline is reported, so nothing stays
//!   due.

pub mod audit;
#[cfg(feature = "alloc")]
mod config;
#[cfg(feature = "alloc")]
mod events;
#[cfg(all(feature = "fd", feature = "alloc"))]
pub mod fd_guarding;
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
pub use events::{AddPairError, JoinRefusal, NotJoined, SupervisorEvent, SupervisorStats};
#[cfg(feature = "alloc")]
pub use machine::{Supervisor, LSS_SLOTS};
