//! What a redundant network reports, flat: one enum, one level, and a stream that survives lag.

use crate::link::health::PortState;
use crate::network::{NetworkEvent, NetworkEventKind};
use crate::pair::{Member, PairId};
use crate::supervisor::flying_master::{MasterReason, MasterRole};
use crate::supervisor::pairs::{PairsEvent, RoleReason};
use crate::SupervisorEvent;
use core::fmt;
use duocan::emcy::EmcyMessage;
use duocan::machine::StationEvent;
use duocan::master::{ErrorStatus, MasterEventKind};
use duocan::node::NodeEventKind;
use duocan::runtime::RuntimeEvent;
use duocan::{Frame, Instant, NmtState, NodeId};
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
    /// The buses a node is heard on changed: heard on one bus only is a fault the application
    /// does not see (the other bus carries everything) and a maintainer must.
    Reach {
        /// The node.
        node: NodeId,
        /// Heard on bus 1, on bus 2.
        heard: [bool; 2],
        /// When.
        at: Instant,
    },
    /// A and B of a pair have carried different values of one function for longer than the
    /// discrepancy time.
    Discrepancy {
        /// The pair.
        pair: PairId,
        /// The function (e.g. the TPDO number).
        function: u32,
        /// A's latest frame.
        a: Frame,
        /// B's latest frame.
        b: Frame,
        /// When the discrepancy time ran out.
        at: Instant,
    },
    /// A and B of a pair agree again on a function.
    DiscrepancyCleared {
        /// The pair.
        pair: PairId,
        /// The function.
        function: u32,
        /// When.
        at: Instant,
    },
    /// The boot process did not start a slave: it is not what 0x1F84–0x1F88 expect, or a step
    /// of its configuration failed (the CiA 302-2 error status says which).
    BootFailed {
        /// The slave.
        node: NodeId,
        /// C, D, M, N, O (identity) or J (configuration), …
        status: ErrorStatus,
        /// When.
        at: Instant,
    },
    /// A pair member was not heard at all within the boot timeout since the network started
    /// or since it was reset ([`PairsConfig::boot_timeout`]): a board, or its buses, dead from
    /// power-on. CiA 301 starts heartbeat monitoring at the first heartbeat, so nothing else
    /// reports it. Once per wait; its first frame ends it (a boot-up, or its heartbeat).
    ///
    /// [`PairsConfig::boot_timeout`]: crate::supervisor::pairs::PairsConfig::boot_timeout
    NotHeard {
        /// The member.
        node: NodeId,
        /// Since when it has been awaited.
        since: Instant,
        /// When (`since` + the boot timeout).
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
            K::Reach { node, heard } => RedundantEvent::Reach { node, heard, at },
            K::Discrepancy {
                pair,
                function,
                a,
                b,
            } => RedundantEvent::Discrepancy {
                pair,
                function,
                a,
                b,
                at,
            },
            K::DiscrepancyCleared { pair, function } => {
                RedundantEvent::DiscrepancyCleared { pair, function, at }
            }
            K::Other(StationEvent::Machine(SupervisorEvent::Node(ref n))) => match n.kind {
                NodeEventKind::HeartbeatResumed { node } => RedundantEvent::SlaveBack { node, at },
                _ => return None,
            },
            K::Other(StationEvent::Machine(SupervisorEvent::Pairs(PairsEvent::Missing {
                node,
                since,
                ..
            }))) => RedundantEvent::NotHeard { node, since, at },
            K::Other(StationEvent::Machine(SupervisorEvent::Master(ref m))) => match m.kind {
                MasterEventKind::IdentityMismatch { node, status, .. }
                | MasterEventKind::ConfigFailed { node, status, .. } => {
                    RedundantEvent::BootFailed { node, status, at }
                }
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
            | RedundantEvent::Emcy { node, .. }
            | RedundantEvent::Reach { node, .. }
            | RedundantEvent::BootFailed { node, .. }
            | RedundantEvent::NotHeard { node, .. } => Some(node),
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
            | RedundantEvent::Emcy { at, .. }
            | RedundantEvent::Reach { at, .. }
            | RedundantEvent::Discrepancy { at, .. }
            | RedundantEvent::DiscrepancyCleared { at, .. }
            | RedundantEvent::BootFailed { at, .. }
            | RedundantEvent::NotHeard { at, .. } => Some(at),
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
            RedundantEvent::Reach { node, heard, .. } => {
                let on = match heard {
                    [true, true] => "both buses",
                    [true, false] => "bus 1 only",
                    [false, true] => "bus 2 only",
                    [false, false] => "no bus",
                };
                write!(f, "node {:#04x}: heard on {on}", node.raw())
            }
            RedundantEvent::Discrepancy { pair, function, .. } => write!(
                f,
                "pair {}: A and B disagree on function {function}",
                pair.0
            ),
            RedundantEvent::DiscrepancyCleared { pair, function, .. } => {
                write!(
                    f,
                    "pair {}: A and B agree again on function {function}",
                    pair.0
                )
            }
            RedundantEvent::BootFailed { node, status, .. } => {
                write!(f, "node {:#04x}: not started, {status}", node.raw())
            }
            RedundantEvent::NotHeard { node, since, at } => write!(
                f,
                "node {:#04x}: not heard for {} ms",
                node.raw(),
                (at - since).as_millis()
            ),
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

#[cfg(test)]
mod tests {
    use super::*;
    use duocan::master::{BootError, MasterEvent};
    use duocan::Id;

    fn flat(kind: NetworkEventKind) -> Option<RedundantEvent> {
        RedundantEvent::of(&NetworkEvent {
            at: Instant::from_millis(7),
            kind,
        })
    }

    #[test]
    fn discrepancy_and_its_clearing_reach_the_flat_stream() {
        let (a, b) = (
            Frame::from_array(Id::Standard(0x190), [1]),
            Frame::from_array(Id::Standard(0x1D0), [2]),
        );
        let e = flat(NetworkEventKind::Discrepancy {
            pair: PairId(1),
            function: 1,
            a,
            b,
        })
        .unwrap();
        assert_eq!(e.at(), Some(Instant::from_millis(7)));
        assert_eq!(e.to_string(), "pair 1: A and B disagree on function 1");
        assert!(matches!(e, RedundantEvent::Discrepancy { a: x, b: y, .. } if x == a && y == b));
        let e = flat(NetworkEventKind::DiscrepancyCleared {
            pair: PairId(1),
            function: 1,
        })
        .unwrap();
        assert_eq!(e.to_string(), "pair 1: A and B agree again on function 1");
    }

    #[test]
    fn a_slave_the_boot_process_refused_or_failed_reaches_the_flat_stream() {
        let node = NodeId::must(0x12);
        let master = |kind| {
            flat(NetworkEventKind::Other(StationEvent::Machine(
                SupervisorEvent::Master(MasterEvent {
                    at: Instant::from_millis(7),
                    kind,
                }),
            )))
        };
        let mismatch = master(MasterEventKind::IdentityMismatch {
            node,
            status: ErrorStatus::D,
            index: 0x1018,
            sub: 1,
            expected: 0x1234,
            actual: 0x4321,
        })
        .unwrap();
        assert_eq!(mismatch.node(), Some(node));
        assert!(matches!(
            mismatch,
            RedundantEvent::BootFailed {
                status: ErrorStatus::D,
                ..
            }
        ));
        let failed = master(MasterEventKind::ConfigFailed {
            node,
            status: ErrorStatus::J,
            reason: BootError::NoSuchPdo { pdo: 600 },
        })
        .unwrap();
        assert!(
            failed
                .to_string()
                .starts_with("node 0x12: not started, error status J"),
            "{failed}"
        );
        assert_eq!(failed.at(), Some(Instant::from_millis(7)));
    }

    #[test]
    fn a_member_never_heard_reaches_the_flat_stream() {
        let node = NodeId::must(0x50);
        let e = flat(NetworkEventKind::Other(StationEvent::Machine(
            SupervisorEvent::Pairs(PairsEvent::Missing {
                at: Instant::from_millis(7),
                pair: PairId(0),
                member: Member::B,
                node,
                since: Instant::from_millis(2),
            }),
        )))
        .unwrap();
        assert_eq!(
            e,
            RedundantEvent::NotHeard {
                node,
                since: Instant::from_millis(2),
                at: Instant::from_millis(7)
            }
        );
        assert_eq!(
            (e.node(), e.at()),
            (Some(node), Some(Instant::from_millis(7)))
        );
        assert_eq!(e.to_string(), "node 0x50: not heard for 5 ms");
    }

    #[test]
    fn reach_says_which_bus_in_words() {
        let node = NodeId::must(0x7A);
        let line = |heard| {
            flat(NetworkEventKind::Reach { node, heard })
                .unwrap()
                .to_string()
        };
        assert_eq!(line([false, true]), "node 0x7a: heard on bus 2 only");
        assert_eq!(line([true, false]), "node 0x7a: heard on bus 1 only");
        assert_eq!(line([true, true]), "node 0x7a: heard on both buses");
        assert_eq!(line([false, false]), "node 0x7a: heard on no bus");
    }
}
