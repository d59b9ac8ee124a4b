//! The one error of the front door: every call ends in `?`.

use crate::cia301::nmt::NmtState;
use crate::cia301::sdo::{SdoError, SdoErrorKind};
use crate::cia302::master::{MasterError, ProgramDownloadError};
use crate::cia302::pdo_config::PdoConfigError;
use crate::cia305::{LssError, LssService};
use crate::eds::{EdsError, LookupError, LookupErrorKind};
use crate::frame::cob_id::NodeId;
use crate::od::abort::AbortCode;
use crate::od::DataType;
use crate::runtime::RuntimeClosed;
use std::fmt;
use std::time::Duration;

/// What a [`NetError::Timeout`] was waiting for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Awaited {
    /// A boot-up message.
    BootUp,
    /// An NMT state.
    State(NmtState),
    /// A PDO (the node's TPDO with this number).
    Pdo(u16),
    /// An emergency message.
    Emcy,
}

/// Why a call on a [`Network`](super::Network) or [`RemoteNode`](super::RemoteNode) failed.
/// One flat enum: each variant names the node and object concerned, and the message says what
/// to do about it.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum NetError {
    /// An SDO transfer failed: the node aborted it, did not answer, or the client refused to
    /// start it. The [`SdoError`] names node, object, direction and cause.
    Sdo(SdoError),
    /// The value read has a different size than the type asked for.
    WrongSize {
        /// The node.
        node: NodeId,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Bytes the type needs.
        expected: usize,
        /// Bytes the node sent.
        got: usize,
    },
    /// A string read is not valid UTF-8.
    NotText {
        /// The node.
        node: NodeId,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// A wait ran out of time.
    Timeout {
        /// The node.
        node: NodeId,
        /// What it waited for.
        awaited: Awaited,
        /// How long it waited.
        after: Duration,
    },
    /// The network is listen-only: it sends nothing, so no SDO and no NMT.
    ListenOnly {
        /// The node the call was for.
        node: Option<NodeId>,
    },
    /// The network's core is a standby master: SDO, NMT and the frames of the network's own
    /// are the active master's (two SDO clients on one server channel would corrupt each
    /// other's transfers).
    Standby {
        /// The node the call was for.
        node: Option<NodeId>,
    },
    /// The core's CiA 302 master refused the call (an NMT command to its own node-ID, a
    /// full queue…).
    Master(MasterError),
    /// A node-ID outside 1–127 was given to [`Network::node`](super::Network::node).
    NoSuchNode(u8),
    /// The network could not send (its transmit queue was full).
    QueueFull,
    /// The port could not be opened.
    Port(String),
    /// The network has been closed (or its runtime stopped).
    Closed,
    /// A by-name call on a node without a device description.
    NoDescription {
        /// The node.
        node: NodeId,
    },
    /// A name that names no entry of the node's description, or several.
    Name {
        /// The node.
        node: NodeId,
        /// The lookup's error: the name, and the candidates of an ambiguous one.
        error: LookupError,
    },
    /// The Rust type asked for does not match the entry's data type.
    WrongType {
        /// The node.
        node: NodeId,
        /// The name asked for.
        name: String,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The entry's data type (from the description).
        data_type: DataType,
        /// The data type of the Rust type asked for.
        asked: DataType,
    },
    /// A value does not fit the entry (or PDO mapping entry) it is for.
    BadValue {
        /// The node.
        node: NodeId,
        /// The entry: its name, or its address.
        object: String,
        /// Why it does not fit.
        why: String,
    },
    /// A device description could not be read.
    Eds(EdsError),
    /// A PDO number outside 1–512.
    NoSuchPdo {
        /// The node.
        node: NodeId,
        /// The number given.
        pdo: u16,
    },
    /// A PDO call that cannot be made as things are (the mapping is not known, the PDO is
    /// disabled, the mapping is too long…).
    Pdo {
        /// The node.
        node: NodeId,
        /// `"TPDO 1"`, `"RPDO 2"`.
        pdo: String,
        /// What is wrong and what to do.
        why: String,
    },
    /// Configuring a PDO over SDO failed: which entry, and what the node did.
    PdoConfig(PdoConfigError),
    /// A program download ([`RemoteNode::download_program`](super::RemoteNode::download_program))
    /// failed in a step: which one, the abort code, and whether the node went back to the
    /// program it had.
    Program(ProgramDownloadError),
    /// An argument outside what the call takes.
    Argument(String),
    /// An LSS request ([`Network::lss`](super::Network::lss)) failed: no slave answered, or
    /// one refused or answered wrongly.
    Lss(LssError),
    /// The local side of a streamed transfer failed: the reader a write took its data from,
    /// or the writer a read put its data into. The transfer was aborted (the node was told).
    Io {
        /// The node.
        node: NodeId,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What kind of failure.
        kind: std::io::ErrorKind,
        /// The failure, as the reader or writer put it.
        message: String,
    },
}

