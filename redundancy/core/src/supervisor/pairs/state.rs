//! A pair's state as the supervision sees it: who commands ([`Authority`]), each member's life
//! cycle ([`Phase`], with the data of each phase kept inside it) and the pair's active member.

use crate::pair::{Member, PairSpec};
use core::fmt;
use duocan_core::{Instant, NmtState, NodeId};

/// Whether the table commands or follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Authority {
    /// Evaluates and sends commands (the active master).
    Command,
    /// Follows what is observed of an active master; sends nothing (a standby master).
    Shadow,
    /// No active master is known (power-on detection and negotiation): records what it hears
    /// and what commands it sees, takes nobody's word for a configuration, sends nothing. What
    /// booted or was heard meanwhile is configured once this master commands.
    Idle,
}

/// Where a member is in its life cycle, as the supervisor sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Not joined: waiting for its boot-up (never heard, or reset).
    Waiting,
    /// Boot-up (or adoption) seen; its configuration is running.
    Configuring,
    /// Configured and monitored.
    Joined,
}

impl fmt::Display for Phase {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Phase::Waiting => "waiting",
            Phase::Configuring => "configuring",
            Phase::Joined => "joined",
        })
    }
}

/// A member's phase with what only that phase knows: a waiting member has no silence deadline,
/// a joined one is never adopted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Stage {
    /// Not joined.
    Waiting {
        /// Heard without a boot-up: adopted at this instant.
        adopt_at: Option<Instant>,
        /// Reported missing during this wait.
        missing: bool,
    },
    /// Its configuration is running.
    Configuring,
    /// Configured and monitored.
    Joined {
        /// Its heartbeat is due at the latest at this instant.
        deadline: Instant,
    },
}

impl Stage {
    /// A fresh wait: not heard, not reported.
    pub(super) const WAITING: Stage = Stage::Waiting {
        adopt_at: None,
        missing: false,
    };
}

/// One member of a pair in the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemberState {
    /// A or B.
    pub member: Member,
    /// Its node-ID.
    pub node: NodeId,
    /// Last NMT state heard (boot-up, heartbeat).
    pub nmt: Option<NmtState>,
    /// Heartbeats received since it joined.
    pub heartbeats: u32,
    /// Last heartbeat (or boot-up).
    pub last: Option<Instant>,
    /// When the current phase began.
    pub since: Instant,
    /// Life cycle, with the data of its phase.
    pub(super) stage: Stage,
    /// Found not to be what the configuration expects; not adopted until it boots again. Not
    /// part of the phase: only a boot-up, or a configuration that passes after all, clears it.
    pub(super) rejected: bool,
}

impl MemberState {
    pub(super) fn new(member: Member, node: NodeId, now: Instant) -> Self {
        MemberState {
            member,
            node,
            nmt: None,
            heartbeats: 0,
            last: None,
            since: now,
            stage: Stage::WAITING,
            rejected: false,
        }
    }
    /// Life cycle.
    pub fn phase(&self) -> Phase {
        match self.stage {
            Stage::Waiting { .. } => Phase::Waiting,
            Stage::Configuring => Phase::Configuring,
            Stage::Joined { .. } => Phase::Joined,
        }
    }
    /// Reported missing during the current wait.
    pub fn missing(&self) -> bool {
        matches!(self.stage, Stage::Waiting { missing: true, .. })
    }
    /// True if joined.
    pub fn joined(&self) -> bool {
        matches!(self.stage, Stage::Joined { .. })
    }
    /// The instant its heartbeat is next due at the latest (joined members).
    pub fn deadline(&self) -> Option<Instant> {
        match self.stage {
            Stage::Joined { deadline } => Some(deadline),
            _ => None,
        }
    }
    /// Joined and not silent at `now`.
    pub fn alive_at(&self, now: Instant) -> bool {
        self.deadline().is_some_and(|d| d > now)
    }
    /// Its identity is not what the configuration expects: left out until it boots again.
    pub fn is_rejected(&self) -> bool {
        self.rejected
    }
}

/// One pair in the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairState {
    /// Its configuration.
    pub spec: PairSpec,
    /// The active member, if any.
    pub active: Option<Member>,
    /// A and B.
    pub members: [MemberState; 2],
}

impl PairState {
    /// A member's state.
    pub fn member(&self, m: Member) -> &MemberState {
        &self.members[idx(m)]
    }
    pub(super) fn member_mut(&mut self, m: Member) -> &mut MemberState {
        &mut self.members[idx(m)]
    }
}

pub(super) const fn idx(m: Member) -> usize {
    match m {
        Member::A => 0,
        Member::B => 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_member_carries_only_the_data_of_its_phase() {
        let mut s = MemberState::new(Member::A, NodeId::must(5), Instant::ZERO);
        assert_eq!(
            (s.phase(), s.deadline(), s.missing()),
            (Phase::Waiting, None, false)
        );
        s.stage = Stage::Waiting {
            adopt_at: Some(Instant::from_millis(1)),
            missing: true,
        };
        assert_eq!(
            (s.phase(), s.deadline(), s.missing()),
            (Phase::Waiting, None, true)
        );
        s.stage = Stage::Joined {
            deadline: Instant::from_millis(10),
        };
        assert_eq!(s.phase(), Phase::Joined);
        assert!(!s.missing());
        assert_eq!(s.deadline(), Some(Instant::from_millis(10)));
        assert!(s.alive_at(Instant::from_millis(9)) && !s.alive_at(Instant::from_millis(10)));
        s.stage = Stage::Configuring;
        assert_eq!((s.phase(), s.deadline()), (Phase::Configuring, None));
        assert!(!s.alive_at(Instant::ZERO));
    }
}
