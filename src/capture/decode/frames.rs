//! What a frame is: [`DecodedFrame`], its [`Kind`] and the one-line text.

use super::kind::{FlyingMasterFrame, Kind};
use super::pdo::PdoInfo;
use super::sdo::SdoInfo;
use crate::cia301::emcy::EmcyMessage;
use crate::cia301::nmt::{NmtCommand, NmtState, NmtTarget};
use crate::frame::cob_id::NodeId;
use crate::frame::Frame;
use crate::profile::railway::{DeviceAddress, Payload, RailFunction};
use core::fmt;

/// One frame, decoded.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum DecodedFrame {
    /// NMT module control: `NMT start node 5`, `NMT reset communication all`.
    Nmt {
        /// The command.
        command: NmtCommand,
        /// The node it addresses, or all.
        target: NmtTarget,
    },
    /// SYNC: `SYNC` or `SYNC counter 7`.
    Sync {
        /// The counter byte, when the producer sends one (0x1019 > 1).
        counter: Option<u8>,
    },
    /// TIME (TIME_OF_DAY): `TIME 2026-11-24 08:03:12.345`.
    Time {
        /// Days since 1984-01-01.
        days: u16,
        /// Milliseconds after midnight (28 bits).
        millis: u32,
    },
    /// EMCY: `node 5 EMCY 0x8130 life guard or heartbeat error, register 0x11, data 00 …`.
    Emcy {
        /// The producer.
        node: NodeId,
        /// Error code, error register, manufacturer bytes ([`EmcyMessage::text`] names the
        /// code).
        emcy: EmcyMessage,
    },
    /// Heartbeat, boot-up or guarding answer: `node 5 heartbeat operational`, `node 5 boot-up`,
    /// `node 5 guarding answer stopped (toggle 1)`.
    Heartbeat {
        /// The sender.
        node: NodeId,
        /// The state it reports (initialising: a boot-up).
        state: NmtState,
        /// The toggle bit (set only in guarding answers).
        toggle: bool,
    },
    /// A node-guarding request (remote frame on 0x700+n): `node 5 guarding request`.
    GuardingRequest {
        /// The node asked.
        node: NodeId,
    },
    /// An SDO frame of a node's default channel.
    Sdo {
        /// The server's node.
        node: NodeId,
        /// What the frame does in its transfer.
        sdo: SdoInfo,
    },
    /// A PDO: raw bytes, or the values by name with a layout.
    Pdo(PdoInfo),
    /// LSS (CiA 305): `LSS request cs=0x04 (switch state global) 01 00 00 00 00 00 00`.
    Lss {
        /// From the master (0x7E5); else from a slave (0x7E4).
        request: bool,
        /// The command specifier (byte 0).
        cs: u8,
        /// The bytes after it.
        data: Vec<u8>,
    },
    /// A CiA 302-2 flying-master frame: `flying master active-master response node 5
    /// (priority 1)`.
    FlyingMaster {
        /// Which of the six.
        frame: FlyingMasterFrame,
        /// The (priority, node) the frame carries (0x71, 0x74, 0x76).
        rank: Option<(u8, NodeId)>,
    },
    /// A frame of the railway profile's 29-bit scheme: `railway R1 C2 L3 B4 P0 node 10
    /// heartbeat operational`.
    Railway {
        /// The function code.
        function: RailFunction,
        /// The address (row, cabinet, layer, board, port).
        address: DeviceAddress,
        /// The node at the board, when the decoder's railway table has one.
        node: Option<NodeId>,
        /// What the frame carries.
        payload: RailPayload,
    },
    /// A frame of a known kind that is not what the kind defines: wrong length, a remote frame
    /// where data belongs, an undefined value: `node 5 heartbeat: 2 bytes, a heartbeat has 1`.
    Malformed {
        /// What the identifier says it is.
        kind: Kind,
        /// The node the identifier names.
        node: Option<NodeId>,
        /// What is wrong, with the bytes where they help.
        problem: String,
    },
    /// An identifier no rule knows: `unknown 0x123 [3] 01 02 03`.
    Unknown(Frame),
}

