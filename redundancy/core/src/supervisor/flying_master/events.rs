//! What the flying master reports: its role ([`MasterRole`]) and each change of it with the
//! reason, a suspension of its commands, and why a command of the application was refused.

use super::frames::Rank;
use super::state::MAX_PEERS;
use core::fmt;
use duocan_core::{Instant, NodeId};

/// Where the device is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterRole {
    /// Not started.
    Off,
    /// Asked for the active master; waiting for an answer.
    Detecting,
    /// Negotiating; announces itself at the end of its wait.
    Negotiating,
    /// The active master.
    Active,
    /// A standby following the active master (if known).
    Standby(Option<Rank>),
}

impl MasterRole {
    /// True when active.
    pub fn is_active(&self) -> bool {
        *self == MasterRole::Active
    }
}

impl fmt::Display for MasterRole {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MasterRole::Off => f.write_str("off"),
            MasterRole::Detecting => f.write_str("detecting"),
            MasterRole::Negotiating => f.write_str("negotiating"),
            MasterRole::Active => f.write_str("active"),
            MasterRole::Standby(Some(r)) => write!(f, "standby (active: {r})"),
            MasterRole::Standby(None) => f.write_str("standby"),
        }
    }
}

/// Why the role changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterReason {
    /// Power-on: started detection.
    PowerOn,
    /// No active master answered: negotiation.
    NoActiveMaster,
    /// A negotiation was requested or forced by another device.
    NegotiationRequested,
    /// Won the negotiation (nobody announced earlier).
    NegotiationWon,
    /// Another device announced itself, or was found, active.
    ActiveMasterFound(Rank),
    /// The active master's heartbeat stopped (its last heartbeat).
    HeartbeatLost {
        /// The lost master.
        master: NodeId,
        /// Its last heartbeat.
        last: Instant,
    },
    /// The active master sent a boot-up: it rebooted and is no longer active.
    MasterRebooted(NodeId),
    /// Two active masters: this one is worse and stepped down.
    ConflictLost(Rank),
    /// Appointed by the active master's hand-over.
    Appointed,
    /// Handed the role over to another master.
    HandedOver(Rank),
    /// The application asked (take over / stand by).
    Manual,
}

impl fmt::Display for MasterReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MasterReason::PowerOn => f.write_str("power-on: active-master detection"),
            MasterReason::NoActiveMaster => f.write_str("no active master answered"),
            MasterReason::NegotiationRequested => f.write_str("negotiation requested"),
            MasterReason::NegotiationWon => f.write_str("won the negotiation"),
            MasterReason::ActiveMasterFound(r) => write!(f, "active master is {r}"),
            MasterReason::HeartbeatLost { master, last } => {
                write!(f, "heartbeat of active master {master} lost (last {last})")
            }
            MasterReason::MasterRebooted(n) => write!(f, "active master {n} rebooted"),
            MasterReason::ConflictLost(r) => {
                write!(f, "two active masters: {r} ranks better")
            }
            MasterReason::Appointed => f.write_str("appointed by the active master's hand-over"),
            MasterReason::HandedOver(r) => write!(f, "handed over to {r}"),
            MasterReason::Manual => f.write_str("commanded by the application"),
        }
    }
}

/// The device's role changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MasterRoleChange {
    /// When (deadline-driven changes: exactly the deadline).
    pub at: Instant,
    /// Before.
    pub from: MasterRole,
    /// After.
    pub to: MasterRole,
    /// Why.
    pub reason: MasterReason,
}

impl fmt::Display for MasterRoleChange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: master {} -> {}: {}",
            self.at, self.from, self.to, self.reason
        )
    }
}

/// What the flying master reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum FlyingEvent {
    /// The role changed.
    Role(MasterRoleChange),
    /// Another active master was suspected; commands are suspended until `until`.
    Suspended {
        /// When.
        at: Instant,
        /// End of the suspension, unless the conflict resolves earlier.
        until: Instant,
    },
}

impl FlyingEvent {
    /// When it happened.
    #[must_use]
    pub fn at(&self) -> Instant {
        match self {
            FlyingEvent::Role(MasterRoleChange { at, .. }) | FlyingEvent::Suspended { at, .. } => {
                *at
            }
        }
    }
}

/// One line, without the time: `this master: active`, `this master: NMT commands suspended
/// until 1.500000s, another active master suspected`.
impl fmt::Display for FlyingEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FlyingEvent::Role(r) => write!(f, "this master: {}", r.to),
            FlyingEvent::Suspended { until, .. } => write!(
                f,
                "this master: NMT commands suspended until {until}, another active master suspected"
            ),
        }
    }
}

/// Why a command of the application was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlyingMasterError {
    /// No live master to hand over to.
    NoSuccessor,
    /// Only an active master can hand over; only a standby can take over.
    WrongRole(MasterRole),
    /// The peer table is full.
    PeersFull,
}

impl core::error::Error for FlyingMasterError {}

impl fmt::Display for FlyingMasterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FlyingMasterError::NoSuccessor => {
                f.write_str("no other master is alive to take over: staying active")
            }
            FlyingMasterError::WrongRole(r) => write!(f, "not possible while {r}"),
            FlyingMasterError::PeersFull => write!(f, "at most {MAX_PEERS} other masters"),
        }
    }
}
