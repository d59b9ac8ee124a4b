//! What a redundant network reports, flat: one enum, one level, and a stream that survives lag.

use crate::link::health::PortState;
use crate::network::{NetworkEvent, NetworkEventKind};
use crate::pair::{Member, PairId};
use crate::supervisor::flying_master::{MasterReason, MasterRole};
use crate::supervisor::pairs::RoleReason;
use core::fmt;
use duocan::emcy::EmcyMessage;
use duocan::node::NodeEventKind;
use duocan::runtime::RuntimeEvent;
use duocan::{Instant, NmtState, NodeId};
use tokio::sync::{broadcast, watch};

/// One thing that happened on a redundant network. Every variant is one level deep; the
/// accessors ([`node`](Self::node), [`at`](Self::at), [`is_failover`](Self::is_failover))
/// answer the common questions without a `match`, and `Display` prints one short line.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum RedundantEvent {
    /// A bus (one port of this master) changed health: `Failed` is a bus failover (the other
    /// bus carries everything), `Ok` a recovery.
    Bus {
        /// 0 = bus 1.
        port: u8,
        /// Before.
        from: PortState,
        /// After.
        to: PortState,
        /// When.
        at: Instant,
    },
    /// A pair's active member changed.
    PairRole {
        /// The pair.
        pair: PairId,
        /// Node-IDs of A and B.
        nodes: [NodeId; 2],
        /// The active member before.
        from: Option<Member>,
        /// The active member now.
        to: Option<Member>,
        /// Why.
        reason: RoleReason,
        /// When (for a silent member: exactly its last heartbeat + the pair timeout).
        at: Instant,
    },
    /// This master's role changed.
    MasterRole {
        /// Before.
        from: MasterRole,
        /// After.
        to: MasterRole,
        /// Why.
        reason: MasterReason,
        /// When (for a takeover: exactly the active master's last heartbeat + the master
        /// timeout).
        at: Instant,
    },
    /// Error control lost a slave (its heartbeat stopped, or it was never heard after its
    /// configuration).
    SlaveLost {
        /// The slave.
        node: NodeId,
        /// When.
        at: Instant,
    },
    /// A lost slave's heartbeat came back.
    SlaveBack {
        /// The slave.
        node: NodeId,
        /// When.
        at: Instant,
    },
    /// A node sent its boot-up.
    BootUp {
        /// The node.
        node: NodeId,
        /// When.
        at: Instant,
    },
    /// A node's NMT state changed.
    State {
        /// The node.
        node: NodeId,
        /// The state before, if known.
        from: Option<NmtState>,
        /// Now.
        to: NmtState,
        /// When.
        at: Instant,
    },
    /// An emergency message of a node.
    Emcy {
        /// The node.
        node: NodeId,
        /// The message.
        msg: EmcyMessage,
        /// When.
        at: Instant,
    },
    /// This reader fell behind and `n` events were dropped for it; the stream goes on. A slow
    /// reader loses events, never the program.
    Lagged(u64),
}

impl RedundantEvent {
    /// The flat event of a network event, if it is one the stream shows.
    fn of(e: &NetworkEvent) -> Option<Self> {
        use NetworkEventKind as K;
        let at = e.at;
        Some(match e.kind {
            K::Port { port, from, to, .. } => RedundantEvent::Bus { port, from, to, at },
            K::PairRole(r) => RedundantEvent::PairRole {
                pair: r.pair,
                nodes: r.nodes,
                from: r.from,
                to: r.to,
                reason: r.reason,
                at,
            },
            K::MasterRole(r) => RedundantEvent::MasterRole {
                from: r.from,
                to: r.to,
                reason: r.reason,
                at,
            },
            K::NodeLost { node, .. } => RedundantEvent::SlaveLost { node, at },
            K::NodeBooted { node } => RedundantEvent::BootUp { node, at },
            K::NodeState { node, from, to } => RedundantEvent::State { node, from, to, at },
            K::Emcy { node, msg } => RedundantEvent::Emcy { node, msg, at },
            K::Other(duocan::machine::StationEvent::Machine(crate::SupervisorEvent::Node(
                ref n,
            ))) => match n.kind {
                NodeEventKind::HeartbeatResumed { node } => RedundantEvent::SlaveBack { node, at },
                _ => return None,
            },
            _ => return None,
        })
    }