impl NetError {
    /// The node concerned, if the error is about one.
    #[must_use]
    pub fn node(&self) -> Option<NodeId> {
        match self {
            NetError::Sdo(e) => Some(e.node),
            NetError::WrongSize { node, .. }
            | NetError::NotText { node, .. }
            | NetError::Timeout { node, .. } => Some(*node),
            NetError::ListenOnly { node } | NetError::Standby { node } => *node,
            NetError::Master(e) => master_node(e),
            NetError::NoDescription { node }
            | NetError::Name { node, .. }
            | NetError::WrongType { node, .. }
            | NetError::BadValue { node, .. }
            | NetError::NoSuchPdo { node, .. }
            | NetError::Pdo { node, .. }
            | NetError::Io { node, .. } => Some(*node),
            NetError::PdoConfig(e) => Some(e.node),
            NetError::Program(e) => Some(e.node),
            NetError::Eds(_) | NetError::Argument(_) | NetError::Lss(_) => None,
            NetError::NoSuchNode(_)
            | NetError::QueueFull
            | NetError::Port(_)
            | NetError::Closed => None,
        }
    }
    /// The SDO abort code, if a transfer was aborted (by the node or by this side, a timeout
    /// being [`AbortCode::TIMEOUT`]).
    #[must_use]
    pub fn abort_code(&self) -> Option<AbortCode> {
        match self {
            NetError::Sdo(e) => e.code(),
            NetError::Program(e) => e.code(),
            _ => None,
        }
    }
    /// True if a node did not answer an SDO request in time.
    #[must_use]
    pub fn is_no_answer(&self) -> bool {
        matches!(self, NetError::Sdo(e) if e.kind == SdoErrorKind::Client(AbortCode::TIMEOUT))
    }
}

