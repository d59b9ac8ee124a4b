//! What a node tells its application: typed events with timestamps, counters, errors.

use super::TX_QUEUE;
use crate::cia301::emcy::EmcyMessage;
use crate::cia301::nmt::{NmtCommand, NmtState};
use crate::cia301::pdo::PdoEvent;
use crate::cia301::time_stamp::TimeOfDay;
use crate::cia304::srdo::config::SrdoConfigError;
use crate::cia304::srdo::SrdoEvent;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::frame::Id;
use crate::frame::Malformed;
use crate::od::parameters::{LoadReport, ParameterGroup, StorageError};
use core::fmt;

/// Why the local NMT state changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateCause {
    /// Power-on or reset: the boot-up sequence.
    Boot,
    /// An NMT command from the bus.
    Command(NmtCommand),
    /// The application asked.
    Local,
}

/// Who wrote a dictionary entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Writer {
    /// The application (or the stack itself).
    Local,
    /// A remote client over SDO.
    Sdo,
}

/// What a failed parameter-storage operation was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StorageAction {
    /// Storing a group (0x1010).
    Store(ParameterGroup),
    /// Restoring a group's defaults (0x1011).
    Restore(ParameterGroup),
    /// Loading the stored values at power-on or at a reset.
    Load,
    /// Taking the power-on image at boot: the dictionary has no room for it (the NMT resets
    /// then restore the previous image, or the defaults).
    CapturePowerOn,
}

/// What happened, and when.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeEvent {
    /// When it happened (for timeouts: exactly the deadline).
    pub at: Instant,
    /// What happened.
    pub kind: NodeEventKind,
}

/// The kinds of [`NodeEvent`].
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum NodeEventKind {
    /// This node's NMT state changed.
    StateChanged {
        /// Previous state.
        from: NmtState,
        /// New state.
        to: NmtState,
        /// Why.
        cause: StateCause,
    },
    /// Another node sent its boot-up message.
    BootUp {
        /// The node.
        node: NodeId,
    },
    /// Another node's state (from heartbeat or guarding) differs from what was known.
    RemoteState {
        /// The node.
        node: NodeId,
        /// Previously known state, if any.
        from: Option<NmtState>,
        /// State now.
        to: NmtState,
    },
    /// A monitored node's heartbeat stopped: fires at `last` + consumer time.
    HeartbeatTimeout {
        /// The node.
        node: NodeId,
        /// Its last heartbeat.
        last: Instant,
    },
    /// A monitored node's heartbeat came back.
    HeartbeatResumed {
        /// The node.
        node: NodeId,
    },
    /// A guarded node did not answer within its life time.
    GuardingTimeout {
        /// The node.
        node: NodeId,
    },
    /// A guarded node answers again.
    GuardingResumed {
        /// The node.
        node: NodeId,
    },
    /// A guarded node's toggle bit did not alternate.
    GuardToggleError {
        /// The node.
        node: NodeId,
    },
    /// This node's master stopped guarding it (life guarding event).
    LifeGuardingLost,
    /// Guarding requests arrive again.
    LifeGuardingResumed,
    /// SYNC produced or received.
    Sync {
        /// Its counter, if it carries one.
        counter: Option<u8>,
        /// True if this node produced it.
        produced: bool,
    },
    /// TIME received (the local clock follows it if this node consumes TIME).
    Time {
        /// The time of day received.
        tod: TimeOfDay,
    },
    /// EMCY from another node.
    Emcy {
        /// The node.
        node: NodeId,
        /// The message.
        msg: EmcyMessage,
    },
    /// A dictionary entry was written and the stack reacted.
    ObjectWritten {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Who wrote it.
        by: Writer,
    },
    /// An NMT command was seen on the bus (whether or not it addressed this node).
    NmtObserved {
        /// The command.
        cmd: NmtCommand,
        /// The addressed node-ID byte (0 = all).
        target: u8,
    },
    /// The PDO engine reports something.
    Pdo(PdoEvent),
    /// The SRDOs report (CiA 304): a consumer in its safe state, a GFC received, …
    Srdo(SrdoEvent),
    /// The node was asked to enter operational and stays where it is: its SRDO configuration
    /// is not marked valid (0x13FE) or does not pass its checks and checksum (0x13FF).
    OperationalRefused {
        /// What is wrong, and where.
        reason: SrdoConfigError,
    },
    /// A group's parameters were stored (0x1010 `"save"`).
    ParametersStored {
        /// The group.
        group: ParameterGroup,
        /// Who asked.
        by: Writer,
    },
    /// A group's stored parameters were removed (0x1011 `"load"`): its defaults apply from the
    /// next reset that reloads it.
    DefaultsRestored {
        /// The group.
        group: ParameterGroup,
        /// Who asked.
        by: Writer,
    },
    /// Stored parameters were loaded at power-on or at a reset.
    ParametersLoaded(LoadReport),
    /// A store, restore or load of parameters failed. A store or restore changed nothing on
    /// the medium; a failed load leaves the power-on values in place.
    StorageFailed {
        /// What was attempted.
        action: StorageAction,
        /// Why it failed.
        error: StorageError,
    },
    /// A frame was refused as malformed (nothing changed because of it).
    Malformed {
        /// Its identifier.
        id: Id,
        /// What was wrong.
        reason: Malformed,
    },
}

