//! Heartbeat-only error control on a CANopen FD network (features `fd` and `alloc`).
//!
//! **Why.** Node guarding is a master asking each node with a remote frame and the node
//! answering with its state; CAN FD has no remote frames, and CANopen FD (CiA 1301) leaves
//! node and life guarding out: error control there is heartbeats alone. A supervisor on an FD
//! network configured to guard would rely on frames the network does not carry, and a live
//! node would be reported lost (or a slave, its life guarding never fed, would leave its
//! operational state). So guarding is a configuration error on an FD network, found at start
//! like a classic-only device on a CAN FD bus: [`Supervisor::check_fd`] names the first node
//! configured for it and how, and the redundant network's builder refuses such a network before
//! anything runs.
//!
//! What the check looks at, every slave of the master (pair members included):
//!
//! - the master's guarding of the slave: a guard time in its 0x1F81 entry
//!   ([`Assignment::guard_time_ms`]);
//! - the slave's own life guarding: a configuration write of a non-zero guard time (0x100C) or
//!   life time factor (0x100D) in what the master writes into it at boot
//!   ([`SlaveConfig::steps`](duocan_core::master::SlaveConfig::steps));
//! - the master's own life guarding: its dictionary's 0x100C and 0x100D both non-zero (another
//!   master would guard it).
//!
//! Nothing else changes on an FD network: the pair supervision, the flying master and the
//! dual-bus layer's port self-diagnosis (port health, the silence rule, the plausibility watch)
//! judge heartbeats, which are classic frames on either kind of bus.

use super::Supervisor;
use core::fmt;
use duocan_core::master::{Assignment, ConfigStep, SlaveConfig};
use duocan_core::od::{comm, ObjectDictionary};
use duocan_core::profile::IdProfile;
use duocan_core::NodeId;

/// How a node is configured for guarding (see [`GuardingOnFd`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum GuardingSource {
    /// The master guards the slave: its 0x1F81 entry holds this guard time, in ms.
    MasterGuards {
        /// The guard time.
        guard_time_ms: u16,
    },
    /// The master's configuration of the slave writes a non-zero value to this object: the
    /// guard time (0x100C) or the life time factor (0x100D), the slave's life guarding.
    SlaveConfig {
        /// 0x100C or 0x100D.
        index: u16,
    },
    /// The master's own dictionary holds a guard time and a life time factor (0x100C,
    /// 0x100D): it expects to be guarded itself.
    OwnDictionary,
}

/// Node guarding configured on a CANopen FD network, which carries no remote frames: a
/// configuration error found at start ([`Supervisor::check_fd`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GuardingOnFd {
    /// The node configured for guarding.
    pub node: NodeId,
    /// How.
    pub source: GuardingSource,
}

impl fmt::Display for GuardingOnFd {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "node {:#04x}: ", self.node.raw())?;
        match self.source {
            GuardingSource::MasterGuards { guard_time_ms } => write!(
                f,
                "the master guards it (guard time {guard_time_ms} ms in 0x1F81)"
            )?,
            GuardingSource::SlaveConfig { index } => write!(
                f,
                "its configuration sets life guarding ({index:#06x} non-zero)"
            )?,
            GuardingSource::OwnDictionary => {
                f.write_str("the master's dictionary sets its own life guarding (0x100C, 0x100D)")?
            }
        }
        f.write_str(
            ": node guarding on a CANopen FD network, which has no remote frames: \
             use heartbeats (0x1016/0x1017) alone",
        )
    }
}

impl core::error::Error for GuardingOnFd {}

impl GuardingSource {
    /// How the master's configuration of a slave sets up guarding, if it does: a guard time
    /// in its 0x1F81 entry, or a write of a non-zero 0x100C or 0x100D among its configuration
    /// steps. What a builder checks before anything is built.
    #[must_use]
    pub fn of_slave(cfg: &SlaveConfig) -> Option<GuardingSource> {
        let guard = cfg.assignment.guard_time_ms();
        let assigned = (guard != 0).then_some(GuardingSource::MasterGuards {
            guard_time_ms: guard,
        });
        assigned.or_else(|| {
            cfg.steps.iter().find_map(|step| match step {
                ConfigStep::Write {
                    index,
                    sub: 0,
                    data,
                } if (*index == comm::GUARD_TIME || *index == comm::LIFE_TIME_FACTOR)
                    && data.iter().any(|b| *b != 0) =>
                {
                    Some(GuardingSource::SlaveConfig { index: *index })
                }
                _ => None,
            })
        })
    }

    fn of_assignment(a: Assignment) -> Option<GuardingSource> {
        (a.is_slave() && a.guard_time_ms() != 0).then_some(GuardingSource::MasterGuards {
            guard_time_ms: a.guard_time_ms(),
        })
    }
}

impl<D: ObjectDictionary, P: IdProfile> Supervisor<D, P> {
    /// Whether this supervisor may run on a CANopen FD network: an error naming the first
    /// node configured for node guarding (the master's guarding of a slave, a slave's life
    /// guarding in its configuration, the master's own), which CAN FD cannot carry (see
    /// [`fd_guarding`](crate::supervisor::fd_guarding)). Called before the network runs, and
    /// again after slaves are added at run time.
    pub fn check_fd(&self) -> Result<(), GuardingOnFd> {
        let master = self.master();
        let own = master.node().od();
        let set = |index| own.get_u32(index, 0).unwrap_or(0) != 0;
        if set(comm::GUARD_TIME) && set(comm::LIFE_TIME_FACTOR) {
            return Err(GuardingOnFd {
                node: master.node().id(),
                source: GuardingSource::OwnDictionary,
            });
        }
        for v in master.slaves() {
            // The live 0x1F81 entry first (written after the configuration, it rules).
            let source = GuardingSource::of_assignment(v.assignment).or_else(|| {
                master
                    .slave_config(v.node)
                    .and_then(GuardingSource::of_slave)
            });
            if let Some(source) = source {
                return Err(GuardingOnFd {
                    node: v.node,
                    source,
                });
            }
        }
        Ok(())
    }
}
