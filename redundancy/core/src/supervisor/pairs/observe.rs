//! What the pair table is told: boot-ups and heartbeats of the members, NMT commands of another
//! master seen on the bus, the end of a configuration (its own, or one seen on the bus), a
//! member found not to be what is expected. Each moves a member's phase and deadline; what
//! follows for the roles is in `roles.rs`.

use super::state::{idx, Stage};
use super::trust::bit;
use super::{Authority, LossReason, PairCommand, PairSupervisor, PairsEvent, Phase, RoleReason};
use crate::pair::Member;
use duocan_core::frame::storage::Storage;
use duocan_core::{Duration, Instant, NmtCommand, NmtState, NodeId};

/// How long the largest receive delay seen is kept before a smaller one replaces it (a lag
/// that ended stops counting within this).
const BEHIND_KEPT: Duration = Duration::from_secs(1);
/// A receive delay this long or longer is no delay but a clock that stepped between the stamp
/// and the hand-over: ignored.
const BEHIND_MAX: Duration = Duration::from_secs(1);

impl<S: Storage> PairSupervisor<S> {
    /// The observations made at `now` come from a frame the bus carried `delay` earlier (its
    /// port's reader runs behind). A member this table starts has its consumer time *plus the
    /// largest such delay of the last second* to be heard running: its first operational
    /// heartbeat reaches the table that much later (a master whose only working bus was handed
    /// over 67 ms late reset each member it started 50 ms after the start, by turns, before its
    /// operational heartbeat arrived). Silences are unaffected: a steady delay shifts every
    /// heartbeat alike.
    pub fn heard_behind(&mut self, now: Instant, delay: Duration) {
        if delay >= BEHIND_MAX {
            return;
        }
        let (max, since) = self.behind;
        if delay >= max || now < since || now.saturating_since(since) >= BEHIND_KEPT {
            self.behind = (delay, now);
        }
    }

    /// How far behind the bus the table's observations come now (see [`Self::heard_behind`]).
    pub(super) fn behind(&self, now: Instant) -> Duration {
        let (max, since) = self.behind;
        if now < since || now.saturating_since(since) >= BEHIND_KEPT {
            Duration::ZERO
        } else {
            max
        }
    }

    /// A node's boot-up message (heartbeat with state initialising) at `now`.
    pub fn boot_up(&mut self, now: Instant, node: NodeId) {
        let Some((pair, m)) = self.locate(node) else {
            return;
        };
        let p = pair.0 as usize;
        if self.is_suspect(node) {
            return; // an implausible error-control frame is no news of the node
        }
        let was = self.pairs[p].members[idx(m)];
        {
            let s = self.pairs[p].member_mut(m);
            s.nmt = Some(NmtState::Initialising);
            s.last = Some(now);
            s.stage = Stage::Configuring;
            s.since = now;
            s.rejected = false;
        }
        if was.joined() {
            self.event(PairsEvent::Lost {
                at: now,
                pair,
                member: m,
                node,
                reason: LossReason::Rebooted,
            });
        }
        self.cmd(PairCommand::Forget { pair, member: m });
        if self.pairs[p].active == Some(m) {
            // Its state is gone: the standby takes over at once if it can.
            let o = m.other();
            let to = self.alive(p, o, now).then_some(o);
            self.set_role(now, p, to, RoleReason::ActiveRebooted);
        }
        if self.authority == Authority::Command {
            self.configure(p, m);
        }
    }

    /// A heartbeat (not a boot-up) of `node` in `state` at `now`.
    pub fn heartbeat(&mut self, now: Instant, node: NodeId, state: NmtState) {
        if state == NmtState::Initialising {
            return self.boot_up(now, node);
        }
        let Some((pair, m)) = self.locate(node) else {
            return;
        };
        let p = pair.0 as usize;
        if self.is_suspect(node) {
            return; // no sign of life: the heartbeat may be an impostor's
        }
        let consumer = self.pairs[p].spec.consumer_time;
        let shadow = self.authority == Authority::Shadow;
        let on_heartbeat = shadow && self.cfg.shadow_join_on_heartbeat;
        let (adopt, holdoff) = (self.cfg.adopt, self.cfg.holdoff);
        let active = self.pairs[p].active == Some(m);
        let operational = state == NmtState::Operational;
        if active && operational {
            self.running |= bit(node);
        }
        // The active member is expected to run unless the application stopped it: a heartbeat
        // saying otherwise is no sign of a working board (see "Not operational").
        let expected = active && self.authority == Authority::Command && !self.is_held(node);
        let failed = expected && !operational && self.running & bit(node) != 0;
        let s = self.pairs[p].member_mut(m);
        let was = s.nmt;
        let first_after_boot = was == Some(NmtState::Initialising);
        s.nmt = Some(state);
        s.last = Some(now);
        let mut join = false;
        let mut adopt_at = None;
        match &mut s.stage {
            Stage::Joined { deadline } => {
                s.heartbeats = s.heartbeats.saturating_add(1);
                if failed {
                    // Due now: handled below as a silence is, in deadline order.
                    *deadline = now;
                } else if operational || !expected {
                    // Deadlines only move later: the cached lower bound stays valid.
                    *deadline = now + consumer;
                }
            }
            // The active master configured it (it beats now): joined as it says.
            Stage::Configuring => join = on_heartbeat && first_after_boot,
            // Heard while following: it is in the active master's network.
            Stage::Waiting { .. } if shadow && !s.rejected => join = true,
            Stage::Waiting { adopt_at: at, .. } => {
                if adopt && !s.rejected && at.is_none() {
                    *at = Some(now + holdoff);
                    adopt_at = *at;
                }
            }
        }
        if join {
            self.join(now, p, m);
        }
        if let Some(t) = adopt_at {
            self.lower_next(t);
        }
        if failed {
            self.lower_next(now);
            self.handle_timeout(now);
            return;
        }
        if self.authority != Authority::Command {
            self.follow_state(now, p, m, state);
        } else {
            // Only a change to operational can be a standby started by someone else.
            if state == NmtState::Operational && was != Some(NmtState::Operational) {
                self.stop_running_standby(now, p, m);
            }
        }
    }

