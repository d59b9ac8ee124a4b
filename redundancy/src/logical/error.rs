//! The one error of the redundant network's front door: bad settings in the builder, refusals
//! of the network, failed transfers and a closed runtime, each naming the node, pair or port
//! concerned and what to do.

use super::NetworkError;
use crate::link::same_function::PairError;
use crate::supervisor::AddPairError;
use alloc::string::String;
use core::fmt;
use duocan::{Duration, NodeId};

/// The part a node-ID was given for in a [`RedundantNetworkBuilder`](super::RedundantNetworkBuilder).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Role {
    /// This master (`.node_id(…)`).
    ThisMaster,
    /// Another master-capable device (`.peer_master(…)`).
    PeerMaster,
    /// A member of a board pair (`.pair(…)`).
    PairMember,
    /// A node addressed by a call.
    Node,
    /// The front door's USDO client on a CANopen FD network (`.with_fd(…)`).
    UsdoClient,
}

impl fmt::Display for Role {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Role::ThisMaster => "this master",
            Role::PeerMaster => "peer master",
            Role::PairMember => "pair member",
            Role::Node => "node",
            Role::UsdoClient => "USDO client",
        })
    }
}

/// Why building, opening or using a redundant network failed. One flat enum for every call of
/// the builder and of the async handle; the message names what was wrong and what to do.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum RedundantError {
    /// A node-ID outside 1–127.
    BadNodeId {
        /// What it was given for.
        role: Role,
        /// The value given.
        id: u8,
    },
    /// One node-ID was given twice (for this master, a peer or a pair member).
    NodeTwice {
        /// The node.
        node: NodeId,
        /// Its first part.
        first: Role,
        /// Its second part.
        second: Role,
    },
    /// A duration setting is zero.
    ZeroDuration {
        /// The setting (the builder method's name).
        setting: &'static str,
    },
    /// A timeout is not longer than the period it watches, so the watched device would fail
    /// between two of its own heartbeats.
    TimeoutTooShort {
        /// The timeout setting.
        setting: &'static str,
        /// Its value.
        timeout: Duration,
        /// The period it must exceed.
        period: Duration,
    },
    /// A duration does not fit the object it is written to (heartbeat times are whole
    /// milliseconds up to 65 535).
    TooLong {
        /// The setting.
        setting: &'static str,
        /// Its value.
        value: Duration,
    },
    /// More peers or pairs than the tables hold.
    TooMany {
        /// "peer masters" or "pairs".
        what: &'static str,
        /// The capacity.
        max: usize,
    },
    /// `build` or `build_boxed` was asked for a network on another identifier profile than
    /// the predefined set, which is the one their type names.
    ProfileNotPredefined {
        /// The profile set ([`NetProfile::name`](super::NetProfile::name)).
        profile: &'static str,
    },
    /// The supervisor refused a pair.
    Pair(AddPairError),
    /// The dual-bus layer refused a pair.
    Link(PairError),
    /// The network refused a call (a standby master, a busy SDO client, an NMT or switch-over
    /// refusal).
    Network(NetworkError),
    /// A call of the front door failed (an SDO transfer, NMT on a standby master, a closed
    /// network…): duocan's error, which names the node and object and what to do.
    #[cfg(feature = "tokio")]
    Net(duocan::net::NetError),
    /// A port could not be opened.
    Port {
        /// 0 = bus 1.
        port: u8,
        /// The name given.
        name: String,
        /// Why.
        why: String,
    },
    /// Node guarding configured on a CANopen FD network, which has no remote frames: the
    /// node and how it is configured (feature `fd`).
    #[cfg(feature = "fd")]
    GuardingOnFd(crate::supervisor::fd_guarding::GuardingOnFd),
    /// The network has been closed (or its runtime stopped).
    Closed,
}

impl RedundantError {
    /// The node concerned, if the error is about one.
    #[must_use]
    pub fn node(&self) -> Option<NodeId> {
        match self {
            RedundantError::NodeTwice { node, .. } => Some(*node),
            #[cfg(feature = "fd")]
            RedundantError::GuardingOnFd(e) => Some(e.node),
            RedundantError::Network(NetworkError::Sdo(e)) => Some(e.node),
            #[cfg(feature = "tokio")]
            RedundantError::Net(e) => e.node(),
            _ => None,
        }
    }
}

impl From<NetworkError> for RedundantError {
    fn from(e: NetworkError) -> Self {
        match e {
            NetworkError::Closed => RedundantError::Closed,
            e => RedundantError::Network(e),
        }
    }
}

/// A closed network is [`RedundantError::Closed`] whichever door says so; every other error
/// of the front door is [`RedundantError::Net`].
#[cfg(feature = "tokio")]
impl From<duocan::net::NetError> for RedundantError {
    fn from(e: duocan::net::NetError) -> Self {
        match e {
            duocan::net::NetError::Closed => RedundantError::Closed,
            e => RedundantError::Net(e),
        }
    }
}

#[cfg(feature = "tokio")]
impl From<duocan::runtime::RuntimeClosed> for RedundantError {
    fn from(_: duocan::runtime::RuntimeClosed) -> Self {
        RedundantError::Closed
    }
}

impl core::error::Error for RedundantError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            RedundantError::Pair(e) => Some(e),
            RedundantError::Link(e) => Some(e),
            RedundantError::Network(e) => Some(e),
            #[cfg(feature = "tokio")]
            RedundantError::Net(e) => Some(e),
            #[cfg(feature = "fd")]
            RedundantError::GuardingOnFd(e) => Some(e),
            _ => None,
        }
    }
}

impl fmt::Display for RedundantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use RedundantError as E;
        match self {
            E::BadNodeId { role, id } => {
                write!(f, "{role} {id}: not a CANopen node-ID: use 1 to 127")
            }
            E::NodeTwice { node, first, second } => write!(
                f,
                "node {:#04x} is given as {first} and as {second}: every device needs its own node-ID",
                node.raw()
            ),
            E::ZeroDuration { setting } => write!(
                f,
                "{setting}: zero is no period: give a positive duration (or leave the setting out for its default)"
            ),
            E::TimeoutTooShort { setting, timeout, period } => write!(
                f,
                "{setting} {} ms is not longer than the heartbeat it watches ({} ms): make it at least two heartbeats long",
                timeout.as_millis(),
                period.as_millis()
            ),
            E::TooLong { setting, value } => write!(
                f,
                "{setting} {} ms: heartbeat times are whole milliseconds up to 65535",
                value.as_millis()
            ),
            E::TooMany { what, max } => write!(f, "at most {max} {what}: declare fewer"),
            E::ProfileNotPredefined { profile } => write!(
                f,
                "profile {profile}: build() and build_boxed() give a network on the predefined connection set; build this one with build_profiled() (or open it)"
            ),
            E::Pair(e) => write!(f, "{e}"),
            E::Link(e) => write!(f, "{e}"),
            E::Network(e) => write!(f, "{e}"),
            #[cfg(feature = "tokio")]
            E::Net(e) => write!(f, "{e}"),
            E::Port { port, name, why } => write!(
                f,
                "bus {} ({name:?}) could not be opened: {why}",
                port + 1
            ),
            #[cfg(feature = "fd")]
            E::GuardingOnFd(e) => write!(f, "{e}"),
            E::Closed => f.write_str("the redundant network has been closed: open it again"),
        }
    }
}
