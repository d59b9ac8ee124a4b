//! What only a redundant network reports: [`RedundantEvent`], carried in duocan's flat event
//! stream as [`NetEvent::Ext`](duocan::net::NetEvent::Ext).
//!
//! **Why.** Boot-ups, states, EMCY, reach, port health and nodes never heard are every
//! network's, and come as duocan's own [`NetEvent`](duocan::net::NetEvent)s; pairs, the master
//! role, the CiA 302-2 master's boot process and error control of its slaves, refused members,
//! LSS and everything else the dual-bus layer reports (A/B discrepancies, suspect heartbeats, a
//! bus lagging, …) exist only here. Each carries the type its layer declares ([`RoleChange`],
//! [`MasterRoleChange`], [`LinkEvent`], [`MasterEvent`], [`NodeEvent`], [`NotJoined`],
//! [`LssMasterEvent`]): an event kind is declared once, where it happens, and this stream is a
//! view of them. `e.ext::<RedundantEvent>()` gives them back typed; `Display`, `node()`, `at()`
//! and `is_failover()` work on the stream's event without it.
//!
//! **What is left out.** Every report of the station reaches the stream once, except:
//!
//! - what duocan's own events already say: the node's boot-up, remote states, EMCY and the
//!   heartbeats the door watches; the master's [`SlaveBootUp`](MasterEventKind::SlaveBootUp)
//!   (the node's boot-up, again), [`ActiveChanged`](MasterEventKind::ActiveChanged) (the
//!   flying master's [`RedundantEvent::MasterRole`] says it, with why), and the node's
//!   heartbeat and guarding timeouts of the master's slaves (the master's
//!   [`SlaveLost`](MasterEventKind::SlaveLost) says it, with the CiA 302-2 status);
//! - what comes once per frame or per cycle, which would flood the stream and make every slow
//!   reader lag: SYNC, TIME, dictionary writes, RPDOs received (the door decodes the TPDOs
//!   itself, [`NetEvent::Pdo`](duocan::net::NetEvent::Pdo)), malformed frames (counted in the
//!   node's statistics) and a program download's progress (its end is
//!   [`ProgramDownloaded`](MasterEventKind::ProgramDownloaded)).
//!
//! The rule for a new kind: it reaches the stream unless one of duocan's events or another
//! kind here already says it, or it can come once per frame or per cycle. A pair member the
//! boot process refused comes twice, on purpose: the master's report says what failed, and
//! [`RedundantEvent::NotJoined`] what the pair supervision did about it (left alone, or reset
//! to try again).

use crate::link::events::{LinkEvent, LinkEventKind};
use crate::logical::NetworkEventKind;
use crate::pair::Member;
use crate::supervisor::audit::BoardAddressed;
use crate::supervisor::flying_master::{FlyingEvent, MasterRole, MasterRoleChange};
use crate::supervisor::pairs::{PairsEvent, RoleChange};
use crate::supervisor::NotJoined;
use crate::SupervisorEvent;
use core::fmt;
use duocan::cia305::{LssMasterEvent, LssMasterEventKind};
use duocan::machine::StationEvent;
use duocan::master::{MasterEvent, MasterEventKind};
use duocan::net::Extension;
use duocan::node::{NodeEvent, NodeEventKind};
use duocan::pdo::PdoEvent;
use duocan::{Instant, NodeId};

/// What happened on a redundant network that only redundancy knows. The supervisor's, the
/// master's and the dual-bus layer's own event types inside (each declared once, where it
/// happens); `Display` prints one short line.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum RedundantEvent {
    /// A pair's active member changed (when: for a silent member, exactly its last heartbeat +
    /// the pair timeout).
    PairRole(RoleChange),
    /// This master's role changed (when: for a takeover, exactly the active master's last
    /// heartbeat + the master timeout).
    MasterRole(MasterRoleChange),
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
    /// What the CiA 302-2 master reports: error control lost a slave
    /// ([`MasterEventKind::SlaveLost`], with E, F or K), the boot process refused or could not
    /// configure one ([`MasterEventKind::IdentityMismatch`], [`MasterEventKind::ConfigFailed`],
    /// with the CiA 302-2 status), configured, started or adopted it, the network started or
    /// mandatory slaves missing, program downloads, request NMT, … ([`RedundantEvent::master`]
    /// gives the kind).
    Master(MasterEvent),
    /// What the master's own node reports that no other event says: a lost slave's heartbeat
    /// back ([`NodeEventKind::HeartbeatResumed`]), guarding, its own NMT state, NMT commands
    /// seen, RPDO timeouts, SRDOs, parameter storage, …
    /// ([`RedundantEvent::node_event`] gives the kind).
    Node(NodeEvent),
    /// A pair member the boot process refused did not join (why inside).
    NotJoined(NotJoined),
    /// A result of the LSS master (board replacement: identify, fastscan).
    Lss(LssMasterEvent),
}

