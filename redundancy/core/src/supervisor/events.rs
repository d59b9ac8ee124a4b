//! What a [`Supervisor`](super::Supervisor) reports, and why a pair could not be added or a
//! member did not join.

use crate::pair::{Member, PairId};
use crate::supervisor::flying_master::FlyingEvent;
use crate::supervisor::pairs::{PairsError, PairsEvent};
use core::fmt;
use duocan_core::master::{BootError, ErrorStatus, IdentityMismatch, MasterError, MasterEvent};
use duocan_core::sdo::SdoEvent;
use duocan_core::{Instant, NodeEvent, NodeId};

/// Why a pair member did not join.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JoinRefusal {
    /// Its identity is not what 0x1F84–0x1F88 expect: it is left alone (not reset, not
    /// adopted) until it boots again.
    Identity(IdentityMismatch),
    /// A step of its boot process failed. If the member did not answer (or its answer was an
    /// abort of the SDO protocol itself: another client on its channel, a disturbed frame), it
    /// is reset, to boot and be configured again; if it refused (an abort code about the object
    /// or the device, a PDO it will not take), it is left alone like a wrong identity: a reset
    /// would not change its answer.
    Config {
        /// The CiA 302-2 error status (B: no answer, J: a configuration write failed).
        status: ErrorStatus,
        /// Which access failed and how.
        reason: BootError,
    },
    /// The master refused to run its boot process.
    Master(MasterError),
}

impl JoinRefusal {
    /// True if the member did not answer or its transfer was disturbed (worth a reset and
    /// another try); false if it answered and refused, or is another device.
    pub fn is_transient(&self) -> bool {
        use duocan_core::cia302::pdo_config::PdoConfigErrorKind;
        use duocan_core::sdo::SdoErrorKind;
        match self {
            JoinRefusal::Config {
                reason: BootError::Sdo(e),
                ..
            } => match e.kind {
                // An abort of the transfer itself (a toggle bit, an unknown command specifier,
                // a block out of sequence, a timeout at the server) is no answer to the
                // configuration: another client on the same channel (a second master for a
                // moment) or a disturbed frame. The next try is likely to pass.
                SdoErrorKind::Server(code) => is_sdo_protocol(code),
                _ => true,
            },
            JoinRefusal::Config {
                reason: BootError::Pdo(e),
                ..
            } => matches!(e.kind, PdoConfigErrorKind::NoAnswer(_)),
            _ => false,
        }
    }
}

/// True for the abort codes of the SDO protocol itself (CiA 301: toggle bit `0503 0000`, the
/// `0504 xxxx` family), as opposed to the server's answer about the object or the device.
fn is_sdo_protocol(code: duocan_core::AbortCode) -> bool {
    code.0 == 0x0503_0000 || code.0 >> 16 == 0x0504
}

impl fmt::Display for JoinRefusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            JoinRefusal::Identity(m) => {
                write!(f, "{m}; check the board or the expected identity")
            }
            JoinRefusal::Config { status, reason } => write!(f, "{status}: {reason}"),
            JoinRefusal::Master(e) => write!(f, "the master refused its boot process: {e}"),
        }
    }
}

// A refusal is reported in an event, not returned; it is still an error an application may
// pass on with `?` or log with its cause.
impl core::error::Error for JoinRefusal {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            JoinRefusal::Identity(_) => None,
            JoinRefusal::Config { reason, .. } => Some(reason),
            JoinRefusal::Master(e) => Some(e),
        }
    }
}

/// What the supervisor tells the application.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum SupervisorEvent {
    /// From the master's own node (SYNC ticks and local writes are not forwarded; see the
    /// counters).
    Node(NodeEvent),
    /// From the pair supervision.
    Pairs(PairsEvent),
    /// From the flying master (which master of the network is active).
    FlyingMaster(FlyingEvent),
    /// From the CiA 302-2 master: boot-ups, identity checks, configurations, starts, adoptions,
    /// error control losses, request NMT, activation.
    Master(MasterEvent),
    /// The result of an SDO transfer the application started ([`Supervisor::sdo_mut`](super::Supervisor::sdo_mut)).
    Sdo(SdoEvent),
    /// A board without node-ID was given a pair slot's node-ID by LSS (it joins from there).
    Addressed(crate::supervisor::audit::BoardAddressed),
    /// A result of the LSS master (board replacement: identify, fastscan).
    Lss(duocan_core::cia305::LssMasterEvent),
    /// A pair member was refused by the master's boot process and did not join.
    NotJoined(NotJoined),
}