    /// The node the event is about, if one.
    #[must_use]
    pub fn node(&self) -> Option<NodeId> {
        match *self {
            RedundantEvent::SlaveLost { node, .. }
            | RedundantEvent::SlaveBack { node, .. }
            | RedundantEvent::BootUp { node, .. }
            | RedundantEvent::State { node, .. }
            | RedundantEvent::Emcy { node, .. } => Some(node),
            RedundantEvent::PairRole { nodes, to, .. } => to.map(|m| match m {
                Member::A => nodes[0],
                Member::B => nodes[1],
            }),
            _ => None,
        }
    }
    /// When it happened (the network's clock).
    #[must_use]
    pub fn at(&self) -> Option<Instant> {
        match *self {
            RedundantEvent::Bus { at, .. }
            | RedundantEvent::PairRole { at, .. }
            | RedundantEvent::MasterRole { at, .. }
            | RedundantEvent::SlaveLost { at, .. }
            | RedundantEvent::SlaveBack { at, .. }
            | RedundantEvent::BootUp { at, .. }
            | RedundantEvent::State { at, .. }
            | RedundantEvent::Emcy { at, .. } => Some(at),
            RedundantEvent::Lagged(_) => None,
        }
    }
    /// True for a failover: a bus in use failed, a pair's active member handed over to the other, or
    /// this standby master took over from the active one.
    #[must_use]
    pub fn is_failover(&self) -> bool {
        match *self {
            // A failed re-initialisation (recovering -> failed) is the same failure going on.
            RedundantEvent::Bus { from, to, .. } => {
                to == PortState::Failed && from != PortState::Recovering
            }
            RedundantEvent::PairRole { from, to, .. } => {
                from.is_some() && to.is_some() && from != to
            }
            RedundantEvent::MasterRole { from, to, .. } => {
                matches!(from, MasterRole::Standby(_)) && to == MasterRole::Active
            }
            _ => false,
        }
    }
}

impl fmt::Display for RedundantEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let member = |m: Option<Member>| match m {
            Some(Member::A) => "A",
            Some(Member::B) => "B",
            None => "no member",
        };
        match *self {
            RedundantEvent::Bus { port, to, .. } => write!(f, "bus {}: {to}", port + 1),
            RedundantEvent::PairRole { nodes, to, .. } => write!(
                f,
                "pair {:#04x}/{:#04x}: {} active",
                nodes[0].raw(),
                nodes[1].raw(),
                member(to)
            ),
            RedundantEvent::MasterRole { to, .. } => write!(f, "this master: {to}"),
            RedundantEvent::SlaveLost { node, .. } => write!(f, "node {:#04x}: lost", node.raw()),
            RedundantEvent::SlaveBack { node, .. } => write!(f, "node {:#04x}: back", node.raw()),
            RedundantEvent::BootUp { node, .. } => write!(f, "node {:#04x}: boot-up", node.raw()),
            RedundantEvent::State { node, to, .. } => write!(f, "node {:#04x}: {to}", node.raw()),
            RedundantEvent::Emcy { node, msg, .. } => {
                write!(f, "node {:#04x}: EMCY {:#06x}", node.raw(), msg.code)
            }
            RedundantEvent::Lagged(n) => write!(f, "{n} events missed"),
        }
    }
}

/// The network's events from the moment [`RedundantNetwork::events`](super::RedundantNetwork::events)
/// was called. `next().await` yields each one; a reader that falls more than
/// [`EVENT_QUEUE`](duocan::runtime::EVENT_QUEUE) events behind gets one
/// [`RedundantEvent::Lagged`] and carries on. The stream ends (`None`) only when the network
/// is closed.
pub struct RedundantEvents {
    rx: broadcast::Receiver<RuntimeEvent<NetworkEvent>>,
    closed: watch::Receiver<bool>,
}

impl RedundantEvents {
    pub(super) fn new(
        rx: broadcast::Receiver<RuntimeEvent<NetworkEvent>>,
        closed: watch::Receiver<bool>,
    ) -> Self {
        RedundantEvents { rx, closed }
    }

    /// The next event, or `None` once the network is closed.
    pub async fn next(&mut self) -> Option<RedundantEvent> {
        loop {
            let r = tokio::select! {
                biased;
                r = self.rx.recv() => r,
                _ = self.closed.wait_for(|c| *c) => return None,
            };
            match r {
                Ok(RuntimeEvent::Device(e)) => {
                    if let Some(e) = RedundantEvent::of(&e) {
                        return Some(e);
                    }
                }
                // The dual-bus layer reports what a port's status means (`Bus`).
                Ok(_) => {}
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    return Some(RedundantEvent::Lagged(n))
                }
                Err(broadcast::error::RecvError::Closed) => return None,
            }
        }
    }
}
