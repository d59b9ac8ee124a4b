//! How members join and leave a pair and which one is active: joining after a configuration,
//! leaving on a reset or a failure, the start of a new active member (first, so that it is on
//! the bus at once), the wait for member A at a cold start, planned switches, and, for a table
//! that follows another master, the roles read off what that master commands and what the
//! members report.

use super::state::Phase;
use super::trust::bit;
use super::{
    Authority, LossReason, PairCommand, PairId, PairSupervisor, PairsEvent, RoleChange, RoleReason,
    Stage,
};
use crate::pair::Member;
use duocan_core::frame::storage::Storage;
use duocan_core::{Instant, NmtCommand, NmtState};

impl<S: Storage> PairSupervisor<S> {
    pub(super) fn join(&mut self, now: Instant, p: usize, m: Member) {
        let spec = self.pairs[p].spec;
        let suspect = self.is_suspect(spec.node(m));
        let s = self.pairs[p].member_mut(m);
        // Monitoring starts now, whether or not it ever beats; a suspect member is due at once.
        let deadline = if suspect {
            now
        } else {
            s.last.map_or(now, |l| l.max(now)) + spec.consumer_time
        };
        s.stage = Stage::Joined { deadline };
        s.since = now;
        s.heartbeats = 0;
        let (nmt, node) = (s.nmt, s.node);
        self.lower_next(deadline);
        self.event(PairsEvent::Joined {
            at: now,
            pair: PairId(p as u8),
            member: m,
            node,
        });
        if self.authority != Authority::Command {
            if nmt == Some(NmtState::Operational) && self.pairs[p].active.is_none() {
                self.set_role(now, p, Some(m), RoleReason::Observed);
            }
            return;
        }
        match self.pairs[p].active {
            // B ready while A is still being configured: A is the board the plant expects to
            // run, so B waits for it, within the bound (see "Member A first" in the module docs).
            None if m == Member::B && self.awaits_a(p) => {
                self.lower_next(now + spec.consumer_time);
            }
            None => {
                self.set_role(now, p, Some(m), RoleReason::FirstJoined);
            }
            Some(a) if a != m => {
                if self.cfg.revertive && m == Member::A {
                    self.planned_switch(now, p, m, RoleReason::Revert);
                } else if nmt == Some(NmtState::Operational) {
                    // Adopted while running (started by another master): back to standby.
                    self.nmt(NmtCommand::EnterPreOperational, node);
                }
            }
            Some(_) => {}
        }
    }

    /// A joined or configuring member leaves the table (reset, rebooted, failed configuration).
    pub(super) fn leave(&mut self, t: Instant, p: usize, m: Member, reason: LossReason) {
        let pair = PairId(p as u8);
        let s = self.pairs[p].member_mut(m);
        let was_joined = s.joined();
        let was_configuring = s.phase() == Phase::Configuring;
        s.stage = Stage::WAITING;
        s.since = t;
        let node = s.node;
        if self.pairs[p].active == Some(m) {
            self.set_role(t, p, None, RoleReason::CommandObserved);
        }
        if was_joined || matches!(reason, LossReason::ConfigFailed | LossReason::Rejected) {
            self.event(PairsEvent::Lost {
                at: t,
                pair,
                member: m,
                node,
                reason,
            });
        }
        self.cmd(PairCommand::Forget { pair, member: m });
        self.lower_next(t + self.cfg.boot_timeout);
        if m == Member::A && was_configuring {
            // A B waiting for A's configuration runs now that it failed.
            self.end_wait_for_a(t, p);
        }
    }

    /// Whether the pair's B, joined, waits for A before it is started: commanding, no member
    /// active, A being configured (its boot-up or adoption seen) and trusted.
    pub(super) fn awaits_a(&self, p: usize) -> bool {
        let pair = &self.pairs[p];
        let a = pair.member(Member::A);
        self.authority == Authority::Command
            && pair.active.is_none()
            && pair.member(Member::B).joined()
            && a.phase() == Phase::Configuring
            && !self.is_suspect(a.node)
    }

    /// The instant a waiting B runs at the latest: its configuration + the pair's consumer
    /// time; `None` unless it waits ([`Self::awaits_a`]).
    pub(super) fn wait_for_a_ends(&self, p: usize) -> Option<Instant> {
        let pair = &self.pairs[p];
        self.awaits_a(p)
            .then(|| pair.member(Member::B).since + pair.spec.consumer_time)
    }

    /// A no longer keeps B waiting (its configuration failed, its heartbeats are in doubt):
    /// a live B runs now, not at the bound.
    pub(super) fn end_wait_for_a(&mut self, now: Instant, p: usize) {
        if self.authority == Authority::Command && !self.awaits_a(p) {
            self.ensure_active(now, p, RoleReason::FirstJoined);
        }
    }

