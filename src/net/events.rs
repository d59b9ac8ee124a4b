//! What the network reports, flat: one enum, one level, and a stream that survives lag.

use super::core::CoreEvent;
use super::ext::{ExtEvent, Extension};
use super::heard_on::HeardOn;
use super::pdo::PdoValues;
use crate::cia301::emcy::EmcyMessage;
use crate::cia301::nmt::NmtState;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::machine::{PortReason, PortState, PortStatus};
use crate::runtime::RuntimeEvent;
use core::fmt;
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
        /// When the loss was declared: `last` + the watch timeout on a simulated clock; on
        /// wall-clock time, when the runtime woke for that deadline (a little later).
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
    /// A port's state as the link keeps it changed (a dual bus: its port health; see
    /// [`Network::ports`](super::Network::ports)). A network on one port reports none: its
    /// driver's reports are [`NetEvent::Port`].
    PortState {
        /// The port (0 = bus 1).
        port: u8,
        /// The state before.
        from: PortState,
        /// The state now.
        to: PortState,
        /// Why (its `Display`: "nothing received for 500 ms").
        reason: PortReason,
        /// When (for a timer-driven change: exactly its deadline).
        at: Instant,
    },
    /// The buses a node is heard on changed (links of more than one bus; see
    /// [`Network::heard_on`](super::Network::heard_on)).
    Reach {
        /// The node.
        node: NodeId,
        /// The buses it is heard on, within the link's reach timeout.
        heard: HeardOn,
        /// When.
        at: Instant,
    },
    /// A watched node ([`RemoteNode::watch_heartbeat`](super::RemoteNode::watch_heartbeat))
    /// sent nothing at all (no heartbeat, no boot-up) for the watch's timeout since the watch
    /// began: a node, or its bus, dead from the start. CiA 301 starts heartbeat monitoring at
    /// the first heartbeat, so [`NetEvent::HeartbeatLost`] never comes for it. Once per watch;
    /// its first heartbeat after that starts the monitoring as CiA 301 does.
    NotHeard {
        /// The node.
        node: NodeId,
        /// When the watch began.
        since: Instant,
        /// When (`since` + the timeout; on wall-clock time, when the runtime woke for it).
        at: Instant,
    },
    /// This reader fell behind and `n` events were dropped for it (the stream goes on with the
    /// oldest event still kept). A slow reader loses events, never the program.
    Lagged(u64),
    /// An event of the core's own (a redundant master's pairs, role, discrepancies…):
    /// [`NetEvent::ext`] gives it back as its type.
    Ext(ExtEvent),
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
            | NetEvent::Pdo { node, .. }
            | NetEvent::Reach { node, .. }
            | NetEvent::NotHeard { node, .. } => Some(*node),
            NetEvent::Ext(e) => e.get().node(),
            NetEvent::Port { .. } | NetEvent::PortState { .. } | NetEvent::Lagged(_) => None,
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
            | NetEvent::Port { at, .. }
            | NetEvent::PortState { at, .. }
            | NetEvent::Reach { at, .. }
            | NetEvent::NotHeard { at, .. } => Some(*at),
            NetEvent::Ext(e) => Some(e.get().at()),
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
    /// True for a failover: a bus in use failed (a port state going to failed, but not a
    /// recovery that failed again: that is the same failure going on), or a core's event that
    /// says it is one ([`Extension::is_failover`]).
    #[must_use]
    pub fn is_failover(&self) -> bool {
        match self {
            NetEvent::PortState { from, to, .. } => {
                *to == PortState::Failed && *from != PortState::Recovering
            }
            NetEvent::Ext(e) => e.get().is_failover(),
            _ => false,
        }
    }
    /// The core's own event as its type `T`, if it is one.
    #[must_use]
    pub fn ext<T: Extension>(&self) -> Option<&T> {
        match self {
            NetEvent::Ext(e) => e.downcast_ref(),
            _ => None,
        }
    }
    /// True for a lost heartbeat, or a watched node never heard.
    #[must_use]
    pub fn is_loss(&self) -> bool {
        matches!(
            self,
            NetEvent::HeartbeatLost { .. } | NetEvent::NotHeard { .. }
        )
    }
}