/// One line, as an operator reads it: `node 0x10: guarding answers again`, `this node:
/// pre-operational -> operational (NMT start)`, `all parameters stored over SDO`.
impl fmt::Display for NodeEventKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let by = |w: &Writer| match w {
            Writer::Local => "locally",
            Writer::Sdo => "over SDO",
        };
        match self {
            NodeEventKind::StateChanged { from, to, cause } => {
                write!(f, "this node: {from} -> {to}")?;
                match cause {
                    StateCause::Boot => f.write_str(" (boot)"),
                    StateCause::Command(c) => write!(f, " (NMT {c})"),
                    StateCause::Local => f.write_str(" (application)"),
                }
            }
            NodeEventKind::BootUp { node } => write!(f, "{node}: boot-up"),
            NodeEventKind::RemoteState { node, to, .. } => write!(f, "{node}: {to}"),
            NodeEventKind::HeartbeatTimeout { node, last } => {
                write!(f, "{node}: heartbeat lost (last at {last})")
            }
            NodeEventKind::HeartbeatResumed { node } => write!(f, "{node}: heartbeat back"),
            NodeEventKind::GuardingTimeout { node } => {
                write!(f, "{node}: no guarding answer within its life time")
            }
            NodeEventKind::GuardingResumed { node } => write!(f, "{node}: guarding answers again"),
            NodeEventKind::GuardToggleError { node } => {
                write!(f, "{node}: guarding toggle bit did not alternate")
            }
            NodeEventKind::LifeGuardingLost => {
                f.write_str("this node: its master stopped guarding it (life guarding event)")
            }
            NodeEventKind::LifeGuardingResumed => f.write_str("this node: guarded again"),
            NodeEventKind::Sync { counter, produced } => {
                f.write_str(if *produced {
                    "SYNC sent"
                } else {
                    "SYNC received"
                })?;
                match counter {
                    Some(c) => write!(f, ", counter {c}"),
                    None => Ok(()),
                }
            }
            NodeEventKind::Time { tod } => {
                let s = tod.ms / 1000;
                write!(
                    f,
                    "TIME received: day {} since 1984, {:02}:{:02}:{:02}.{:03}",
                    tod.days,
                    s / 3600,
                    s / 60 % 60,
                    s % 60,
                    tod.ms % 1000
                )
            }
            NodeEventKind::Emcy { node, msg } => {
                write!(f, "{node}: EMCY {:#06x} {}", msg.code, msg.text())
            }
            NodeEventKind::ObjectWritten { index, sub, by: w } => {
                write!(f, "{index:#06x}sub{sub} written {}", by(w))
            }
            NodeEventKind::NmtObserved { cmd, target } => match target {
                0 => write!(f, "NMT {cmd} for all nodes seen"),
                t => write!(f, "NMT {cmd} for node {t:#04x} seen"),
            },
            NodeEventKind::Pdo(e) => fmt::Display::fmt(e, f),
            NodeEventKind::Srdo(e) => fmt::Display::fmt(e, f),
            NodeEventKind::OperationalRefused { reason } => {
                write!(f, "this node: operational refused, {reason}")
            }
            NodeEventKind::ParametersStored { group, by: w } => {
                write!(f, "{group} stored {}", by(w))
            }
            NodeEventKind::DefaultsRestored { group, by: w } => write!(
                f,
                "{group}: defaults restored {}, they apply from the next reset",
                by(w)
            ),
            NodeEventKind::ParametersLoaded(r) => write!(
                f,
                "stored parameters loaded: {} applied, {} left out",
                r.applied, r.skipped
            ),
            NodeEventKind::StorageFailed { action, error } => {
                match action {
                    StorageAction::Store(g) => write!(f, "storing {g} failed")?,
                    StorageAction::Restore(g) => write!(f, "restoring the defaults of {g} failed")?,
                    StorageAction::Load => f.write_str("loading the stored parameters failed")?,
                    StorageAction::CapturePowerOn => {
                        f.write_str("no room for the power-on image of the parameters")?
                    }
                }
                write!(f, ": {error}")
            }
            NodeEventKind::Malformed { id, reason } => {
                write!(f, "malformed frame {id} refused: {reason}")
            }
        }
    }
}