    /// An NMT command seen on the bus (sent by another master). Followed unless commanding (a
    /// commander learns of another commander through the flying master).
    pub fn nmt_observed(&mut self, now: Instant, cmd: NmtCommand, target: u8) {
        if self.authority == Authority::Command {
            return;
        }
        if target == 0 {
            for p in 0..self.pairs.len() {
                for m in [Member::A, Member::B] {
                    self.follow_command(now, p, m, cmd);
                }
            }
            return;
        }
        let Some(node) = NodeId::new(target) else {
            return;
        };
        if let Some((pair, m)) = self.locate(node) {
            self.follow_command(now, pair.0 as usize, m, cmd);
        }
    }

    /// Another master was seen ending the configuration of `node` (its confirmation of the
    /// heartbeat producer time, the last step): a member that booted joins the shadow table.
    /// Ignored when commanding (this master's own configurations report through
    /// [`PairSupervisor::configured`]) and for members not being configured.
    pub fn configuration_observed(&mut self, now: Instant, node: NodeId) {
        if self.authority == Authority::Command {
            return;
        }
        if let Some((p, m)) = self.configuring(node) {
            self.join(now, p, m);
        }
    }

    /// The configuration of `node` finished (`ok`) or failed (it is reset, to boot and be
    /// configured again). Ignored unless `node` is a pair member being configured.
    ///
    /// A member left out as rejected that the master configured after all (its boot process
    /// tried again and passed the checks that had failed) joins too.
    pub fn configured(&mut self, now: Instant, node: NodeId, ok: bool) {
        let Some((p, m)) = self
            .configuring(node)
            .or_else(|| self.rejected_member(node, ok))
        else {
            return;
        };
        self.pairs[p].member_mut(m).rejected = false;
        if ok && self.is_suspect(node) {
            // Configured while its heartbeats are in doubt: it waits, unstarted and not reset,
            // until they are trusted and it is adopted again.
            return self.leave(now, p, m, LossReason::Suspect);
        }
        if ok {
            return self.join(now, p, m);
        }
        self.leave(now, p, m, LossReason::ConfigFailed);
        if self.authority == Authority::Command {
            self.nmt(NmtCommand::ResetNode, node);
        }
    }

    /// `node` is not what the configuration expects (its identity differs, or it refuses its
    /// configuration): it does not join
    /// (a joined one leaves) and is not reset (a reset would not change what it is), nor adopted
    /// when heard; its next boot-up is checked again. Ignored unless `node` is a pair member.
    pub fn rejected(&mut self, now: Instant, node: NodeId) {
        let Some((pair, m)) = self.locate(node) else {
            return;
        };
        let p = pair.0 as usize;
        if self.pairs[p].member(m).phase() != Phase::Waiting {
            self.leave(now, p, m, LossReason::Rejected);
        }
        self.pairs[p].member_mut(m).rejected = true;
    }

    /// True if `node` is a pair member whose configuration was asked for and has not ended.
    pub fn is_configuring(&self, node: NodeId) -> bool {
        self.configuring(node).is_some()
    }

    /// The pair index and member of `node` if it was left out as rejected and is now `ok`.
    fn rejected_member(&self, node: NodeId, ok: bool) -> Option<(usize, Member)> {
        let (pair, m) = self.locate(node)?;
        let p = pair.0 as usize;
        let s = self.pairs[p].member(m);
        (ok && s.rejected && s.phase() == Phase::Waiting).then_some((p, m))
    }

    /// The pair index and member of `node` if it is being configured.
    fn configuring(&self, node: NodeId) -> Option<(usize, Member)> {
        let (pair, m) = self.locate(node)?;
        let p = pair.0 as usize;
        (self.pairs[p].member(m).phase() == Phase::Configuring).then_some((p, m))
    }
}
