//! What the master reports: typed events with timestamps, the per-slave view, counters, errors.

use super::boot::{BootError, BootPhase, ErrorStatus, IdentityMismatch};
use super::config::{Assignment, StartPolicy};
use crate::cia301::nmt::{NmtCommand, NmtState, NmtTarget};
use crate::cia301::pdo::Dir;
use crate::cia301::sdo::SdoEvent;
use crate::frame::cob_id::NodeId;
use crate::frame::cob_id::NodeSet;
use crate::frame::instant::Instant;
use crate::node::NodeEventKind;
use crate::od::abort::AbortCode;
use core::fmt;

/// What happened, and when.
#[derive(Clone, Debug, PartialEq)]
pub struct MasterEvent {
    /// When (for the node's timeouts: exactly the deadline).
    pub at: Instant,
    /// What.
    pub kind: MasterEventKind,
}

/// The kinds of [`MasterEvent`].
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum MasterEventKind {
    /// From the master's own node (passed through unchanged).
    Node(NodeEventKind),
    /// The result of an SDO transfer the application started on [`super::Master::sdo_mut`]
    /// (the master's own transfers are reported through the events below).
    Sdo(SdoEvent),
    /// An assigned slave sent its boot-up; the boot process starts if the master is active.
    SlaveBootUp {
        /// The slave.
        node: NodeId,
    },
    /// The slave is not what 0x1F84–0x1F88 expect; it is not configured nor started.
    IdentityMismatch {
        /// The slave.
        node: NodeId,
        /// Which entry, what was expected and what the slave has.
        mismatch: IdentityMismatch,
    },
    /// A step of the boot process failed; the slave is not started.
    ConfigFailed {
        /// The slave.
        node: NodeId,
        /// The CiA 302-2 error status.
        status: ErrorStatus,
        /// Which access failed and how.
        reason: BootError,
    },
    /// How far a program download is ([`super::Master::download_program`]): bytes of the
    /// image the slave confirmed, of `total`. Reported when it starts and as it moves.
    ProgramProgress {
        /// The slave.
        node: NodeId,
        /// Bytes confirmed.
        done: usize,
        /// Bytes of the image.
        total: usize,
    },
    /// A program download ended: the new program runs and identifies as expected, or the
    /// step that failed and how.
    ProgramDownloaded {
        /// The slave.
        node: NodeId,
        /// The outcome.
        result: Result<super::ProgramReport, super::ProgramDownloadError>,
    },
    /// The slave refused one configuration write (its [`SlaveConfig`](super::SlaveConfig) has
    /// [`WriteAborts::Continue`](super::WriteAborts::Continue)); the boot goes on with the
    /// next step.
    ConfigWriteAborted {
        /// The slave.
        node: NodeId,
        /// The object written.
        index: u16,
        /// Its sub-index.
        sub: u8,
        /// The slave's abort code.
        code: AbortCode,
    },
    /// The slave's identity was checked and its configuration written; it is ready to start.
    SlaveConfigured {
        /// The slave.
        node: NodeId,
        /// Whether the master starts it or leaves that to the application.
        start: StartPolicy,
    },
    /// The master started the slave.
    SlaveStarted {
        /// The slave.
        node: NodeId,
        /// By the "start all nodes" broadcast.
        broadcast: bool,
    },
    /// The slave was found in `state` and left as it was (keep-alive slave at the master's
    /// boot, status L; or any slave at a takeover).
    SlaveAdopted {
        /// The slave.
        node: NodeId,
        /// Its state.
        state: NmtState,
    },
    /// Error control lost the slave: heartbeat (E), guarding (F), or no heartbeat after it was
    /// configured (K).
    SlaveLost {
        /// The slave.
        node: NodeId,
        /// E, F or K.
        status: ErrorStatus,
    },
    /// The boot time (0x1F89) passed with these mandatory slaves not booted: the network is not
    /// started (it starts when they are).
    MandatoryMissing {
        /// The slaves.
        nodes: NodeSet,
    },
    /// Every mandatory slave is booted and the network was started.
    NetworkStarted {
        /// With one "start all nodes" broadcast.
        broadcast: bool,
        /// At a takeover, found running (nothing was sent).
        takeover: bool,
    },
    /// A request NMT (0x1F82) write from another node (or the application).
    NmtRequest {
        /// The addressed node(s).
        target: NmtTarget,
        /// The command asked for.
        cmd: NmtCommand,
        /// False if the master did not send it (standby, or a reset of the master itself).
        sent: bool,
    },
    /// The master became active or standby.
    ActiveChanged {
        /// Active now.
        active: bool,
    },
    /// The master could not add a heartbeat consumer entry (0x1016) for an assigned slave.
    ConsumerNotConfigured {
        /// The slave.
        node: NodeId,
        /// Why the dictionary refused it.
        code: AbortCode,
    },
    /// A write to 0x1F81 made a node a slave while every slot of the master was taken
    /// ([`MasterConfig::max_slaves`](super::MasterConfig::max_slaves)): the entry was set back
    /// to 0 (not a slave).
    TooManySlaves {
        /// The node.
        node: NodeId,
        /// The master's slots.
        capacity: usize,
    },
}