/// One line per event, as a monitor prints it: `node 0x05: boot-up`, `node 0x05: operational`,
/// `node 0x05: heartbeat lost`, `node 0x05: heartbeat back`, `node 0x05: EMCY 0x8130 life guard
/// or heartbeat error`, `node 0x05: TPDO 1 Input 1=7 Status=0`, `port: down (interface down)`,
/// `bus 1: failed (port down: interface down)`, `node 0x05: heard on bus 2 only`,
/// `node 0x2a: not heard for 500 ms`, `12 events missed`.
impl fmt::Display for NetEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NetEvent::BootUp { node, .. } => write!(f, "{node}: boot-up"),
            NetEvent::State { node, to, .. } => write!(f, "{node}: {to}"),
            NetEvent::HeartbeatLost { node, .. } => write!(f, "{node}: heartbeat lost"),
            NetEvent::HeartbeatResumed { node, .. } => write!(f, "{node}: heartbeat back"),
            NetEvent::Emcy { node, msg, .. } => {
                write!(f, "{node}: EMCY {:#06x} {}", msg.code, msg.text())
            }
            NetEvent::Pdo {
                node, pdo, values, ..
            } => {
                write!(f, "{node}: TPDO {pdo}")?;
                for v in values.iter() {
                    match &v.name {
                        Some(name) => write!(f, " {name}={}", v.value)?,
                        None => write!(f, " {:#06x}sub{}={}", v.index, v.sub, v.value)?,
                    }
                }
                Ok(())
            }
            NetEvent::Port { status, .. } => match status {
                PortStatus::TxOk => f.write_str("port: frame sent"),
                PortStatus::TxFailed(c) => write!(f, "port: frame not sent ({c})"),
                PortStatus::Error(c) => write!(f, "port: error ({c})"),
                PortStatus::Down(c) => write!(f, "port: down ({c})"),
                PortStatus::Up => f.write_str("port: up"),
            },
            NetEvent::PortState {
                port, to, reason, ..
            } => write!(f, "bus {}: {to} ({reason})", u16::from(*port) + 1),
            NetEvent::Reach { node, heard, .. } => write!(f, "{node}: {heard}"),
            NetEvent::NotHeard { node, since, at } => {
                write!(f, "{node}: not heard for {} ms", (*at - *since).as_millis())
            }
            NetEvent::Lagged(n) => write!(f, "{n} events missed"),
            NetEvent::Ext(e) => fmt::Display::fmt(e, f),
        }
    }
}

/// The network's events, from the moment [`Network::events`](super::Network::events) was
/// called. `next().await` yields each event; a reader that falls more than
/// [`EVENT_QUEUE`](crate::runtime::EVENT_QUEUE) events behind gets one
/// [`NetEvent::Lagged`] with the count it missed and carries on (the count is of the runtime's
/// events, which include SDO transfer completions the stream does not show). The stream ends
/// (`None`) only when the network has been closed with [`Network::close`](super::Network::close).
pub struct Events {
    pub(super) rx: broadcast::Receiver<RuntimeEvent<CoreEvent>>,
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
                Ok(RuntimeEvent::Device(CoreEvent::Net(e))) => return Some(e),
                Ok(RuntimeEvent::Port { status, at, .. }) => {
                    return Some(NetEvent::Port { status, at })
                }
                // Transfer outcomes go to the call that started them.
                Ok(RuntimeEvent::Device(_)) => {}
                Err(broadcast::error::RecvError::Lagged(n)) => return Some(NetEvent::Lagged(n)),
                Err(broadcast::error::RecvError::Closed) => return None,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::ErrorCause;
    use crate::net::pdo::PdoValue;
    use crate::net::AnyValue;
    use std::sync::Arc;

    #[test]
    fn each_event_is_one_line_naming_the_node() {
        let node = NodeId::must(5);
        let at = Instant::from_millis(7);
        let emcy = EmcyMessage {
            code: 0x8130,
            register: 0x11,
            data: [0; 5],
        };
        let values = PdoValues(Arc::from([
            PdoValue {
                index: 0x6000,
                sub: 1,
                name: Some(Arc::from("Input 1")),
                value: AnyValue::Unsigned(7),
            },
            PdoValue {
                index: 0x6000,
                sub: 3,
                name: None,
                value: AnyValue::Signed(-2),
            },
        ]));
        let lines = [
            (
                NetEvent::HeartbeatResumed { node, at },
                "node 0x05: heartbeat back",
            ),
            (
                NetEvent::Emcy {
                    node,
                    msg: emcy,
                    at,
                },
                "node 0x05: EMCY 0x8130 life guard or heartbeat error",
            ),
            (
                NetEvent::Pdo {
                    node,
                    pdo: 1,
                    values,
                    at,
                },
                "node 0x05: TPDO 1 Input 1=7 0x6000sub3=-2",
            ),
            (
                NetEvent::Port {
                    status: PortStatus::Down(ErrorCause::InterfaceDown),
                    at,
                },
                "port: down (interface down)",
            ),
            (
                NetEvent::PortState {
                    port: 0,
                    from: PortState::Ok,
                    to: PortState::Failed,
                    reason: PortReason::Down(ErrorCause::InterfaceDown),
                    at,
                },
                "bus 1: failed (port down: interface down)",
            ),
            (
                NetEvent::Reach {
                    node,
                    heard: HeardOn::from([false, true]),
                    at,
                },
                "node 0x05: heard on bus 2 only",
            ),
            (NetEvent::Lagged(12), "12 events missed"),
        ];
        for (event, line) in lines {
            assert_eq!(event.to_string(), line);
        }
    }
}
