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