impl fmt::Display for NetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NetError::Sdo(e) => fmt::Display::fmt(e, f),
            NetError::WrongSize { node, index, sub, expected, got } => write!(
                f,
                "node {}, object {index:#06x} sub {sub}: the node sent {got} byte(s) but the type read needs {expected}: read it as a type of {got} byte(s) (see the node's EDS)",
                node.raw()
            ),
            NetError::NotText { node, index, sub } => write!(
                f,
                "node {}, object {index:#06x} sub {sub}: the value is not UTF-8 text: read it as bytes",
                node.raw()
            ),
            NetError::Timeout { node, awaited, after } => {
                write!(f, "node {}: no ", node.raw())?;
                match awaited {
                    Awaited::BootUp => f.write_str("boot-up")?,
                    Awaited::State(s) => write!(f, "heartbeat with state {s:?}")?,
                    Awaited::Pdo(n) => write!(f, "TPDO {n}")?,
                    Awaited::Emcy => f.write_str("emergency message")?,
                }
                match awaited {
                    Awaited::Pdo(_) => return write!(
                        f,
                        " within {} ms: check that the node is operational and the PDO enabled, that the network knows its mapping (read, save or learn it), and its transmission type (SYNC needs a SYNC producer)",
                        after.as_millis()
                    ),
                    Awaited::Emcy => return write!(
                        f,
                        " within {} ms: a node sends one only when an error appears or goes",
                        after.as_millis()
                    ),
                    _ => {}
                }
                write!(
                    f,
                    " within {} ms: check that the node is powered and on this bus, and that it produces heartbeats (0x1017)",
                    after.as_millis()
                )
            }
            NetError::ListenOnly { node } => {
                if let Some(n) = node {
                    write!(f, "node {}: ", n.raw())?;
                }
                f.write_str("the network is listen-only and sends nothing: open it with Network::open to talk to nodes")
            }
            NetError::Standby { node } => {
                if let Some(n) = node {
                    write!(f, "node {}: ", n.raw())?;
                }
                f.write_str("this master is standby: SDO, NMT and RPDOs go through the active master (or make this one active)")
            }
            NetError::Master(e) => write!(f, "the master refused: {e}"),
            NetError::NoSuchNode(raw) => write!(f, "node-ID {raw} is not a CANopen node-ID: use 1 to 127"),
            NetError::QueueFull => f.write_str("the network's transmit queue is full: send less at once"),
            NetError::Port(why) => write!(f, "the port could not be opened: {why}"),
            NetError::Closed => f.write_str("the network has been closed: open it again"),
            NetError::NoDescription { node } => write!(
                f,
                "node {0} has no device description, so names mean nothing to it: attach one with Network::add_node({0}, description) or RemoteNode::with_description, or use (index, sub)",
                node.raw()
            ),
            NetError::Name { node, error } => {
                write!(f, "node {}: {error}", node.raw())?;
                match error.kind {
                    LookupErrorKind::Ambiguous { .. } => f.write_str(
                        ": name one of them by its address (\"1017sub0\") or as \"Object.Entry\"",
                    ),
                    LookupErrorKind::NotFound => f.write_str(
                        " in its device description: check the spelling (case does not matter) or use the address (\"0x1017\", \"1018sub1\")",
                    ),
                    _ => Ok(()),
                }
            }
            NetError::WrongType { node, name, index, sub, data_type, asked } => write!(
                f,
                "node {}, {name:?} ({index:#06x} sub {sub}) is {} but was asked for as {}: use {} (or read_value)",
                node.raw(),
                crate::eds::type_name(*data_type),
                crate::eds::type_name(*asked),
                super::value::rust_type(*data_type),
            ),
            NetError::BadValue { node, object, why } => {
                write!(f, "node {}, {object}: {why}: give a value of the entry's type", node.raw())
            }
            NetError::Eds(e) => write!(f, "the device description could not be read: {e}"),
            NetError::NoSuchPdo { node, pdo } => write!(
                f,
                "node {}: there is no PDO {pdo}: PDOs are numbered 1 to 512",
                node.raw()
            ),
            NetError::Pdo { node, pdo, why } => write!(f, "node {}, {pdo}: {why}", node.raw()),
            NetError::PdoConfig(e) => fmt::Display::fmt(e, f),
            NetError::Program(e) => fmt::Display::fmt(e, f),
            NetError::Argument(why) => f.write_str(why),
            NetError::Lss(LssError::Timeout(s @ LssService::SwitchSelective)) => write!(
                f,
                "LSS, {s}: no slave with this identity answered in time: check the identity (all four parts) and that the slave is on this bus"
            ),
            NetError::Lss(LssError::Timeout(s)) => write!(
                f,
                "LSS, {s}: no slave answered in time: a slave serves it in configuration mode only (switch state global or selective first); check that it is on this bus, or wait longer"
            ),
            NetError::Lss(e) => write!(f, "LSS, {e}"),
            NetError::Io { node, index, sub, message, .. } => write!(
                f,
                "node {}, object {index:#06x} sub {sub}: the local reader or writer failed ({message}), so the transfer was aborted: fix the file or stream and try again",
                node.raw()
            ),
        }
    }
}

impl std::error::Error for NetError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            NetError::Sdo(e) => Some(e),
            NetError::Name { error, .. } => Some(error),
            NetError::Eds(e) => Some(e),
            NetError::PdoConfig(e) => Some(e),
            NetError::Program(e) => Some(e),
            NetError::Lss(e) => Some(e),
            NetError::Master(e) => Some(e),
            _ => None,
        }
    }
}

/// The node a master's refusal names, if one.
fn master_node(e: &MasterError) -> Option<NodeId> {
    match *e {
        MasterError::NotAssigned(n)
        | MasterError::OwnNode(n)
        | MasterError::Busy(n)
        | MasterError::NoSuchPdo { node: n, .. }
        | MasterError::TooManySlaves { node: n, .. } => Some(n),
        _ => None,
    }
}

impl From<MasterError> for NetError {
    /// [`MasterError::Standby`] is [`NetError::Standby`]; every other refusal is
    /// [`NetError::Master`].
    fn from(e: MasterError) -> Self {
        match e {
            MasterError::Standby => NetError::Standby { node: None },
            e => NetError::Master(e),
        }
    }
}

impl From<EdsError> for NetError {
    fn from(e: EdsError) -> Self {
        NetError::Eds(e)
    }
}

impl From<RuntimeClosed> for NetError {
    fn from(_: RuntimeClosed) -> Self {
        NetError::Closed
    }
}