/// What a railway frame carries: CiA 301 payloads for the node-level services, the railway
/// payload (index, sub-index, data, checked CRC) for process frames.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum RailPayload {
    /// NMT module control.
    Nmt {
        /// The command.
        command: NmtCommand,
        /// The node it addresses, or all.
        target: NmtTarget,
    },
    /// SYNC (no data).
    Sync,
    /// A fault report: the node's EMCY.
    Emcy(EmcyMessage),
    /// Heartbeat, boot-up or guarding answer.
    State {
        /// The state.
        state: NmtState,
        /// The toggle bit.
        toggle: bool,
    },
    /// A guarding request (remote frame).
    GuardingRequest,
    /// An SDO frame (with the node's transfer context when the table names the node).
    Sdo(SdoInfo),
    /// A process frame (command, command answer, state change, state query, state answer)
    /// whose CRC matched.
    Process(Payload),
    /// Error control of a node missing from its table (function 0x1FF): the raw bytes.
    Unmapped(Vec<u8>),
}

impl DecodedFrame {
    /// The kind of frame (railway frames are [`Kind::Railway`], whatever they carry).
    #[must_use]
    pub fn kind(&self) -> Kind {
        match self {
            DecodedFrame::Nmt { .. } => Kind::Nmt,
            DecodedFrame::Sync { .. } => Kind::Sync,
            DecodedFrame::Time { .. } => Kind::Time,
            DecodedFrame::Emcy { .. } => Kind::Emcy,
            DecodedFrame::Heartbeat { .. } | DecodedFrame::GuardingRequest { .. } => {
                Kind::Heartbeat
            }
            DecodedFrame::Sdo { .. } => Kind::Sdo,
            DecodedFrame::Pdo(_) => Kind::Pdo,
            DecodedFrame::Lss { .. } => Kind::Lss,
            DecodedFrame::FlyingMaster { .. } => Kind::FlyingMaster,
            DecodedFrame::Railway { .. } => Kind::Railway,
            DecodedFrame::Malformed { kind, .. } => *kind,
            DecodedFrame::Unknown(_) => Kind::Unknown,
        }
    }

    /// The CiA 301 service a railway frame carries ([`Kind::Railway`] for process frames),
    /// else [`DecodedFrame::kind`]: for a filter that wants a railway heartbeat as a heartbeat.
    #[must_use]
    pub fn service(&self) -> Kind {
        match self {
            DecodedFrame::Railway { payload, .. } => match payload {
                RailPayload::Nmt { .. } => Kind::Nmt,
                RailPayload::Sync => Kind::Sync,
                RailPayload::Emcy(_) => Kind::Emcy,
                RailPayload::State { .. } | RailPayload::GuardingRequest => Kind::Heartbeat,
                RailPayload::Sdo(_) => Kind::Sdo,
                RailPayload::Process(_) | RailPayload::Unmapped(_) => Kind::Railway,
            },
            other => other.kind(),
        }
    }

    /// The node the frame is of (its sender or server) or to (an NMT command's target, a
    /// flying master's rank); `None` for broadcasts and frames without one.
    #[must_use]
    pub fn node(&self) -> Option<NodeId> {
        match self {
            DecodedFrame::Nmt {
                target: NmtTarget::Node(n),
                ..
            } => Some(*n),
            DecodedFrame::Emcy { node, .. }
            | DecodedFrame::Heartbeat { node, .. }
            | DecodedFrame::GuardingRequest { node }
            | DecodedFrame::Sdo { node, .. } => Some(*node),
            DecodedFrame::Pdo(p) => p.node,
            DecodedFrame::FlyingMaster { rank, .. } => rank.map(|(_, n)| n),
            DecodedFrame::Railway {
                node,
                payload:
                    RailPayload::Nmt {
                        target: NmtTarget::Node(n),
                        ..
                    },
                ..
            } => node.or(Some(*n)),
            DecodedFrame::Railway { node, .. } | DecodedFrame::Malformed { node, .. } => *node,
            _ => None,
        }
    }