    /// Makes `to` active, starting it (commanding), and reports the change.
    pub(super) fn set_role(
        &mut self,
        t: Instant,
        p: usize,
        to: Option<Member>,
        reason: RoleReason,
    ) {
        let from = self.pairs[p].active;
        if from == to {
            return;
        }
        self.pairs[p].active = to;
        let spec = self.pairs[p].spec;
        if let Some(m) = from {
            self.running &= !bit(spec.node(m));
        }
        if let Some(m) = to {
            // Running it is this table's decision from now on.
            let node = spec.node(m);
            self.by_application &= !bit(node);
            self.held &= !bit(node);
            self.restarted &= !bit(node);
            // Commanding, running from its first operational heartbeat after its start on: until
            // then a heartbeat in flight may still say pre-operational. Started even when heard
            // running (adopted operational, followed from its heartbeat): a start is harmless
            // to a running board, and the heartbeat that said so may be a second device's with
            // its node-ID, not yet found out, while the board itself booted pre-operational.
            if self.authority == Authority::Command && !self.is_suspect(node) {
                // A suspect one is not started: the same instant's timeout replaces it (a
                // start would wake a board the table is about to reset). Started, it has the
                // consumer time from now to be heard running, and as long again as the bus
                // reaches this table late.
                self.nmt(NmtCommand::Start, node);
                let consumer = spec.consumer_time + self.behind(t);
                if let Stage::Joined { deadline } = &mut self.pairs[p].member_mut(m).stage {
                    *deadline = (*deadline).max(t + consumer);
                }
            } else if self.pairs[p].member(m).nmt == Some(NmtState::Operational) {
                // Followed, not commanded: heard running, it is expected to go on.
                self.running |= bit(node);
            }
        }
        if let Some(m) = to.filter(|_| self.authority == Authority::Command) {
            // A member left as it was while another device shared its heartbeats may still
            // run: one running board per pair.
            let other = self.pairs[p].member(m.other());
            if self.is_duplicated(other.node) && !other.joined() {
                self.nmt(NmtCommand::EnterPreOperational, other.node);
            }
        }
        let pair = PairId(p as u8);
        self.cmd(PairCommand::SetActive { pair, member: to });
        self.event(PairsEvent::Role(RoleChange {
            at: t,
            pair,
            nodes: [spec.a, spec.b],
            from,
            to,
            reason,
        }));
    }

    /// A switch between two live members: the new one started, the old one to pre-operational.
    pub(super) fn planned_switch(
        &mut self,
        now: Instant,
        p: usize,
        to: Member,
        reason: RoleReason,
    ) {
        let old = self.pairs[p].active;
        self.set_role(now, p, Some(to), reason);
        if let Some(o) = old.filter(|o| *o != to) {
            let node = self.pairs[p].spec.node(o);
            self.nmt(NmtCommand::EnterPreOperational, node);
        }
    }

    /// A pair without an active member but with a live joined member gets one.
    pub(super) fn ensure_active(&mut self, now: Instant, p: usize, reason: RoleReason) {
        if self.pairs[p].active.is_some() {
            return;
        }
        let pick = [Member::A, Member::B]
            .into_iter()
            .filter(|m| self.alive(p, *m, now))
            // An operational member keeps running rather than being replaced.
            .max_by_key(|m| {
                (
                    self.pairs[p].member(*m).nmt == Some(NmtState::Operational),
                    *m == Member::A,
                )
            });
        if let Some(m) = pick {
            self.set_role(now, p, Some(m), reason);
        }
    }

    /// Shadow: a member's reported state moves the roles.
    pub(super) fn follow_state(&mut self, now: Instant, p: usize, m: Member, state: NmtState) {
        if !self.pairs[p].member(m).joined() {
            return;
        }
        let active = self.pairs[p].active;
        match state {
            NmtState::Operational if active.is_none() => {
                self.set_role(now, p, Some(m), RoleReason::Observed)
            }
            NmtState::PreOperational | NmtState::Stopped if active == Some(m) => {
                let o = m.other();
                let other_op = self.pairs[p].member(o).joined()
                    && self.pairs[p].member(o).nmt == Some(NmtState::Operational);
                self.set_role(now, p, other_op.then_some(o), RoleReason::Observed)
            }
            _ => {}
        }
    }

    /// Shadow: an NMT command of the active master moves the table.
    pub(super) fn follow_command(&mut self, now: Instant, p: usize, m: Member, cmd: NmtCommand) {
        match cmd {
            NmtCommand::Start => {
                if !self.pairs[p].member(m).joined() {
                    self.join(now, p, m);
                }
                // The role first: the member is heard running at its next heartbeat, not
                // at the command.
                self.set_role(now, p, Some(m), RoleReason::Observed);
                self.pairs[p].member_mut(m).nmt = Some(NmtState::Operational);
            }
            NmtCommand::EnterPreOperational | NmtCommand::Stop => {
                self.pairs[p].member_mut(m).nmt = Some(cmd.resulting_state());
                if self.pairs[p].active == Some(m) {
                    self.set_role(now, p, None, RoleReason::CommandObserved);
                }
            }
            NmtCommand::ResetNode | NmtCommand::ResetCommunication => {
                let s = self.pairs[p].member(m);
                if s.phase() != Phase::Waiting {
                    self.leave(now, p, m, LossReason::ResetObserved);
                }
            }
        }
    }
}
