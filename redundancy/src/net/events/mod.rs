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
            | RedundantEvent::Addressed(BoardAddressed { at, .. })
            | RedundantEvent::Master(MasterEvent { at, .. })
            | RedundantEvent::Node(NodeEvent { at, .. })
            | RedundantEvent::NotJoined(NotJoined { at, .. })
            | RedundantEvent::Lss(LssMasterEvent { at, .. }) => *at,
            RedundantEvent::Member(e) => e.at(),
            RedundantEvent::Flying(e) => e.at(),
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
mod tests;