impl SupervisorEvent {
    /// When it happened.
    #[must_use]
    pub fn at(&self) -> Instant {
        match self {
            SupervisorEvent::Node(n) => n.at,
            SupervisorEvent::Pairs(p) => p.at(),
            SupervisorEvent::FlyingMaster(f) => f.at(),
            SupervisorEvent::Master(e) => e.at,
            SupervisorEvent::Sdo(s) => s.at,
            SupervisorEvent::NotJoined(n) => n.at,
            SupervisorEvent::Addressed(b) => b.at,
            SupervisorEvent::Lss(l) => l.at,
        }
    }
}

/// A pair member the master's boot process refused: it did not join
/// ([`SupervisorEvent::NotJoined`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NotJoined {
    /// When.
    pub at: Instant,
    /// The pair.
    pub pair: PairId,
    /// The member.
    pub member: Member,
    /// Its node.
    pub node: NodeId,
    /// Why.
    pub why: JoinRefusal,
}

/// One line, without the time: `pair 0 member B (node 0x50): not joined, error status D: …`.
impl fmt::Display for NotJoined {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "pair {} member {} ({}): not joined, {}",
            self.pair.0, self.member, self.node, self.why
        )
    }
}

/// One line, without the time, each part as its layer prints it.
impl fmt::Display for SupervisorEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SupervisorEvent::Node(e) => fmt::Display::fmt(&e.kind, f),
            SupervisorEvent::Pairs(e) => fmt::Display::fmt(e, f),
            SupervisorEvent::FlyingMaster(e) => fmt::Display::fmt(e, f),
            SupervisorEvent::Master(e) => fmt::Display::fmt(&e.kind, f),
            SupervisorEvent::Sdo(e) => fmt::Display::fmt(e, f),
            SupervisorEvent::Addressed(b) => b.fmt_untimed(f),
            SupervisorEvent::Lss(e) => fmt::Display::fmt(&e.kind, f),
            SupervisorEvent::NotJoined(e) => fmt::Display::fmt(e, f),
        }
    }
}

/// Counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SupervisorStats {
    /// SYNC produced.
    pub sync_produced: u64,
    /// SYNC received.
    pub sync_received: u64,
    /// NMT commands of the pair supervision sent through the master.
    pub nmt_sent: u32,
    /// NMT commands the pair supervision asked for while this master could not command (or
    /// the master's queue was full).
    pub nmt_withheld: u32,
    /// Boot processes of pair members started on the pair supervision's request.
    pub configs: u32,
    /// Frames dropped because the driver did not drain them.
    pub tx_dropped: u32,
    /// Events dropped because the application did not drain them.
    pub events_dropped: u32,
}

/// Why a pair could not be added.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AddPairError {
    /// The pair table refused it.
    Pairs(PairsError),
    /// The master refused a member's slave configuration.
    Master(NodeId, MasterError),
}

impl core::error::Error for AddPairError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            AddPairError::Pairs(e) => Some(e),
            AddPairError::Master(_, e) => Some(e),
        }
    }
}

impl fmt::Display for AddPairError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AddPairError::Pairs(e) => write!(f, "{e}"),
            AddPairError::Master(n, e) => write!(f, "pair member {n}: {e}"),
        }
    }
}

impl From<PairsError> for AddPairError {
    fn from(e: PairsError) -> Self {
        AddPairError::Pairs(e)
    }
}

// The lines are compared as strings, which needs `alloc`.
#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::*;
    use alloc::string::ToString;
    use duocan_core::node::NodeEventKind;

    /// The supervisor's events print one line each, its own as it words them and the lower
    /// layers' as they do.
    #[test]
    fn supervisor_events_print_one_line_each() {
        let (at, node) = (Instant::from_millis(7), NodeId::must(0x50));
        let refused = SupervisorEvent::NotJoined(NotJoined {
            at,
            pair: PairId(1),
            member: Member::A,
            node,
            why: JoinRefusal::Master(MasterError::Busy(node)),
        });
        assert_eq!(
            refused.to_string(),
            "pair 1 member A (node 0x50): not joined, the master refused its boot process: \
             node 0x50 is being booted or updated: wait for the end of that first"
        );
        let back = SupervisorEvent::Node(NodeEvent {
            at,
            kind: NodeEventKind::HeartbeatResumed { node },
        });
        assert_eq!(back.to_string(), "node 0x50: heartbeat back");
    }
}
