//! What only a redundant network reports: [`RedundantEvent`], carried in duocan's flat event
//! stream as [`NetEvent::Ext`](duocan::net::NetEvent::Ext).
//!
//! **Why.** Boot-ups, states, EMCY, reach, port health and nodes never heard are every
//! network's, and come as duocan's own [`NetEvent`](duocan::net::NetEvent)s; pairs, the master
//! role, error control of the master's slaves, refused boots and everything else the dual-bus
//! layer reports (A/B discrepancies, suspect heartbeats, a bus lagging, …) exist only here. Each
//! carries the type its layer declares ([`RoleChange`], [`MasterRoleChange`], [`LinkEvent`]):
//! an event kind is declared once, where it happens, and this stream is a view of them. `e.ext::<RedundantEvent>()` gives them back typed; `Display`, `node()`, `at()` and
//! `is_failover()` work on the stream's event without it.

use crate::link::events::{LinkEvent, LinkEventKind};
use crate::logical::NetworkEventKind;
use crate::pair::Member;
use crate::supervisor::audit::BoardAddressed;
use crate::supervisor::flying_master::{FlyingEvent, MasterRole, MasterRoleChange};
use crate::supervisor::pairs::{PairsEvent, RoleChange};
use crate::SupervisorEvent;
use core::fmt;
use duocan::machine::StationEvent;
use duocan::master::{ErrorStatus, MasterEventKind};
use duocan::net::Extension;
use duocan::node::NodeEventKind;
use duocan::{Instant, NodeId};

/// What happened on a redundant network that only redundancy knows. The supervisor's and the
/// dual-bus layer's own event types inside (each declared once, where it happens); `Display`
/// prints one short line.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum RedundantEvent {
    /// A pair's active member changed (when: for a silent member, exactly its last heartbeat +
    /// the pair timeout).
    PairRole(RoleChange),
    /// This master's role changed (when: for a takeover, exactly the active master's last
    /// heartbeat + the master timeout).
    MasterRole(MasterRoleChange),
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
    /// A pair member joined its pair (configured) or left it ([`PairsEvent::Joined`],
    /// [`PairsEvent::Lost`]; a role change is [`RedundantEvent::PairRole`], a member never
    /// heard duocan's `NetEvent::NotHeard`).
    Member(PairsEvent),
    /// This master suspended its NMT commands: another active master is suspected
    /// ([`FlyingEvent::Suspended`]; a role change is [`RedundantEvent::MasterRole`]).
    Flying(FlyingEvent),
    /// A board without a node-ID was given a pair member's node-ID by LSS; it joins from there.
    Addressed(BoardAddressed),
    /// What the dual-bus layer reports besides port health and reach (duocan's
    /// `NetEvent::PortState` and `NetEvent::Reach`): A/B discrepancies and their end, channel
    /// switches, heartbeats suspected, babbling identifiers, duplicate node-IDs, a bus lagging
    /// behind the other, …
    Link(LinkEvent),
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
}

