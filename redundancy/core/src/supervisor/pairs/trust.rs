//! What the table believes of its members' heartbeats: the dual-bus layer's verdicts (an
//! impostor, a babbling identifier, a duplicate node-ID), and who may have started a standby.

use super::state::Stage;
use super::{Member, PairSupervisor};
use duocan_core::frame::storage::Storage;
use duocan_core::{Instant, NmtCommand, NodeId};

/// The bit of `node` in a node-ID set.
pub(super) const fn bit(node: NodeId) -> u128 {
    1 << node.raw()
}

impl<S: Storage> PairSupervisor<S> {
    /// The application sent `cmd` to `target` (0: all nodes) through this table's master: a
    /// standby it starts may run beside the active member (a test, a comparison of both); any
    /// other command to it, or one of this table's own, ends that. An active member it sends to
    /// pre-operational or stopped is left so, still active ([`PairSupervisor::is_held`]), until
    /// it or this table starts it again.
    pub fn application_nmt(&mut self, cmd: NmtCommand, target: u8) {
        let targets = match NodeId::new(target) {
            Some(n) => bit(n),
            None => u128::MAX,
        };
        match cmd {
            NmtCommand::Start => {
                self.by_application |= targets;
                self.held &= !targets;
            }
            NmtCommand::Stop | NmtCommand::EnterPreOperational => {
                self.by_application &= !targets;
                self.held |= targets;
            }
            // A reset ends in a boot-up: the member is joined and decided on afresh.
            NmtCommand::ResetNode | NmtCommand::ResetCommunication => {
                self.by_application &= !targets;
                self.held &= !targets;
            }
        }
    }

    /// Whether the application sent `node` to pre-operational or stopped through this table's
    /// master ([`PairSupervisor::application_nmt`]) and nothing started it since: an active
    /// member not running is then what was asked for, no failure.
    pub fn is_held(&self, node: NodeId) -> bool {
        self.held & bit(node) != 0
    }

    /// Whether the dual-bus layer finds `node`'s heartbeats implausible
    /// ([`PairSupervisor::suspect`]).
    pub fn is_suspect(&self, node: NodeId) -> bool {
        self.suspect & bit(node) != 0
    }

    /// Whether `node` is suspect because a second device shares its heartbeats on both buses
    /// ([`PairSupervisor::suspect`]'s `duplicated`).
    pub fn is_duplicated(&self, node: NodeId) -> bool {
        self.duplicated & bit(node) != 0
    }

    /// Member `m` of pair `p` is joined, not silent at `now` and trusted: one that can run.
    pub(super) fn alive(&self, p: usize, m: Member, now: Instant) -> bool {
        let s = self.pairs[p].member(m);
        s.alive_at(now) && !self.is_suspect(s.node)
    }

    /// The dual-bus layer judged `node`'s heartbeats implausible (`suspect`: an impostor on one
    /// bus, a babbling identifier, a duplicate node-ID) or plausible again. While suspect, its
    /// heartbeats and boot-ups are no sign of life and it is not adopted; a joined member is
    /// handled at once as if its consumer time had run out (commanding: an active member is
    /// replaced by a live standby, the member is reset). `duplicated` (too fast on both buses:
    /// a second device shares its heartbeat, its own board may run) spares it the reset: see
    /// "Heartbeats that lie" in the [module docs](super). Ignored unless `node` is a pair
    /// member.
    pub fn suspect(&mut self, now: Instant, node: NodeId, suspect: bool, duplicated: bool) {
        let Some((pair, m)) = self.locate(node) else {
            return;
        };
        if self.is_suspect(node) == suspect {
            return;
        }
        self.suspect ^= bit(node);
        self.duplicated &= !bit(node);
        if !suspect {
            return;
        }
        if duplicated {
            self.duplicated |= bit(node);
        }
        let stage = &mut self.pairs[pair.0 as usize].member_mut(m).stage;
        let joined = matches!(stage, Stage::Joined { .. });
        match stage {
            Stage::Joined { deadline } => *deadline = (*deadline).min(now),
            // Not adopted on an impostor's word.
            Stage::Waiting { adopt_at, .. } => *adopt_at = None,
            Stage::Configuring => {}
        }
        self.lower_next(now);
        self.handle_timeout(now);
        // A member found duplicated after it left (trusted meanwhile, the duplicate still
        // beating: a bus cut took its verdict away) while its pair has no active member and
        // the other cannot run: the last resort, as at its loss (its board was sent to
        // pre-operational when the other member took over, and that one died since). A joined
        // one had it from its deadline, just run.
        let p = pair.0 as usize;
        if m == Member::A {
            // Not waited for while in doubt: a B waiting for it runs now.
            self.end_wait_for_a(now, p);
        }
        if duplicated && !joined && !self.alive(p, m.other(), now) {
            self.last_resort(p);
        }
    }

    /// Commanding: a joined standby heard becoming operational (the caller sees the change;
    /// a heartbeat of the active member just switched over may still say operational) while
    /// the active member is alive was started by someone else (a rogue NMT start): back to
    /// pre-operational at once, unless the application started it
    /// ([`PairSupervisor::application_nmt`]).
    pub(super) fn stop_running_standby(&mut self, now: Instant, p: usize, m: Member) {
        let pair = &self.pairs[p];
        let Some(a) = pair.active.filter(|a| *a != m) else {
            return;
        };
        let s = pair.member(m);
        let node = s.node;
        let by_application = self.by_application & bit(node) != 0;
        if !s.joined() || by_application || !self.alive(p, a, now) {
            return;
        }
        self.nmt(NmtCommand::EnterPreOperational, node);
    }
}
