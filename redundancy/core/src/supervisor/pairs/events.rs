//! What the pair supervision asks for ([`PairCommand`]) and reports ([`PairsEvent`]), and why.

use crate::pair::{Member, PairId, MAX_PAIRS};
use core::fmt;
use duocan_core::{Duration, Instant, NmtCommand, NmtState, NodeId};

/// What the supervisor asks of the master and the dual-bus layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairCommand {
    /// Send an NMT command to one node.
    Nmt {
        /// The command.
        cmd: NmtCommand,
        /// The node.
        node: NodeId,
    },
    /// Configure a node (at least its heartbeat producer time), then report the result with
    /// [`PairSupervisor::configured`](super::PairSupervisor::configured).
    Configure {
        /// The node.
        node: NodeId,
        /// Heartbeat producer time to write to 0x1017.
        producer_time: Duration,
    },
    /// Tell the dual-bus layer which member's process data to deliver.
    SetActive {
        /// The pair.
        pair: PairId,
        /// The active member.
        member: Option<Member>,
    },
    /// Tell the dual-bus layer to forget a member's latest values (it was reset).
    Forget {
        /// The pair.
        pair: PairId,
        /// The member.
        member: Member,
    },
}

/// Why a pair's active member changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RoleReason {
    /// The first member to run after a start: the first configured, except that B waits up to
    /// the pair's consumer time for A while A is being configured (see the module docs,
    /// "Member A first").
    FirstJoined,
    /// The active member was silent for the consumer time (last heartbeat given).
    ActiveSilent {
        /// Its last heartbeat (or its configuration, if it never beat).
        last: Instant,
    },
    /// The active member booted again (it lost its state).
    ActiveRebooted,
    /// The only joined member was silent.
    OnlyMemberSilent {
        /// Its last heartbeat.
        last: Instant,
    },
    /// The application asked.
    Manual,
    /// Revertive policy: A rejoined and takes the role back.
    Revert,
    /// Followed from the active master's NMT commands or the members' states (shadow).
    Observed,
    /// This master took command and found the pair without an active member.
    Takeover,
    /// The active member was reset or stopped by an NMT command seen on the bus.
    CommandObserved,
    /// The active member's heartbeats became implausible (an impostor on one bus, a babbling
    /// identifier, a duplicate node-ID): handled as if it were silent.
    ActiveSuspect,
    /// The active member reported itself not operational (pre-operational or stopped: its
    /// application or its error behaviour, CiA 301 0x1029, put it there) without a command of
    /// this master: handled as if it were silent.
    ActiveNotOperational {
        /// The state it reported.
        state: NmtState,
    },
}

impl fmt::Display for RoleReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RoleReason::FirstJoined => f.write_str("first member configured"),
            RoleReason::ActiveSilent { last } => {
                write!(f, "active member silent since {last}")
            }
            RoleReason::ActiveRebooted => f.write_str("active member booted again"),
            RoleReason::OnlyMemberSilent { last } => {
                write!(f, "only joined member silent since {last}")
            }
            RoleReason::Manual => f.write_str("manual switch-over"),
            RoleReason::Revert => f.write_str("revertive policy: A rejoined"),
            RoleReason::Observed => f.write_str("observed from the active master"),
            RoleReason::Takeover => f.write_str("new active master: pair had no active member"),
            RoleReason::CommandObserved => f.write_str("NMT command observed"),
            RoleReason::ActiveSuspect => f.write_str(
                "active member's heartbeats implausible (impostor, babbling identifier or duplicate node-ID)",
            ),
            RoleReason::ActiveNotOperational { state } => {
                write!(f, "active member {state} without a command of this master")
            }
        }
    }
}

/// A pair's active member changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RoleChange {
    /// When (for a silence: exactly the deadline).
    pub at: Instant,
    /// The pair.
    pub pair: PairId,
    /// Node-IDs of A and B.
    pub nodes: [NodeId; 2],
    /// Previous active member.
    pub from: Option<Member>,
    /// New active member.
    pub to: Option<Member>,
    /// Why.
    pub reason: RoleReason,
}

impl fmt::Display for RoleChange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let m = |x: Option<Member>| match x {
            Some(Member::A) => "A",
            Some(Member::B) => "B",
            None => "none",
        };
        write!(
            f,
            "{}: pair {} (A {}, B {}) active {} -> {}: {}",
            self.at,
            self.pair.0,
            self.nodes[0],
            self.nodes[1],
            m(self.from),
            m(self.to),
            self.reason
        )
    }
}

