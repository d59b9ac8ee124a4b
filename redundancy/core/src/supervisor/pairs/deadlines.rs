//! The table's timers: every member's deadline (a joined member's silence, a waiting member's
//! adoption or missing report) lives in its phase; a cached lower bound (`next`) spares
//! [`PairSupervisor::handle_timeout`] a scan of the table until something can be due, and the
//! due items are handled in deadline order.

use super::state::{idx, Stage};
use super::trust::bit;
use super::{Authority, LossReason, MemberState, PairId, PairSupervisor, PairsEvent, RoleReason};
use crate::pair::Member;
use duocan_core::frame::instant::{earliest_of, shift_back};
use duocan_core::frame::storage::Storage;
use duocan_core::{Duration, Instant, NmtCommand, NmtState};

impl<S: Storage> PairSupervisor<S> {
    /// Earliest instant at which [`PairSupervisor::handle_timeout`] has work (may be early).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }

    /// Does what is due at `now`: silences, adoptions, missing members, in deadline order.
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.next.is_none_or(|t| t > now) {
            return;
        }
        while let Some((t, p, m)) = self.earliest() {
            if t > now {
                break;
            }
            self.expire(t, p, m);
        }
        self.next = self.earliest().map(|x| x.0);
    }

    /// The caller's clock stepped back `by` (the clock contract, see
    /// [`crate::supervisor`]): every member's last heartbeat, phase start, silence deadline and
    /// adoption instant move back with it, so that no member gains or loses time to run. The
    /// table does not watch the clock itself; its owner tells it.
    pub fn step_back(&mut self, by: Duration) {
        for pair in self.pairs.iter_mut() {
            for s in pair.members.iter_mut() {
                shift_back(&mut s.last, by);
                s.since = s.since - by;
                match &mut s.stage {
                    Stage::Joined { deadline } => *deadline = *deadline - by,
                    Stage::Waiting { adopt_at, .. } => shift_back(adopt_at, by),
                    Stage::Configuring => {}
                }
            }
        }
        // The cached bound moves with the deadlines (it stays as early as it was, so the table
        // wakes when it would have), and takes in a deadline that saturated at the end of time:
        // "never" before, a real one once moved back.
        let moved = self.next.map(|t| t - by);
        self.next = earliest_of([moved, self.earliest().map(|x| x.0)]);
    }

    /// The caller's clock jumped ahead (or its driver stalled): the table was given nothing
    /// between `from` (the latest time it was given) and `to` (the clock contract, see
    /// [`crate::supervisor`]). Whatever fell due in between was not watched: the frames that
    /// would have met it were not seen. Every joined member whose deadline is after `from` is
    /// observed again: its deadline becomes at least `to` + its pair's consumer time, so that it
    /// is judged silent (or not running) only if it stays so for its consumer time after the
    /// jump; a member heard without a boot-up is adopted at the earliest `to` + the hold-off.
    /// What was due by `from` was watched and stays due. Deadlines only move later.
    pub fn jumped(&mut self, from: Instant, to: Instant) {
        let holdoff = self.cfg.holdoff;
        for pair in self.pairs.iter_mut() {
            let consumer = pair.spec.consumer_time;
            for s in pair.members.iter_mut() {
                match &mut s.stage {
                    Stage::Joined { deadline } if *deadline > from => {
                        *deadline = (*deadline).max(to + consumer);
                    }
                    Stage::Waiting {
                        adopt_at: Some(at), ..
                    } if *at > from => *at = (*at).max(to + holdoff),
                    _ => {}
                }
            }
        }
    }

    /// The least slack a member's silence is judged with: its pair's consumer time less its
    /// producer time (the span of missed heartbeats that runs a consumer time out); `None`
    /// without pairs.
    #[must_use]
    pub fn slack(&self) -> Option<Duration> {
        self.pairs
            .iter()
            .map(|p| p.spec.consumer_time - p.spec.producer_time)
            .min()
    }

    /// The longest consumer time of any pair; `None` without pairs.
    #[must_use]
    pub fn longest_consumer(&self) -> Option<Duration> {
        self.pairs.iter().map(|p| p.spec.consumer_time).max()
    }

    /// The earliest due item of any member: (instant, pair, member).
    fn earliest(&self) -> Option<(Instant, usize, Member)> {
        let mut best: Option<(Instant, usize, Member)> = None;
        for (p, pair) in self.pairs.iter().enumerate() {
            for s in &pair.members {
                let mut due = self.due(s);
                if s.member == Member::B {
                    // A B waiting for A runs at the bound (`roles.rs`), before its deadline.
                    due = earliest_of([due, self.wait_for_a_ends(p)]);
                }
                if let Some(t) = due {
                    if best.is_none_or(|b| t < b.0) {
                        best = Some((t, p, s.member));
                    }
                }
            }
        }
        best
    }

    fn due(&self, s: &MemberState) -> Option<Instant> {
        let commanding = self.authority == Authority::Command;
        match s.stage {
            Stage::Joined { deadline } => commanding.then_some(deadline),
            Stage::Waiting { adopt_at, missing } => {
                let adopt = adopt_at.filter(|_| commanding);
                let missing = (!missing && s.last.is_none_or(|l| l < s.since))
                    .then(|| s.since + self.cfg.boot_timeout);
                earliest_of([adopt, missing])
            }
            Stage::Configuring => None,
        }
    }

    fn expire(&mut self, t: Instant, p: usize, m: Member) {
        let s = self.pairs[p].members[idx(m)];
        match s.stage {
            // Alive at the end of its wait for A (only that is due before its deadline): B
            // runs. It becomes active, so the wait ends and the loop moves on.
            Stage::Joined { deadline } if deadline > t && !self.is_suspect(s.node) => {
                self.set_role(t, p, Some(m), RoleReason::FirstJoined)
            }
            Stage::Joined { .. } => self.silent(t, p, m, s),
            Stage::Waiting { adopt_at, .. } => {
                let adopt =
                    adopt_at.is_some_and(|a| a <= t) && self.authority == Authority::Command;
                if adopt && s.nmt == Some(NmtState::Stopped) {
                    // A stopped board answers no SDO: its configuration would only time out
                    // (a board that stopped by itself while a duplicate hid it). Reset: it is
                    // configured at its boot-up, as after any reset.
                    if let Stage::Waiting { adopt_at, .. } = &mut self.pairs[p].member_mut(m).stage
                    {
                        *adopt_at = None;
                    }
                    self.nmt(NmtCommand::ResetNode, s.node);
                } else if adopt {
                    let st = self.pairs[p].member_mut(m);
                    st.stage = Stage::Configuring;
                    st.since = t;
                    self.configure(p, m);
                } else {
                    if let Stage::Waiting { missing, .. } = &mut self.pairs[p].member_mut(m).stage {
                        *missing = true;
                    }
                    self.event(PairsEvent::Missing {
                        at: t,
                        pair: PairId(p as u8),
                        member: m,
                        node: s.node,
                        since: s.since,
                    });
                }
            }
            Stage::Configuring => {}
        }
    }

    /// A joined member's deadline passed at `t`.
    fn silent(&mut self, t: Instant, p: usize, m: Member, s: MemberState) {
        let last = s
            .deadline()
            .map_or(t, |d| d - self.pairs[p].spec.consumer_time);
        let o = m.other();
        let other_alive = self.alive(p, o, t);
        let consumer = self.pairs[p].spec.consumer_time;
        // Heard within the consumer time, but not running: the active member that stopped,
        // or was never heard running after its start (a deadline only operational heartbeats
        // move; see `heartbeat`).
        let stopped = match s.nmt {
            Some(st @ (NmtState::PreOperational | NmtState::Stopped))
                if self.pairs[p].active == Some(m)
                    && !self.is_held(s.node)
                    && s.last.is_some_and(|l| l + consumer > t) =>
            {
                Some(st)
            }
            _ => None,
        };
        let active = self.pairs[p].active == Some(m);
        let node = bit(s.node);
        if stopped.is_some()
            && active
            && !other_alive
            && self.running & node == 0
            && self.restarted & node == 0
            && !self.is_suspect(s.node)
        {
            // Never heard running since its start, alive, and the pair's only hope: started
            // once more rather than reset (its start may have reached it late).
            self.restarted |= node;
            self.nmt(NmtCommand::Start, s.node);
            let deadline = t + consumer + self.behind(t);
            if let Stage::Joined { deadline: d } = &mut self.pairs[p].member_mut(m).stage {
                *d = deadline;
            }
            return self.lower_next(deadline);
        }
        let (why, loss) = if self.is_suspect(s.node) {
            (Some(RoleReason::ActiveSuspect), LossReason::Suspect)
        } else if let Some(state) = stopped {
            (
                Some(RoleReason::ActiveNotOperational { state }),
                LossReason::NotOperational { state },
            )
        } else {
            (None, LossReason::Silent { last })
        };
        if active {
            if other_alive {
                // Start first: the new active is what the reaction bound is about.
                let why = why.unwrap_or(RoleReason::ActiveSilent { last });
                self.set_role(t, p, Some(o), why);
            } else {
                let why = why.unwrap_or(RoleReason::OnlyMemberSilent { last });
                self.set_role(t, p, None, why);
            }
        }
        self.leave(t, p, m, loss);
        if !self.is_duplicated(s.node) {
            self.nmt(NmtCommand::ResetNode, s.node);
        } else if active && other_alive {
            // Its board may run beside the duplicate: one running board per pair.
            self.nmt(NmtCommand::EnterPreOperational, s.node);
        }
        if active && !other_alive {
            self.last_resort(p);
        }
    }

    /// The pair lost its active member and has no other that can run: a member whose
    /// heartbeats a second device shares (so they cannot tell whether it runs) is started, not
    /// made active. Its board may well run; if it does not, the start costs nothing. The member
    /// that becomes active next sends it back to pre-operational (`set_role`).
    pub(super) fn last_resort(&mut self, p: usize) {
        if self.authority != Authority::Command || self.pairs[p].active.is_some() {
            return;
        }
        for m in [Member::A, Member::B] {
            let node = self.pairs[p].spec.node(m);
            if self.is_duplicated(node) && !self.is_held(node) {
                self.nmt(NmtCommand::Start, node);
            }
        }
    }

    pub(super) fn lower_next(&mut self, t: Instant) {
        if self.next.is_none_or(|n| t < n) {
            self.next = Some(t);
        }
    }
}