impl RedundantEvent {
    /// The event of a network event's kind at `at`, if it is one of redundancy's own and not
    /// left out (see [the module](self)).
    pub(super) fn of(at: Instant, kind: NetworkEventKind) -> Option<Self> {
        use NetworkEventKind as K;
        Some(match kind {
            K::PairRole(r) => RedundantEvent::PairRole(r),
            K::MasterRole(r) => RedundantEvent::MasterRole(r),
            K::NodeLost { node, status } => RedundantEvent::Master(MasterEvent {
                at,
                kind: MasterEventKind::SlaveLost { node, status },
            }),
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
            K::Other(StationEvent::Machine(m)) => return Self::of_supervisor(m),
            // Port, reach, boot-ups, states, EMCY and SDO results are duocan's events; an RPDO
            // received comes once per frame.
            _ => return None,
        })
    }

    /// The event of a supervisor's report the network did not type, if the stream shows it.
    fn of_supervisor(e: SupervisorEvent) -> Option<Self> {
        Some(match e {
            SupervisorEvent::Pairs(p @ (PairsEvent::Joined { .. } | PairsEvent::Lost { .. })) => {
                RedundantEvent::Member(p)
            }
            SupervisorEvent::FlyingMaster(f @ FlyingEvent::Suspended { .. }) => {
                RedundantEvent::Flying(f)
            }
            SupervisorEvent::Addressed(b) => RedundantEvent::Addressed(b),
            SupervisorEvent::NotJoined(n) => RedundantEvent::NotJoined(n),
            SupervisorEvent::Lss(l) => RedundantEvent::Lss(l),
            SupervisorEvent::Node(n) if shown_node(&n.kind) => RedundantEvent::Node(n),
            SupervisorEvent::Master(m) if shown_master(&m.kind) => RedundantEvent::Master(m),
            _ => return None,
        })
    }

    /// The master's report inside, if it is one: `if let Some(MasterEventKind::SlaveLost {
    /// node, status }) = e.master()`.
    #[must_use]
    pub fn master(&self) -> Option<&MasterEventKind> {
        match self {
            RedundantEvent::Master(m) => Some(&m.kind),
            _ => None,
        }
    }

    /// The master's node's report inside, if it is one: `if let
    /// Some(NodeEventKind::HeartbeatResumed { node }) = e.node_event()`.
    #[must_use]
    pub fn node_event(&self) -> Option<&NodeEventKind> {
        match self {
            RedundantEvent::Node(n) => Some(&n.kind),
            _ => None,
        }
    }

