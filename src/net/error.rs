//! The one error of the front door: every call ends in `?`.

use crate::cia301::nmt::NmtState;
use crate::cia301::sdo::{SdoError, SdoErrorKind};
use crate::frame::cob_id::NodeId;
use crate::od::abort::AbortCode;
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
    /// A node-ID outside 1–127 was given to [`Network::node`](super::Network::node).
    NoSuchNode(u8),
    /// The network could not send (its transmit queue was full).
    QueueFull,
    /// The port could not be opened.
    Port(String),
    /// The network has been closed (or its runtime stopped).
    Closed,
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
            NetError::ListenOnly { node } => *node,
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
            NetError::NoSuchNode(raw) => write!(f, "node-ID {raw} is not a CANopen node-ID: use 1 to 127"),
            NetError::QueueFull => f.write_str("the network's transmit queue is full: send less at once"),
            NetError::Port(why) => write!(f, "the port could not be opened: {why}"),
            NetError::Closed => f.write_str("the network has been closed: open it again"),
        }
    }
}

impl std::error::Error for NetError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            NetError::Sdo(e) => Some(e),
            _ => None,
        }
    }
}

impl From<RuntimeClosed> for NetError {
    fn from(_: RuntimeClosed) -> Self {
        NetError::Closed
    }
}