/// Why a member left the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LossReason {
    /// Silent for the consumer time; it was reset.
    Silent {
        /// Last heartbeat (or configuration).
        last: Instant,
    },
    /// It booted again.
    Rebooted,
    /// Its configuration failed; it was reset.
    ConfigFailed,
    /// It is not what the configuration expects (identity) or refused its configuration; it
    /// was left alone.
    Rejected,
    /// A reset command for it was seen on the bus (shadow).
    ResetObserved,
    /// Its heartbeats became implausible; it was reset, as a silent member is.
    Suspect,
    /// It was the active member and reported itself not operational without a command of this
    /// master; it was reset, as a silent member is.
    NotOperational {
        /// The state it reported.
        state: NmtState,
    },
}

/// Why, in words: "silent since 1.250000s", "rebooted", …
impl fmt::Display for LossReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LossReason::Silent { last } => write!(f, "silent since {last}, reset"),
            LossReason::Rebooted => f.write_str("it booted again"),
            LossReason::ConfigFailed => f.write_str("its configuration failed, reset"),
            LossReason::Rejected => f.write_str("rejected (identity or configuration), left alone"),
            LossReason::ResetObserved => f.write_str("a reset command for it was seen on the bus"),
            LossReason::Suspect => f.write_str("its heartbeats became implausible, reset"),
            LossReason::NotOperational { state } => {
                write!(f, "it reported {state} without a command, reset")
            }
        }
    }
}

/// What the pair supervisor reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum PairsEvent {
    /// A pair's active member changed.
    Role(RoleChange),
    /// A member joined (configured).
    Joined {
        /// When.
        at: Instant,
        /// The pair.
        pair: PairId,
        /// The member.
        member: Member,
        /// Its node.
        node: NodeId,
    },
    /// A member is no longer joined.
    Lost {
        /// When (for a silence: the deadline).
        at: Instant,
        /// The pair.
        pair: PairId,
        /// The member.
        member: Member,
        /// Its node.
        node: NodeId,
        /// Why.
        reason: LossReason,
    },
    /// A configured member was not heard within the boot timeout.
    Missing {
        /// When.
        at: Instant,
        /// The pair.
        pair: PairId,
        /// The member.
        member: Member,
        /// Its node.
        node: NodeId,
        /// Since when it has been awaited.
        since: Instant,
    },
}

impl PairsEvent {
    /// When it happened (for a silent member, its deadline).
    #[must_use]
    pub fn at(&self) -> Instant {
        match self {
            PairsEvent::Role(RoleChange { at, .. })
            | PairsEvent::Joined { at, .. }
            | PairsEvent::Lost { at, .. }
            | PairsEvent::Missing { at, .. } => *at,
        }
    }
}

/// One line, without the time: `pair 0 member B (node 0x50): joined`, `pair 0: A active`.
impl fmt::Display for PairsEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PairsEvent::Role(r) => match r.to {
                Some(m) => write!(f, "pair {}: {m} active", r.pair.0),
                None => write!(f, "pair {}: no member active", r.pair.0),
            },
            PairsEvent::Joined {
                pair, member, node, ..
            } => write!(f, "pair {} member {member} ({node}): joined", pair.0),
            PairsEvent::Lost {
                pair,
                member,
                node,
                reason,
                ..
            } => write!(
                f,
                "pair {} member {member} ({node}): lost, {reason}",
                pair.0
            ),
            PairsEvent::Missing {
                pair, member, node, ..
            } => write!(f, "pair {} member {member} ({node}): not heard", pair.0),
        }
    }
}

/// Why a pair could not be added or a command was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PairsError {
    /// The table holds [`MAX_PAIRS`] pairs already.
    Full,
    /// The node belongs to a pair already.
    NodeTaken(NodeId),
    /// A and B are the same node.
    SameNode(NodeId),
    /// No such pair.
    NoPair(PairId),
    /// The member to switch to is not joined and alive.
    NotAlive(PairId, Member),
    /// This supervisor follows another master and commands nothing.
    Shadow,
}

impl core::error::Error for PairsError {}

impl fmt::Display for PairsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PairsError::Full => write!(f, "pair table full ({MAX_PAIRS} pairs)"),
            PairsError::NodeTaken(n) => write!(f, "{n} already belongs to a pair"),
            PairsError::SameNode(n) => write!(f, "A and B are both {n}"),
            PairsError::NoPair(p) => write!(f, "no pair {}", p.0),
            PairsError::NotAlive(p, m) => write!(
                f,
                "pair {} member {m} is not joined and alive: cannot make it active",
                p.0
            ),
            PairsError::Shadow => f.write_str(
                "this master is standby: switch-overs are commanded by the active master",
            ),
        }
    }
}