    /// The node the event is about, if one (a pair's newly active member).
    #[must_use]
    pub fn node(&self) -> Option<NodeId> {
        match self {
            RedundantEvent::Member(
                PairsEvent::Joined { node, .. }
                | PairsEvent::Lost { node, .. }
                | PairsEvent::Missing { node, .. },
            )
            | RedundantEvent::Addressed(BoardAddressed { node, .. })
            | RedundantEvent::NotJoined(NotJoined { node, .. }) => Some(*node),
            RedundantEvent::PairRole(r) => r.to.map(|m| match m {
                Member::A => r.nodes[0],
                Member::B => r.nodes[1],
            }),
            RedundantEvent::Master(m) => master_node(&m.kind),
            RedundantEvent::Node(n) => node_node(&n.kind),
            RedundantEvent::Lss(l) => match l.kind {
                LssMasterEventKind::Assigned { node, .. } => Some(node),
                _ => None,
            },
            _ => None,
        }
    }
    /// When it happened (the network's clock).
    #[must_use]
    pub fn at(&self) -> Instant {
        match self {
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
            | RedundantEvent::Master(MasterEvent { at, .. })
            | RedundantEvent::Node(NodeEvent { at, .. })
            | RedundantEvent::NotJoined(NotJoined { at, .. })
            | RedundantEvent::Lss(LssMasterEvent { at, .. }) => *at,
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

/// Whether a report of the master's node reaches the stream (see [the module](self)).
fn shown_node(k: &NodeEventKind) -> bool {
    use NodeEventKind as N;
    match k {
        // duocan's own events, or the master's `SlaveLost`.
        N::BootUp { .. }
        | N::RemoteState { .. }
        | N::Emcy { .. }
        | N::HeartbeatTimeout { .. }
        | N::GuardingTimeout { .. } => false,
        // Once per frame or per cycle.
        N::Sync { .. }
        | N::Time { .. }
        | N::ObjectWritten { .. }
        | N::Malformed { .. }
        | N::Pdo(PdoEvent::RpdoReceived { .. }) => false,
        _ => true,
    }
}

/// Whether a report of the master reaches the stream (see [the module](self)).
fn shown_master(k: &MasterEventKind) -> bool {
    use MasterEventKind as M;
    // The node's and the application's SDO reports come apart (the supervisor splits them);
    // a boot-up and the activation are said by other events; the progress comes per frame.
    !matches!(
        k,
        M::Node(_)
            | M::Sdo(_)
            | M::SlaveBootUp { .. }
            | M::ActiveChanged { .. }
            | M::ProgramProgress { .. }
    )
}

/// The slave a master's report is about, if one.
fn master_node(k: &MasterEventKind) -> Option<NodeId> {
    use MasterEventKind as M;
    match *k {
        M::SlaveBootUp { node }
        | M::IdentityMismatch { node, .. }
        | M::ConfigFailed { node, .. }
        | M::ProgramProgress { node, .. }
        | M::ProgramDownloaded { node, .. }
        | M::ConfigWriteAborted { node, .. }
        | M::SlaveConfigured { node, .. }
        | M::SlaveStarted { node, .. }
        | M::SlaveAdopted { node, .. }
        | M::SlaveLost { node, .. }
        | M::ConsumerNotConfigured { node, .. }
        | M::TooManySlaves { node, .. } => Some(node),
        M::NmtRequest {
            target: duocan::nmt::NmtTarget::Node(node),
            ..
        } => Some(node),
        M::Node(ref n) => node_node(n),
        M::Sdo(ref s) => Some(s.node),
        _ => None,
    }
}

/// The other node a node's report is about, if one (not the master's own node).
fn node_node(k: &NodeEventKind) -> Option<NodeId> {
    use NodeEventKind as N;
    match *k {
        N::BootUp { node }
        | N::RemoteState { node, .. }
        | N::HeartbeatTimeout { node, .. }
        | N::HeartbeatResumed { node }
        | N::GuardingTimeout { node }
        | N::GuardingResumed { node }
        | N::GuardToggleError { node }
        | N::Emcy { node, .. } => Some(node),
        N::NmtObserved { target, .. } => NodeId::new(target),
        _ => None,
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

/// One line, without the time, each event as its layer prints it: `pair 0x10/0x11: B active`,
/// `this master: active`, `node 0x12: not started, error status D: …`, `node 0x12: lost,
/// error status E: heartbeat lost`, `node 0x12: heartbeat back`.
impl fmt::Display for RedundantEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RedundantEvent::PairRole(RoleChange { nodes, to, .. }) => {
                write!(f, "pair {:#04x}/{:#04x}: ", nodes[0].raw(), nodes[1].raw())?;
                match to {
                    Some(m) => write!(f, "{m} active"),
                    None => f.write_str("no member active"),
                }
            }
            RedundantEvent::MasterRole(MasterRoleChange { to, .. }) => {
                write!(f, "this master: {to}")
            }
            RedundantEvent::Link(l) => fmt::Display::fmt(&l.kind, f),
            RedundantEvent::Member(p) => fmt::Display::fmt(p, f),
            RedundantEvent::Flying(e) => fmt::Display::fmt(e, f),
            RedundantEvent::Addressed(b) => b.fmt_untimed(f),
            RedundantEvent::Master(m) => fmt::Display::fmt(&m.kind, f),
            RedundantEvent::Node(n) => fmt::Display::fmt(&n.kind, f),
            RedundantEvent::NotJoined(n) => fmt::Display::fmt(n, f),
            RedundantEvent::Lss(l) => fmt::Display::fmt(&l.kind, f),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::logical::NetworkEvent;
    use crate::supervisor::pairs::PairsEvent;
    use crate::PairId;
    use duocan::master::{BootError, ErrorStatus, IdentityMismatch};
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

    /// The event of the stream a report of the master becomes.
    fn master(kind: MasterEventKind) -> Option<NetEvent> {
        flat(NetworkEventKind::Other(StationEvent::Machine(
            SupervisorEvent::Master(MasterEvent {
                at: Instant::from_millis(7),
                kind,
            }),
        )))
    }

    /// The event of the stream a report of the master's node becomes.
    fn node_report(kind: NodeEventKind) -> Option<NetEvent> {
        flat(NetworkEventKind::Other(StationEvent::Machine(
            SupervisorEvent::Node(NodeEvent {
                at: Instant::from_millis(7),
                kind,
            }),
        )))
    }

    #[test]
    fn a_slave_the_boot_process_refused_or_failed_reaches_the_flat_stream() {
        let node = NodeId::must(0x12);
        let kind = MasterEventKind::IdentityMismatch {
            node,
            mismatch: IdentityMismatch {
                status: ErrorStatus::D,
                index: 0x1018,
                sub: 1,
                expected: 0x1234,
                actual: 0x4321,
            },
        };
        let mismatch = master(kind.clone()).unwrap();
        assert_eq!(mismatch.node(), Some(node));
        assert_eq!(
            mismatch
                .ext::<RedundantEvent>()
                .and_then(RedundantEvent::master),
            Some(&kind)
        );
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

    /// What the master reports beyond failures, dropped before, arrives typed as the master
    /// declares it, with its line: a slave configured and started, a boot failure with its CiA
    /// 302-2 status, a lost slave's heartbeat back, a member refused, an LSS result.
    #[test]
    fn a_slave_configured_started_refused_or_back_and_lss_results_reach_the_flat_stream() {
        use crate::supervisor::JoinRefusal;
        use duocan::cia305::LssOutcome;
        use duocan::master::StartPolicy;
        let (at, node) = (Instant::from_millis(7), NodeId::must(0x12));
        let configured = MasterEventKind::SlaveConfigured {
            node,
            start: StartPolicy::Application,
        };
        let e = master(configured.clone()).unwrap();
        assert_eq!(
            e.ext(),
            Some(&RedundantEvent::Master(MasterEvent {
                at,
                kind: configured
            }))
        );
        assert_eq!(
            e.to_string(),
            "node 0x12: configured, the application starts it"
        );
        assert_eq!((e.node(), e.at()), (Some(node), Some(at)));
        let e = master(MasterEventKind::SlaveStarted {
            node,
            broadcast: false,
        })
        .unwrap();
        assert_eq!(e.to_string(), "node 0x12: started");
        let e = master(MasterEventKind::ConfigFailed {
            node,
            status: ErrorStatus::B,
            reason: BootError::NoSuchPdo { pdo: 600 },
        })
        .unwrap();
        assert!(
            matches!(
                e.ext::<RedundantEvent>().and_then(RedundantEvent::master),
                Some(MasterEventKind::ConfigFailed {
                    status: ErrorStatus::B,
                    ..
                })
            ),
            "{e:?}"
        );
        assert!(
            e.to_string().starts_with(
                "node 0x12: not started, error status B: no answer to the upload of 0x1000"
            ),
            "{e}"
        );

        let e = node_report(NodeEventKind::HeartbeatResumed { node }).unwrap();
        assert_eq!(
            e.ext::<RedundantEvent>()
                .and_then(RedundantEvent::node_event),
            Some(&NodeEventKind::HeartbeatResumed { node })
        );
        assert_eq!(e.to_string(), "node 0x12: heartbeat back");
        assert_eq!(e.node(), Some(node));

        let refused = NotJoined {
            at,
            pair: PairId(0),
            member: Member::B,
            node,
            why: JoinRefusal::Config {
                status: ErrorStatus::J,
                reason: BootError::NoSuchPdo { pdo: 600 },
            },
        };
        let e = flat(NetworkEventKind::Other(StationEvent::Machine(
            SupervisorEvent::NotJoined(refused),
        )))
        .unwrap();
        assert_eq!(e.ext(), Some(&RedundantEvent::NotJoined(refused)));
        assert!(
            e.to_string()
                .starts_with("pair 0 member B (node 0x12): not joined, error status J"),
            "{e}"
        );
        assert_eq!(e.node(), Some(node));

        let lss = LssMasterEvent {
            at,
            kind: LssMasterEventKind::Done(LssOutcome::NodeIdConfigured),
        };
        let e = flat(NetworkEventKind::Other(StationEvent::Machine(
            SupervisorEvent::Lss(lss),
        )))
        .unwrap();
        assert_eq!(e.ext(), Some(&RedundantEvent::Lss(lss)));
        assert_eq!(e.to_string(), "LSS: configure node-ID accepted");
        assert_eq!(e.at(), Some(at));
    }

    /// What another event already says, and what comes once per frame or per cycle, stays off
    /// the stream (the rule of the module's doc); everything else of the node reaches it.
    #[test]
    fn duplicates_and_per_frame_reports_stay_off_the_flat_stream() {
        let node = NodeId::must(0x12);
        for kind in [
            MasterEventKind::SlaveBootUp { node },
            MasterEventKind::ActiveChanged { active: true },
            MasterEventKind::ProgramProgress {
                node,
                done: 7,
                total: 70,
            },
        ] {
            assert_eq!(master(kind.clone()), None, "{kind:?}");
        }
        for kind in [
            NodeEventKind::Sync {
                counter: None,
                produced: true,
            },
            NodeEventKind::ObjectWritten {
                index: 0x1017,
                sub: 0,
                by: duocan::node::Writer::Sdo,
            },
            NodeEventKind::HeartbeatTimeout {
                node,
                last: Instant::ZERO,
            },
        ] {
            assert_eq!(node_report(kind), None, "{kind:?}");
        }
        let e = node_report(NodeEventKind::GuardToggleError { node }).unwrap();
        assert_eq!(
            e.to_string(),
            "node 0x12: guarding toggle bit did not alternate"
        );
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