impl RedundantEvent {
    /// The event of a network event's kind at `at`, if it is one of redundancy's own.
    pub(super) fn of(at: Instant, kind: NetworkEventKind) -> Option<Self> {
        use NetworkEventKind as K;
        Some(match kind {
            K::PairRole(r) => RedundantEvent::PairRole(r),
            K::MasterRole(r) => RedundantEvent::MasterRole(r),
            K::NodeLost { node, .. } => RedundantEvent::SlaveLost { node, at },
            K::Discrepancy {
                pair,
                function,
                a,
                b,
            } => RedundantEvent::Link(LinkEvent {
                at,
                kind: LinkEventKind::Discrepancy {
                    pair,
                    function,
                    a,
                    b,
                },
            }),
            K::DiscrepancyCleared { pair, function } => RedundantEvent::Link(LinkEvent {
                at,
                kind: LinkEventKind::DiscrepancyCleared { pair, function },
            }),
            K::Other(StationEvent::Link(l)) => RedundantEvent::Link(l),
            K::Other(StationEvent::Machine(SupervisorEvent::Pairs(
                p @ (PairsEvent::Joined { .. } | PairsEvent::Lost { .. }),
            ))) => RedundantEvent::Member(p),
            K::Other(StationEvent::Machine(SupervisorEvent::FlyingMaster(
                f @ FlyingEvent::Suspended { .. },
            ))) => RedundantEvent::Flying(f),
            K::Other(StationEvent::Machine(SupervisorEvent::Addressed(b))) => {
                RedundantEvent::Addressed(b)
            }
            K::Other(StationEvent::Machine(SupervisorEvent::Node(ref n))) => match n.kind {
                NodeEventKind::HeartbeatResumed { node } => RedundantEvent::SlaveBack { node, at },
                _ => return None,
            },
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

    /// The node the event is about, if one (a pair's newly active member).
    #[must_use]
    pub fn node(&self) -> Option<NodeId> {
        match *self {
            RedundantEvent::SlaveLost { node, .. }
            | RedundantEvent::SlaveBack { node, .. }
            | RedundantEvent::BootFailed { node, .. }
            | RedundantEvent::Member(
                PairsEvent::Joined { node, .. }
                | PairsEvent::Lost { node, .. }
                | PairsEvent::Missing { node, .. },
            )
            | RedundantEvent::Addressed(BoardAddressed { node, .. }) => Some(node),
            RedundantEvent::PairRole(r) => r.to.map(|m| match m {
                Member::A => r.nodes[0],
                Member::B => r.nodes[1],
            }),
            _ => None,
        }
    }
    /// When it happened (the network's clock).
    #[must_use]
    pub fn at(&self) -> Instant {
        match *self {
            RedundantEvent::PairRole(RoleChange { at, .. })
            | RedundantEvent::MasterRole(MasterRoleChange { at, .. })
            | RedundantEvent::Link(LinkEvent { at, .. })
            | RedundantEvent::Member(
                PairsEvent::Role(RoleChange { at, .. })
                | PairsEvent::Joined { at, .. }
                | PairsEvent::Lost { at, .. }
                | PairsEvent::Missing { at, .. },
            )
            | RedundantEvent::Flying(
                FlyingEvent::Role(MasterRoleChange { at, .. }) | FlyingEvent::Suspended { at, .. },
            )
            | RedundantEvent::Addressed(BoardAddressed { at, .. })
            | RedundantEvent::SlaveLost { at, .. }
            | RedundantEvent::SlaveBack { at, .. }
            | RedundantEvent::BootFailed { at, .. } => at,
        }
    }
    /// True for a failover: a pair's active member handed over to the other, or this standby
    /// master took over from the active one (a bus failover is duocan's
    /// [`NetEvent::PortState`](duocan::net::NetEvent::PortState)).
    #[must_use]
    pub fn is_failover(&self) -> bool {
        match *self {
            RedundantEvent::PairRole(RoleChange { from, to, .. }) => {
                from.is_some() && to.is_some() && from != to
            }
            RedundantEvent::MasterRole(MasterRoleChange { from, to, .. }) => {
                matches!(from, MasterRole::Standby(_)) && to == MasterRole::Active
            }
            _ => false,
        }
    }
}

impl Extension for RedundantEvent {
    fn at(&self) -> Instant {
        RedundantEvent::at(self)
    }
    fn node(&self) -> Option<NodeId> {
        RedundantEvent::node(self)
    }
    fn is_failover(&self) -> bool {
        RedundantEvent::is_failover(self)
    }
    fn eq_dyn(&self, other: &dyn Extension) -> bool {
        (other as &dyn core::any::Any).downcast_ref::<Self>() == Some(self)
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
            RedundantEvent::PairRole(RoleChange { nodes, to, .. }) => write!(
                f,
                "pair {:#04x}/{:#04x}: {} active",
                nodes[0].raw(),
                nodes[1].raw(),
                member(to)
            ),
            RedundantEvent::MasterRole(MasterRoleChange { to, .. }) => {
                write!(f, "this master: {to}")
            }
            RedundantEvent::Link(l) => fmt::Display::fmt(&l.kind, f),
            RedundantEvent::Member(p) => match p {
                PairsEvent::Joined {
                    pair, member, node, ..
                } => write!(f, "pair {} member {member} ({node}): joined", pair.0),
                PairsEvent::Lost {
                    pair,
                    member,
                    node,
                    reason,
                    ..
                } => write!(f, "pair {} member {member} ({node}): lost, {reason}", pair.0),
                PairsEvent::Missing {
                    pair, member, node, ..
                } => write!(f, "pair {} member {member} ({node}): not heard", pair.0),
                PairsEvent::Role(r) => write!(f, "pair {}: {} active", r.pair.0, member(r.to)),
            },
            RedundantEvent::Flying(e) => match e {
                FlyingEvent::Suspended { until, .. } => write!(
                    f,
                    "this master: NMT commands suspended until {until}, another active master suspected"
                ),
                FlyingEvent::Role(r) => write!(f, "this master: {}", r.to),
            },
            RedundantEvent::Addressed(b) => write!(
                f,
                "pair {} member {}: a board without node-ID ({}) given {} by LSS",
                b.pair.0, b.member, b.address, b.node
            ),
            RedundantEvent::SlaveLost { node, .. } => write!(f, "node {:#04x}: lost", node.raw()),
            RedundantEvent::SlaveBack { node, .. } => write!(f, "node {:#04x}: back", node.raw()),
            RedundantEvent::BootFailed { node, status, .. } => {
                write!(f, "node {:#04x}: not started, {status}", node.raw())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::logical::NetworkEvent;
    use crate::supervisor::pairs::PairsEvent;
    use crate::PairId;
    use duocan::master::{BootError, MasterEvent};
    use duocan::net::{CoreEvent, NetEvent};
    use duocan::{Frame, Id};

    /// The event of the door's stream a network event becomes.
    fn flat(kind: NetworkEventKind) -> Option<NetEvent> {
        let e = NetworkEvent {
            at: Instant::from_millis(7),
            kind,
        };
        match super::super::core::core_event(e)? {
            CoreEvent::Net(e) => Some(e),
            _ => None,
        }
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
        assert_eq!(
            e.to_string(),
            format!("pair 1 function 1: A sends {a}, B sends {b}")
        );
        assert!(matches!(
            e.ext(),
            Some(RedundantEvent::Link(LinkEvent {
                kind: LinkEventKind::Discrepancy { a: x, b: y, .. },
                ..
            })) if *x == a && *y == b
        ));
        let e = flat(NetworkEventKind::DiscrepancyCleared {
            pair: PairId(1),
            function: 1,
        })
        .unwrap();
        assert_eq!(e.to_string(), "pair 1 function 1: A and B agree again");
    }

    /// The supervisor's other reports reach the stream: a member joining and leaving its pair,
    /// commands suspended, a replacement board addressed by LSS; typed as the supervisor
    /// declares them, one line each.
    #[test]
    fn members_joining_and_leaving_suspensions_and_addressed_boards_reach_the_flat_stream() {
        use crate::supervisor::pairs::LossReason;
        let (at, node) = (Instant::from_millis(7), NodeId::must(0x50));
        let sup = |e| flat(NetworkEventKind::Other(StationEvent::Machine(e))).unwrap();
        let joined = PairsEvent::Joined {
            at,
            pair: PairId(0),
            member: Member::B,
            node,
        };
        let e = sup(SupervisorEvent::Pairs(joined));
        assert_eq!(e.ext(), Some(&RedundantEvent::Member(joined)));
        assert_eq!(e.to_string(), "pair 0 member B (node 0x50): joined");
        assert_eq!((e.node(), e.at()), (Some(node), Some(at)));
        let lost = PairsEvent::Lost {
            at,
            pair: PairId(0),
            member: Member::B,
            node,
            reason: LossReason::Rebooted,
        };
        let e = sup(SupervisorEvent::Pairs(lost));
        assert_eq!(
            e.to_string(),
            "pair 0 member B (node 0x50): lost, it booted again"
        );
        let until = Instant::from_millis(500);
        let e = sup(SupervisorEvent::FlyingMaster(FlyingEvent::Suspended {
            at,
            until,
        }));
        assert_eq!(
            e.to_string(),
            format!("this master: NMT commands suspended until {until}, another active master suspected")
        );
        assert_eq!(e.at(), Some(at));
        let address = duocan::cia305::LssAddress {
            vendor: 0xD0CA00,
            product: 0x305,
            revision: 1,
            serial: 2,
        };
        let b = BoardAddressed {
            at,
            pair: PairId(0),
            member: Member::B,
            node,
            address,
        };
        let e = sup(SupervisorEvent::Addressed(b));
        assert_eq!(e.ext(), Some(&RedundantEvent::Addressed(b)));
        assert_eq!(
            e.to_string(),
            format!("pair 0 member B: a board without node-ID ({address}) given node 0x50 by LSS")
        );
        assert_eq!(e.node(), Some(node));
    }

    /// Every other report of the dual-bus layer reaches the stream too, typed as the layer
    /// declares it, one line each.
    #[test]
    fn every_other_report_of_the_dual_bus_layer_reaches_the_flat_stream() {
        let kinds = [
            LinkEventKind::Lag {
                port: 1,
                lag: duocan::Duration::from_millis(12),
                window: duocan::Duration::from_millis(14),
            },
            LinkEventKind::LagCleared { port: 1 },
            LinkEventKind::Trusted {
                node: NodeId::must(0x10),
            },
        ];
        for kind in kinds {
            let l = LinkEvent {
                at: Instant::from_millis(7),
                kind,
            };
            let e = flat(NetworkEventKind::Other(StationEvent::Link(l))).unwrap();
            assert_eq!(e.ext(), Some(&RedundantEvent::Link(l)));
            assert_eq!(e.to_string(), kind.to_string());
            assert!(!e.to_string().contains('\n'));
            assert_eq!(e.at(), Some(Instant::from_millis(7)));
        }
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
            mismatch.ext(),
            Some(RedundantEvent::BootFailed {
                status: ErrorStatus::D,
                ..
            })
        ));
        assert!(!mismatch.is_failover());
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
            NetEvent::NotHeard {
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