/// One line, as an operator reads it: `node 0x10: configured, the master starts it`,
/// `node 0x10: not started, error status D: …`, `node 0x10: lost, error status E: …`.
impl fmt::Display for MasterEventKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MasterEventKind::Node(k) => write!(f, "this master's node: {k}"),
            MasterEventKind::Sdo(e) => fmt::Display::fmt(e, f),
            MasterEventKind::SlaveBootUp { node } => {
                write!(f, "{node}: boot-up, slave of this master")
            }
            MasterEventKind::IdentityMismatch { node, mismatch } => {
                write!(f, "{node}: not started, {mismatch}")
            }
            MasterEventKind::ConfigFailed {
                node,
                status,
                reason,
            } => write!(f, "{node}: not started, {status} ({reason})"),
            MasterEventKind::ProgramProgress { node, done, total } => {
                write!(f, "{node}: program download, {done} of {total} bytes")
            }
            MasterEventKind::ProgramDownloaded { node, result } => match result {
                Ok(r) => write!(
                    f,
                    "{node}: program downloaded, {} bytes, software {:#010x} runs",
                    r.bytes, r.identification
                ),
                Err(e) => write!(f, "{node}: {e}"),
            },
            MasterEventKind::ConfigWriteAborted {
                node,
                index,
                sub,
                code,
            } => write!(
                f,
                "{node}: configuration write {index:#06x}sub{sub} refused ({code}), boot goes on"
            ),
            MasterEventKind::SlaveConfigured { node, start } => match start {
                StartPolicy::Auto => write!(f, "{node}: configured, the master starts it"),
                StartPolicy::Application => {
                    write!(f, "{node}: configured, the application starts it")
                }
            },
            MasterEventKind::SlaveStarted { node, broadcast } => {
                if *broadcast {
                    write!(f, "{node}: started (start all nodes)")
                } else {
                    write!(f, "{node}: started")
                }
            }
            MasterEventKind::SlaveAdopted { node, state } => {
                write!(f, "{node}: found {state}, left as it is")
            }
            MasterEventKind::SlaveLost { node, status } => write!(f, "{node}: lost, {status}"),
            MasterEventKind::MandatoryMissing { nodes } => write!(
                f,
                "network not started: mandatory slaves {nodes} not booted within the boot time"
            ),
            MasterEventKind::NetworkStarted {
                broadcast,
                takeover,
            } => f.write_str(match (takeover, broadcast) {
                (true, _) => "network found running at the takeover",
                (false, true) => "network started (start all nodes)",
                (false, false) => "network started",
            }),
            MasterEventKind::NmtRequest { target, cmd, sent } => {
                match target {
                    NmtTarget::All => write!(f, "request NMT {cmd} for all nodes")?,
                    NmtTarget::Node(n) => write!(f, "request NMT {cmd} for {n}")?,
                }
                f.write_str(if *sent { ", sent" } else { ", not sent" })
            }
            MasterEventKind::ActiveChanged { active } => f.write_str(if *active {
                "this master: active"
            } else {
                "this master: standby"
            }),
            MasterEventKind::ConsumerNotConfigured { node, code } => write!(
                f,
                "{node}: no heartbeat consumer entry (0x1016) for it: {code}"
            ),
            MasterEventKind::TooManySlaves { node, capacity } => write!(
                f,
                "{node}: not made a slave, all {capacity} slots of the master are taken"
            ),
        }
    }
}