    /// True when the frame concerns `node`: it is of or to it ([`DecodedFrame::node`]), or an
    /// NMT command to all nodes.
    #[must_use]
    pub fn concerns(&self, node: NodeId) -> bool {
        let to_all = matches!(
            self,
            DecodedFrame::Nmt {
                target: NmtTarget::All,
                ..
            } | DecodedFrame::Railway {
                payload: RailPayload::Nmt {
                    target: NmtTarget::All,
                    ..
                },
                ..
            }
        );
        to_all || self.node() == Some(node)
    }
}

/// `node 5`, as the lines name nodes (decimal, as engineers and `candump` users count them).
pub(super) struct N(pub NodeId);

impl fmt::Display for N {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "node {}", self.0.raw())
    }
}

/// `01 02 03`.
pub(super) struct Hex<'a>(pub &'a [u8]);

impl fmt::Display for Hex<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, b) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

pub(super) fn nmt_text(
    f: &mut fmt::Formatter<'_>,
    command: NmtCommand,
    target: NmtTarget,
) -> fmt::Result {
    let what = match command {
        NmtCommand::Start => "start",
        NmtCommand::Stop => "stop",
        NmtCommand::EnterPreOperational => "pre-operational",
        NmtCommand::ResetNode => "reset",
        NmtCommand::ResetCommunication => "reset communication",
    };
    match target {
        NmtTarget::All => write!(f, "NMT {what} all"),
        NmtTarget::Node(n) => write!(f, "NMT {what} {}", N(n)),
    }
}

pub(super) fn emcy_text(f: &mut fmt::Formatter<'_>, e: &EmcyMessage) -> fmt::Result {
    if e.is_reset() {
        return write!(f, "EMCY reset, register {:#04x}", e.register);
    }
    write!(
        f,
        "EMCY {:#06x} {}, register {:#04x}, data {}",
        e.code,
        e.text(),
        e.register,
        Hex(&e.data)
    )
}

pub(super) fn state_text(f: &mut fmt::Formatter<'_>, state: NmtState, toggle: bool) -> fmt::Result {
    match (state, toggle) {
        (NmtState::Initialising, false) => f.write_str("boot-up"),
        (s, false) => write!(f, "heartbeat {s}"),
        (s, true) => write!(f, "guarding answer {s} (toggle 1)"),
    }
}

impl fmt::Display for DecodedFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodedFrame::Nmt { command, target } => nmt_text(f, *command, *target),
            DecodedFrame::Sync { counter: None } => f.write_str("SYNC"),
            DecodedFrame::Sync { counter: Some(c) } => write!(f, "SYNC counter {c}"),
            DecodedFrame::Time { days, millis } => super::services::time_text(f, *days, *millis),
            DecodedFrame::Emcy { node, emcy } => {
                write!(f, "{} ", N(*node))?;
                emcy_text(f, emcy)
            }
            DecodedFrame::Heartbeat {
                node,
                state,
                toggle,
            } => {
                write!(f, "{} ", N(*node))?;
                state_text(f, *state, *toggle)
            }
            DecodedFrame::GuardingRequest { node } => write!(f, "{} guarding request", N(*node)),
            DecodedFrame::Sdo { node, sdo } => write!(f, "{} {sdo}", N(*node)),
            DecodedFrame::Pdo(p) => p.fmt(f),
            DecodedFrame::Lss { request, cs, data } => {
                let side = if *request { "request" } else { "response" };
                write!(f, "LSS {side} cs={cs:#04x}")?;
                if let Some(name) = super::services::lss_name(*request, *cs) {
                    write!(f, " ({name})")?;
                }
                if !data.is_empty() {
                    write!(f, " {}", Hex(data))?;
                }
                Ok(())
            }
            DecodedFrame::FlyingMaster { frame, rank } => {
                write!(f, "flying master {frame}")?;
                if let Some((priority, node)) = rank {
                    write!(f, " {} (priority {priority})", N(*node))?;
                }
                Ok(())
            }
            DecodedFrame::Railway {
                function,
                address,
                node,
                payload,
            } => super::railway::text(f, *function, *address, *node, payload),
            DecodedFrame::Malformed {
                kind,
                node,
                problem,
            } => {
                if let Some(n) = node {
                    write!(f, "{} ", N(*n))?;
                }
                write!(f, "{}: {problem}", kind.label())
            }
            DecodedFrame::Unknown(frame) => write!(f, "unknown {frame}"),
        }
    }
}