impl fmt::Display for NodeEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.kind, f)
    }
}

/// Counters a node keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeStats {
    /// Frames handed to the node.
    pub rx_frames: u64,
    /// Frames the node produced.
    pub tx_frames: u64,
    /// Frames refused as malformed.
    pub malformed: u64,
    /// Frames no service of this node handles.
    pub unhandled: u64,
    /// Frames dropped because the transmit queue was full.
    pub tx_dropped: u32,
    /// Events dropped because the application did not drain them.
    pub events_dropped: u32,
}

/// The transmit queue is full: the driver has not drained it. Retry after draining.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueueFull;

impl fmt::Display for QueueFull {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "node transmit queue full ({TX_QUEUE} frames): drain poll_transmit and retry"
        )
    }
}

impl core::error::Error for QueueFull {}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each kind is one line an operator reads.
    #[test]
    fn node_events_print_one_line_each() {
        let node = NodeId::must(0x0A);
        assert_eq!(
            NodeEventKind::GuardingResumed { node }.to_string(),
            "node 0x0a: guarding answers again"
        );
        assert_eq!(
            NodeEventKind::StateChanged {
                from: NmtState::PreOperational,
                to: NmtState::Operational,
                cause: StateCause::Command(NmtCommand::Start),
            }
            .to_string(),
            format!(
                "this node: {} -> {} (NMT start)",
                NmtState::PreOperational,
                NmtState::Operational
            )
        );
        assert_eq!(
            NodeEventKind::Time {
                tod: TimeOfDay {
                    days: 15000,
                    ms: 3_723_004
                }
            }
            .to_string(),
            "TIME received: day 15000 since 1984, 01:02:03.004"
        );
        assert_eq!(
            NodeEventKind::Pdo(PdoEvent::RpdoTooShort {
                pdo: 2,
                expected: 4,
                got: 3
            })
            .to_string(),
            "RPDO 2 refused: 3 bytes, its mapping needs 4"
        );
        assert_eq!(
            NodeEventKind::ParametersStored {
                group: ParameterGroup::All,
                by: Writer::Sdo
            }
            .to_string(),
            "all parameters stored over SDO"
        );
    }
}