impl fmt::Display for MasterEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.kind, f)
    }
}

/// What the master knows of one node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SlaveView {
    /// The node.
    pub node: NodeId,
    /// Its 0x1F81 value.
    pub assignment: Assignment,
    /// Its NMT state: heard (boot-up, heartbeat, guarding) or, if nothing was heard since, as
    /// last commanded by this master.
    pub state: Option<NmtState>,
    /// Error control lost it, or it does not answer.
    pub missing: bool,
    /// Where its boot process is.
    pub phase: BootPhase,
    /// The last error status, if any.
    pub last_error: Option<ErrorStatus>,
    /// Boot-ups seen.
    pub boot_ups: u32,
    /// Who starts it.
    pub start: StartPolicy,
}

impl SlaveView {
    /// The 0x1F82 read value: 0 unknown, 1 missing, 4 stopped, 5 operational, 127
    /// pre-operational.
    pub fn request_nmt_code(&self) -> u8 {
        use super::objects::request;
        if self.missing {
            return request::MISSING;
        }
        match self.state {
            None => request::UNKNOWN,
            Some(NmtState::Stopped) => request::STOP,
            Some(NmtState::Operational) => request::START,
            Some(NmtState::PreOperational | NmtState::Initialising) => request::PRE_OPERATIONAL,
        }
    }
}

/// Counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MasterStats {
    /// NMT commands sent.
    pub nmt_sent: u32,
    /// NMT commands dropped: the transmit queue was full.
    pub nmt_dropped: u32,
    /// Boot process runs started.
    pub boots_started: u32,
    /// Probes of silent slaves.
    pub probes: u32,
    /// Times a slave's SDO access had to wait for a free client session.
    pub jobs_queued: u32,
    /// Most slaves waiting for a session at once.
    pub max_waiting: u32,
    /// Events dropped because the application did not drain them.
    pub events_dropped: u32,
}

/// Why a master call was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterError {
    /// The master is standby (or 0x1F80 bit 0 is clear): it sends nothing.
    Standby,
    /// The node is not an assigned slave.
    NotAssigned(NodeId),
    /// The node is the master itself.
    OwnNode(NodeId),
    /// The NMT transmit queue is full: drain `poll_transmit` and retry.
    QueueFull,
    /// The master's dictionary lacks a master object (use
    /// [`super::objects::master_dictionary`]).
    MissingObject {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// A PDO step of a slave's configuration names a PDO number outside 1–512.
    NoSuchPdo {
        /// The slave.
        node: NodeId,
        /// The number.
        pdo: u16,
    },
    /// The configuration asks for more PDOs of the master's own node than CiA 301 numbers
    /// (512 in each direction).
    TooManyPdos {
        /// Receive ([`MasterConfig::rpdos`](super::MasterConfig::rpdos)) or transmit.
        dir: Dir,
        /// The count asked for.
        count: usize,
    },
    /// The slave is being booted or has a program download under way.
    Busy(NodeId),
    /// A program image is larger than the master's SDO transfer limit.
    ImageTooLarge {
        /// Bytes of the image.
        len: usize,
        /// The limit.
        limit: usize,
    },
    /// The master has a slot for `capacity` nodes
    /// ([`MasterConfig::max_slaves`](super::MasterConfig::max_slaves)), all taken: `node` cannot
    /// be a slave (or get a program download).
    TooManySlaves {
        /// The node refused.
        node: NodeId,
        /// The master's slots.
        capacity: usize,
    },
    /// The dictionary refused a configuration value.
    Refused {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: AbortCode,
    },
    /// [`Master::configure`](super::Master::configure) after the master booted: its
    /// configuration is written before boot, once.
    AlreadyBooted,
}

