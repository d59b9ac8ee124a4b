//! What the logical network reports: [`NetworkEvent`], one typed stream made of the station's
//! events (the ones the application reacts to typed, everything else as the station said it).

use crate::link::events::{LinkEvent, LinkEventKind, PortReason};
use crate::link::health::PortState;
use crate::pair::PairId;
use crate::supervisor::flying_master::{FlyingEvent, MasterRoleChange};
use crate::supervisor::pairs::{PairsEvent, RoleChange};
use crate::supervisor::SupervisorEvent;
use duocan::emcy::EmcyMessage;
use duocan::machine::StationEvent;
use duocan::master::{ErrorStatus, MasterEventKind};
use duocan::node::NodeEventKind;
use duocan::pdo::PdoEvent;
use duocan::sdo::SdoEvent;
use duocan::{Frame, Instant, NmtState, NodeId};

/// Something that happened on the network, and when.
#[derive(Clone, Debug, PartialEq)]
pub struct NetworkEvent {
    /// When (for timeouts: exactly the deadline).
    pub at: Instant,
    /// What.
    pub kind: NetworkEventKind,
}

/// The kinds of [`NetworkEvent`]: the typed ones the application reacts to, and everything else
/// as the station reported it.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum NetworkEventKind {
    /// A port (one bus) changed health state.
    Port {
        /// 0 = bus 1.
        port: u8,
        /// Before.
        from: PortState,
        /// After.
        to: PortState,
        /// Why.
        reason: PortReason,
    },
    /// The buses a node is heard on changed (heard on one bus only is a fault to report).
    Reach {
        /// The node.
        node: NodeId,
        /// Heard on bus 1, on bus 2.
        heard: [bool; 2],
    },
    /// A node sent its boot-up.
    NodeBooted {
        /// The node.
        node: NodeId,
    },
    /// A node's NMT state changed (from its heartbeat or guarding answer).
    NodeState {
        /// The node.
        node: NodeId,
        /// Known before, if anything.
        from: Option<NmtState>,
        /// Now.
        to: NmtState,
    },
    /// Error control lost a slave: heartbeat (E), guarding (F), none after configuration (K).
    NodeLost {
        /// The slave.
        node: NodeId,
        /// E, F or K.
        status: ErrorStatus,
    },
    /// A pair's active member changed (reason and members inside).
    PairRole(RoleChange),
    /// This master's role changed.
    MasterRole(MasterRoleChange),
    /// An EMCY message of a node.
    Emcy {
        /// The node.
        node: NodeId,
        /// The message.
        msg: EmcyMessage,
    },
    /// A and B of a pair have carried different values of one function for longer than the
    /// discrepancy time (the event's time is when it ran out).
    Discrepancy {
        /// The pair.
        pair: PairId,
        /// The function (e.g. the TPDO number).
        function: u32,
        /// A's latest frame.
        a: Frame,
        /// B's latest frame.
        b: Frame,
    },
    /// A and B agree again.
    DiscrepancyCleared {
        /// The pair.
        pair: PairId,
        /// The function.
        function: u32,
    },
    /// One of the master's RPDOs was received: its values are in the dictionary
    /// ([`LogicalNetwork::pdo_value`](super::LogicalNetwork::pdo_value)).
    PdoReceived {
        /// The master's RPDO number.
        pdo: u16,
    },
    /// An SDO transfer the application started ended (its [`RequestId`](duocan::sdo::RequestId) inside).
    Sdo(SdoEvent),
    /// Anything else (member joined or lost, boot process steps, channel switches, …).
    Other(StationEvent<LinkEvent, SupervisorEvent>),
}

/// When a station event happened.
pub(super) fn when(e: &StationEvent<LinkEvent, SupervisorEvent>) -> Instant {
    match e {
        StationEvent::Link(l) => l.at,
        StationEvent::Machine(m) => m.at(),
    }
}

/// The typed kind of a station event, if it has one.
pub(crate) fn typed(e: &StationEvent<LinkEvent, SupervisorEvent>) -> Option<NetworkEventKind> {
    use NetworkEventKind as K;
    Some(match e {
        StationEvent::Link(l) => match l.kind {
            LinkEventKind::Port {
                port,
                from,
                to,
                reason,
            } => K::Port {
                port,
                from,
                to,
                reason,
            },
            LinkEventKind::Reach { node, heard } => K::Reach { node, heard },
            LinkEventKind::Discrepancy {
                pair,
                function,
                a,
                b,
            } => K::Discrepancy {
                pair,
                function,
                a,
                b,
            },
            LinkEventKind::DiscrepancyCleared { pair, function } => {
                K::DiscrepancyCleared { pair, function }
            }
            _ => return None,
        },
        StationEvent::Machine(m) => match m {
            SupervisorEvent::Node(n) => match n.kind {
                NodeEventKind::BootUp { node } => K::NodeBooted { node },
                NodeEventKind::RemoteState { node, from, to } => K::NodeState { node, from, to },
                NodeEventKind::Emcy { node, msg } => K::Emcy { node, msg },
                NodeEventKind::Pdo(PdoEvent::RpdoReceived { pdo }) => K::PdoReceived { pdo },
                _ => return None,
            },
            SupervisorEvent::Pairs(PairsEvent::Role(r)) => K::PairRole(*r),
            SupervisorEvent::FlyingMaster(FlyingEvent::Role(r)) => K::MasterRole(*r),
            SupervisorEvent::Master(e) => match e.kind {
                MasterEventKind::SlaveLost { node, status } => K::NodeLost { node, status },
                _ => return None,
            },
            SupervisorEvent::Sdo(s) => K::Sdo(s.clone()),
            _ => return None,
        },
    })
}
