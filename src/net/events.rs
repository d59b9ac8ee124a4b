//! What the network reports, flat: one enum, one level, and a stream that survives lag.

use super::door::DoorEvent;
use super::pdo::PdoValues;
use crate::cia301::emcy::EmcyMessage;
use crate::cia301::nmt::NmtState;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::machine::PortStatus;
use crate::runtime::RuntimeEvent;
use tokio::sync::{broadcast, watch};

/// One thing that happened on the network. Every variant is one level deep; the accessors
/// ([`NetEvent::node`], [`NetEvent::at`], [`NetEvent::state`]) answer the common questions
/// without a `match`.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum NetEvent {
    /// A node sent its boot-up message.
    BootUp {
        /// The node.
        node: NodeId,
        /// When it arrived.
        at: Instant,
    },
    /// A node's NMT state (from its heartbeat) differs from the last one heard.
    State {
        /// The node.
        node: NodeId,
        /// The state heard before, `None` the first time.
        from: Option<NmtState>,
        /// The state now.
        to: NmtState,
        /// When it was heard.
        at: Instant,
    },
    /// A watched node's heartbeat stopped ([`RemoteNode::watch_heartbeat`](super::RemoteNode::watch_heartbeat)).
    HeartbeatLost {
        /// The node.
        node: NodeId,
        /// Its last heartbeat.
        last: Instant,
        /// When the loss was declared (`last` + the watch timeout).
        at: Instant,
    },
    /// A lost heartbeat came back.
    HeartbeatResumed {
        /// The node.
        node: NodeId,
        /// When.
        at: Instant,
    },
    /// An emergency message from a node.
    Emcy {
        /// The node.
        node: NodeId,
        /// What it sent.
        msg: EmcyMessage,
        /// When.
        at: Instant,
    },
    /// A node's TPDO, decoded by the mapping the network knows ([`RemotePdo::read`],
    /// [`RemotePdo::save`], [`RemotePdo::learn`]): its values in mapping order, named and
    /// typed by the node's device description if one is attached.
    ///
    /// [`RemotePdo::read`]: super::RemotePdo::read
    /// [`RemotePdo::save`]: super::RemotePdo::save
    /// [`RemotePdo::learn`]: super::RemotePdo::learn
    Pdo {
        /// The node.
        node: NodeId,
        /// Its TPDO number.
        pdo: u16,
        /// The values.
        values: PdoValues,
        /// When it arrived.
        at: Instant,
    },
    /// The port's status changed (down, error passive, back up…).
    Port {
        /// The status.
        status: PortStatus,
        /// When.
        at: Instant,
    },
    /// This reader fell behind and `n` events were dropped for it (the stream goes on with the
    /// oldest event still kept). A slow reader loses events, never the program.
    Lagged(u64),
}

impl NetEvent {
    /// The node the event is about, if any.
    #[must_use]
    pub fn node(&self) -> Option<NodeId> {
        match self {
            NetEvent::BootUp { node, .. }
            | NetEvent::State { node, .. }
            | NetEvent::HeartbeatLost { node, .. }
            | NetEvent::HeartbeatResumed { node, .. }
            | NetEvent::Emcy { node, .. }
            | NetEvent::Pdo { node, .. } => Some(*node),
            NetEvent::Port { .. } | NetEvent::Lagged(_) => None,
        }
    }
    /// When it happened (the network's clock, see [`Network::now`](super::Network::now)).
    #[must_use]
    pub fn at(&self) -> Option<Instant> {
        match self {
            NetEvent::BootUp { at, .. }
            | NetEvent::State { at, .. }
            | NetEvent::HeartbeatLost { at, .. }
            | NetEvent::HeartbeatResumed { at, .. }
            | NetEvent::Emcy { at, .. }
            | NetEvent::Pdo { at, .. }
            | NetEvent::Port { at, .. } => Some(*at),
            NetEvent::Lagged(_) => None,
        }
    }
    /// The node's new NMT state, for a state change or a boot-up (which is `Initialising`).
    #[must_use]
    pub fn state(&self) -> Option<NmtState> {
        match *self {
            NetEvent::State { to, .. } => Some(to),
            NetEvent::BootUp { .. } => Some(NmtState::Initialising),
            _ => None,
        }
    }
    /// The node and message of an emergency: `if let Some((node, m)) = e.emcy()`, then
    /// `m.code`, `m.register`, `m.data` (the five vendor bytes) and `m.text()`.
    #[must_use]
    pub fn emcy(&self) -> Option<(NodeId, EmcyMessage)> {
        match *self {
            NetEvent::Emcy { node, msg, .. } => Some((node, msg)),
            _ => None,
        }
    }
    /// The node, TPDO number and values of a received PDO.
    #[must_use]
    pub fn pdo(&self) -> Option<(NodeId, u16, &PdoValues)> {
        match self {
            NetEvent::Pdo {
                node, pdo, values, ..
            } => Some((*node, *pdo, values)),
            _ => None,
        }
    }
    /// True for a lost heartbeat.
    #[must_use]
    pub fn is_loss(&self) -> bool {
        matches!(self, NetEvent::HeartbeatLost { .. })
    }
}

/// The network's events, from the moment [`Network::events`](super::Network::events) was
/// called. `next().await` yields each event; a reader that falls more than
/// [`EVENT_QUEUE`](crate::runtime::EVENT_QUEUE) events behind gets one
/// [`NetEvent::Lagged`] with the count it missed and carries on (the count is of the runtime's
/// events, which include SDO transfer completions the stream does not show). The stream ends
/// (`None`) only when the network has been closed with [`Network::close`](super::Network::close).
pub struct Events {
    pub(super) rx: broadcast::Receiver<RuntimeEvent<DoorEvent>>,
    /// Turns true when the network is closed (the broadcast itself outlives the runtime).
    pub(super) closed: watch::Receiver<bool>,
}

impl Events {
    /// The next event, or `None` once the network is closed.
    pub async fn next(&mut self) -> Option<NetEvent> {
        loop {
            // Events already queued come first; then the end.
            let r = tokio::select! {
                biased;
                r = self.rx.recv() => r,
                _ = self.closed.wait_for(|c| *c) => return None,
            };
            match r {
                Ok(RuntimeEvent::Device(DoorEvent::Net(e))) => return Some(e),
                Ok(RuntimeEvent::Port { status, at, .. }) => {
                    return Some(NetEvent::Port { status, at })
                }
                // Transfer outcomes go to the call that started them.
                Ok(RuntimeEvent::Device(DoorEvent::Sdo(..))) => {}
                Err(broadcast::error::RecvError::Lagged(n)) => return Some(NetEvent::Lagged(n)),
                Err(broadcast::error::RecvError::Closed) => return None,
            }
        }
    }
}