impl fmt::Display for MasterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MasterError::Standby => f.write_str(
                "the master is standby or not the NMT master (0x1F80 bit 0): activate it first",
            ),
            MasterError::NotAssigned(n) => write!(
                f,
                "{n} is not an assigned slave: set bit 0 of 0x1F81 sub {}",
                n.raw()
            ),
            MasterError::OwnNode(n) => write!(f, "{n} is the master itself"),
            MasterError::QueueFull => {
                f.write_str("the master's NMT queue is full: drain poll_transmit and retry")
            }
            MasterError::MissingObject { index, sub } => write!(
                f,
                "the master's dictionary has no {index:#06x}sub{sub}: build it with master::objects::master_dictionary"
            ),
            MasterError::NoSuchPdo { node, pdo } => write!(
                f,
                "the configuration of {node} names PDO {pdo}: CiA 301 numbers PDOs 1 to 512"
            ),
            MasterError::TooManyPdos { dir, count } => write!(
                f,
                "the master is configured for {count} {}s: CiA 301 numbers PDOs 1 to 512",
                match dir {
                    Dir::Receive => "RPDO",
                    Dir::Transmit => "TPDO",
                }
            ),
            MasterError::Busy(n) => write!(
                f,
                "{n} is being booted or updated: wait for the end of that first"
            ),
            MasterError::ImageTooLarge { len, limit } => write!(
                f,
                "the image has {len} bytes, above the master's SDO transfer limit of {limit}"
            ),
            MasterError::TooManySlaves { node, capacity } => write!(
                f,
                "{node} needs a slot, and all {capacity} of the master's are taken: raise MasterConfig::max_slaves"
            ),
            MasterError::AlreadyBooted => {
                f.write_str("the master has booted: its network configuration is written before boot")
            }
            MasterError::Refused { index, sub, code } => {
                write!(f, "the master's {index:#06x}sub{sub} refused the value: {code}")
            }
        }
    }
}

impl core::error::Error for MasterError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            MasterError::Refused { code, .. } => Some(code),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each kind is one line an operator reads: the node in hex, what happened, the CiA 302-2
    /// status in words where there is one.
    #[test]
    fn master_events_print_one_line_each() {
        let node = NodeId::must(0x10);
        let line = |kind: MasterEventKind| kind.to_string();
        assert_eq!(
            line(MasterEventKind::SlaveConfigured {
                node,
                start: StartPolicy::Application
            }),
            "node 0x10: configured, the application starts it"
        );
        assert_eq!(
            line(MasterEventKind::SlaveStarted {
                node,
                broadcast: true
            }),
            "node 0x10: started (start all nodes)"
        );
        assert_eq!(
            line(MasterEventKind::IdentityMismatch {
                node,
                mismatch: IdentityMismatch {
                    status: ErrorStatus::D,
                    index: 0x1018,
                    sub: 1,
                    expected: 0x1234,
                    actual: 0x4321,
                }
            }),
            "node 0x10: not started, error status D: vendor-ID 0x1018 sub 1 differs from 0x1F85 \
             (0x1018sub1 is 0x00004321, expected 0x00001234)"
        );
        assert_eq!(
            line(MasterEventKind::SlaveLost {
                node,
                status: ErrorStatus::E
            }),
            "node 0x10: lost, error status E: heartbeat lost"
        );
        assert_eq!(
            line(MasterEventKind::NmtRequest {
                target: NmtTarget::Node(node),
                cmd: NmtCommand::Stop,
                sent: false
            }),
            "request NMT stop for node 0x10, not sent"
        );
        let mut nodes = NodeSet::EMPTY;
        nodes.insert(node);
        let missing = line(MasterEventKind::MandatoryMissing { nodes });
        assert!(missing.contains("{16}"), "{missing}");
        assert!(!missing.contains('\n'));
    }
}
