//! Slave-pair supervision: a heartbeat table of redundant slave pairs, event-driven and exact.
//!
//! [`PairSupervisor`] is a sans-IO machine. Its inputs are observations — a member's boot-up or
//! heartbeat at an instant, the result of its configuration, an NMT command seen on the bus —
//! and time. Its outputs are [`PairCommand`]s (NMT start / reset / enter pre-operational of a
//! node, configure a node, tell the dual-bus layer which member is active) and [`PairsEvent`]s
//! (role changes with pair, members, reason and time; members joining, lost, missing).
//!
//! # Rules
//!
//! - **Joining.** A member's boot-up asks for its configuration ([`PairCommand::Configure`]:
//!   the CiA 302-2 boot process of the master, identity check, configuration, at least 0x1017);
//!   when [`PairSupervisor::configured`] reports success it is *joined*. The first member of a
//!   pair to be configured becomes active and is started; the other stays pre-operational as
//!   standby. A first start and a rejoin after a fault look the same. A failed configuration
//!   resets the member (it boots and is configured again); a member that is not what the
//!   configuration expects ([`PairSupervisor::rejected`]: wrong identity) is left alone, not
//!   joined, until it boots again.
//! - **Evaluation** is event-driven: every joined member has a deadline, its last heartbeat (or
//!   its configuration, whichever is later) + the pair's consumer time. At the deadline exactly:
//!   - active silent, standby alive → start the standby (it becomes active), reset the active;
//!   - standby silent (active alive, or none) → reset it;
//!   - the only joined member silent → reset it, the pair has no active member.
//!
//!   Both silent is the last two cases in a row (with one deadline each). Members reset are no
//!   longer joined; the start of the new active is emitted first, at the deadline, so it is on
//!   the bus within the consumer time + one frame.
//! - **Non-revertive** by default: a member that rejoins after a failover is standby. With
//!   [`PairsConfig::revertive`], member A takes the role back when it rejoins (a planned
//!   switch: A started, B sent to pre-operational).
//! - **Watchdog.** Monitoring starts at configuration, so a member that is configured and never
//!   speaks is detected like one that stops. A configured pair member that is never heard at all
//!   is reported [`PairsEvent::Missing`] after [`PairsConfig::boot_timeout`] (once per wait; no
//!   NMT command is sent to a node nobody hears).
//! - **Members heard without boot-up** (a reset that never reached the node, e.g. across a
//!   partition, or a supervisor started after its slaves) are *adopted*: after
//!   [`PairsConfig::holdoff`] without a boot-up they are configured and join like any other
//!   member; an operational one joining a pair that has an active member is sent to
//!   pre-operational. The hold-off gives a second master that reappeared with them (a healed
//!   partition) the time to be detected before this one commands anything.
//!
//! # Heartbeats that lie
//!
//! A heartbeat names its node but not its sender: a babbling controller repeating it, a second
//! board configured with the same node-ID, a device beating it on one bus only would keep a
//! dead member "alive". The dual-bus layer judges each member's heartbeats per bus against the
//! producer time it is configured with ([`crate::link::plausible`]) and hands its verdicts here
//! ([`PairSupervisor::suspect`]). A **suspect** member is handled like a silent one at the
//! instant of the verdict: an active member is replaced by a live standby (started first, on the
//! bus within one frame) and reset; a standby is reset; while suspect its heartbeats and
//! boot-ups are no sign of life, it is not adopted, and a configuration that ends meanwhile
//! leaves it waiting, unstarted. The standby is thus started, after the member's last real
//! heartbeat, within the consumer time + 1 ms, or earlier, at the verdict:
//!
//! | What | Verdict (detection bound) |
//! | --- | --- |
//! | A controller babbling the heartbeat on one bus | at its 6th frame at the latest (0.4 ms at 1 Mbit/s) |
//! | Two devices with the same node-ID beating at the producer time | within 8 producer periods of both beating |
//! | An impostor beating on one bus only | the real node's last heartbeat on the other bus + the reachability window (3 guarding periods by default): consumer time + 1 ms + (window − consumer time) |
//!
//! A standby heard becoming operational while the active member is alive was started by
//! someone else (a rogue NMT start-all): it is sent back to pre-operational at that heartbeat.
//! The active master takes an NMT command it did not send as a sign of another active master
//! and suspends its own commands for the detection timeout (0x1F90 sub 1, 100 ms by default; see
//! [`crate::supervisor::flying_master`]), so one board runs again, on the bus within one frame,
//! at the later of the command + the detection timeout and the standby's first heartbeat after
//! it. A node announces a state change at once with a heartbeat, so that is the command + the
//! detection timeout when this master heard the command, and the standby's heartbeat right
//! after its start when it did not (a command on a bus segment it cannot hear). A standby the
//! application starts through this master ([`PairSupervisor::application_nmt`]) is left running.
//!
//! # Command and shadow
//!
//! A supervisor in [`Authority::Command`] evaluates and commands. One in [`Authority::Shadow`]
//! (the standby master, or an active one that suspects another active master) only follows:
//! heartbeats and boot-ups keep the table and the deadlines up to date, NMT commands of the
//! active master seen on the bus ([`PairSupervisor::nmt_observed`]) move the roles, and a member
//! joins when the active master is seen to configure it
//! ([`PairSupervisor::configuration_observed`]; or, for a table that cannot see that, at its
//! first heartbeat after its boot-up, [`PairsConfig::shadow_join_on_heartbeat`]). One in
//! [`Authority::Idle`] (no active master known yet, at power-on) records and follows commands but
//! takes nobody's word for a configuration. Switching to command evaluates at once what is due (a
//! takeover acts on the shadow table without resetting anything that is alive) and configures
//! what nobody was seen to configure.

use crate::pair::{Member, PairId, PairSpec, MAX_PAIRS};
use core::fmt;
use duocan::frame::instant::earliest_of;
use duocan::frame::queue::Bounded;
use duocan::{Duration, Instant, NmtCommand, NmtState, NodeId};
use heapless::Vec;

mod events;
mod state;
mod trust;

pub use events::{LossReason, PairCommand, PairsError, PairsEvent, RoleChange, RoleReason};
use state::{idx, Stage};
pub use state::{Authority, MemberState, PairState, Phase};
use trust::bit;

/// Commands a supervisor can hold before they are drained.
pub const COMMAND_QUEUE: usize = 256;
/// Events a supervisor can hold before they are drained.
pub const EVENT_QUEUE: usize = 256;

/// Policy of the whole table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct PairsConfig {
    /// Give the role back to A when A rejoins (default: false, non-revertive).
    pub revertive: bool,
    /// Adopt members heard without a boot-up (default: true).
    pub adopt: bool,
    /// How long a member heard without boot-up is watched before it is adopted.
    pub holdoff: Duration,
    /// A configured member not heard for this long after the table started (or after it was
    /// reset) is reported missing.
    pub boot_timeout: Duration,
    /// A shadow table takes a member's first heartbeat after its boot-up as the sign that the
    /// active master configured it (its heartbeat producer time is written last). Right for a
    /// table that sees nothing else; wrong for boards that beat by default. The supervisor sees
    /// the active master's SDO confirmations and clears this
    /// ([`PairSupervisor::configuration_observed`]).
    pub shadow_join_on_heartbeat: bool,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl PairsConfig {
    /// The configuration with [`revertive`](Self::revertive) replaced.
    #[must_use]
    pub fn with_revertive(mut self, revertive: bool) -> Self {
        self.revertive = revertive;
        self
    }
    /// The configuration with [`adopt`](Self::adopt) replaced.
    #[must_use]
    pub fn with_adopt(mut self, adopt: bool) -> Self {
        self.adopt = adopt;
        self
    }
    /// The configuration with [`holdoff`](Self::holdoff) replaced.
    #[must_use]
    pub fn with_holdoff(mut self, holdoff: Duration) -> Self {
        self.holdoff = holdoff;
        self
    }
    /// The configuration with [`boot_timeout`](Self::boot_timeout) replaced.
    #[must_use]
    pub fn with_boot_timeout(mut self, boot_timeout: Duration) -> Self {
        self.boot_timeout = boot_timeout;
        self
    }
    /// The configuration with [`shadow_join_on_heartbeat`](Self::shadow_join_on_heartbeat) replaced.
    #[must_use]
    pub fn with_shadow_join_on_heartbeat(mut self, shadow_join_on_heartbeat: bool) -> Self {
        self.shadow_join_on_heartbeat = shadow_join_on_heartbeat;
        self
    }
}

impl Default for PairsConfig {
    fn default() -> Self {
        PairsConfig {
            revertive: false,
            adopt: true,
            holdoff: Duration::from_millis(200),
            boot_timeout: Duration::from_secs(5),
            shadow_join_on_heartbeat: true,
        }
    }
}

const NONE: u8 = 0xFF;

/// The pair table and its evaluation.
pub struct PairSupervisor {
    cfg: PairsConfig,
    authority: Authority,
    pairs: Vec<PairState, MAX_PAIRS>,
    /// node-ID → pair index · 2 + member index.
    index: [u8; 128],
    /// A lower bound of every member's next deadline (recomputed when reached).
    next: Option<Instant>,
    commands: Bounded<PairCommand, COMMAND_QUEUE>,
    events: Bounded<PairsEvent, EVENT_QUEUE>,
    /// Node-IDs (bits) whose heartbeats the dual-bus layer finds implausible.
    suspect: u128,
    /// Node-IDs (bits) the application started through this table's master.
    by_application: u128,
}

impl PairSupervisor {
    /// An empty table, commanding.
    #[must_use]
    pub fn new(cfg: PairsConfig) -> Self {
        PairSupervisor {
            cfg,
            authority: Authority::Command,
            pairs: Vec::new(),
            index: [NONE; 128],
            next: None,
            commands: Bounded::new(),
            events: Bounded::new(),
            suspect: 0,
            by_application: 0,
        }
    }

    /// The policy.
    pub fn config(&self) -> &PairsConfig {
        &self.cfg
    }
    /// Changes the policy (revertive, hold-off, …) from now on.
    pub fn set_config(&mut self, cfg: PairsConfig) {
        self.cfg = cfg;
    }

    /// Whether [`PairSupervisor::add_pair`] would accept `spec`.
    pub fn check(&self, spec: &PairSpec) -> Result<(), PairsError> {
        if spec.a == spec.b {
            return Err(PairsError::SameNode(spec.a));
        }
        for n in [spec.a, spec.b] {
            if self.index[n.raw() as usize] != NONE {
                return Err(PairsError::NodeTaken(n));
            }
        }
        if self.pairs.is_full() {
            return Err(PairsError::Full);
        }
        Ok(())
    }

    /// Adds a pair; its members are awaited from `now` (boot timeout).
    pub fn add_pair(&mut self, now: Instant, spec: PairSpec) -> Result<PairId, PairsError> {
        self.check(&spec)?;
        let p = self.pairs.len();
        self.pairs
            .push(PairState {
                spec,
                active: None,
                members: [
                    MemberState::new(Member::A, spec.a, now),
                    MemberState::new(Member::B, spec.b, now),
                ],
            })
            .map_err(|_| PairsError::Full)?;
        self.index[spec.a.raw() as usize] = (p * 2) as u8;
        self.index[spec.b.raw() as usize] = (p * 2 + 1) as u8;
        self.lower_next(now + self.cfg.boot_timeout);
        Ok(PairId(p as u8))
    }

    /// The pair and member a node belongs to.
    pub fn locate(&self, node: NodeId) -> Option<(PairId, Member)> {
        let i = self.index[node.raw() as usize];
        (i != NONE).then(|| {
            let m = if i.is_multiple_of(2) {
                Member::A
            } else {
                Member::B
            };
            (PairId(i / 2), m)
        })
    }

    /// One pair.
    pub fn pair(&self, p: PairId) -> Option<&PairState> {
        self.pairs.get(p.0 as usize)
    }
    /// The whole table.
    pub fn pairs(&self) -> impl Iterator<Item = (PairId, &PairState)> + '_ {
        self.pairs
            .iter()
            .enumerate()
            .map(|(i, p)| (PairId(i as u8), p))
    }
    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }
    /// True if no pair is configured.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Commanding or following.
    pub fn authority(&self) -> Authority {
        self.authority
    }

    /// Switches between commanding and following. Becoming the commander evaluates at once
    /// what is due: silent members, pairs without an active member but with a live one,
    /// configurations the previous commander left unfinished.
    pub fn set_authority(&mut self, now: Instant, a: Authority) {
        if self.authority == a {
            return;
        }
        self.authority = a;
        if a != Authority::Command {
            return;
        }
        for p in 0..self.pairs.len() {
            for m in [Member::A, Member::B] {
                let holdoff = self.cfg.holdoff;
                match &mut self.pairs[p].member_mut(m).stage {
                    Stage::Configuring => self.configure(p, m),
                    // Watched while following: the hold-off starts over from now.
                    Stage::Waiting {
                        adopt_at: Some(at), ..
                    } => *at = now + holdoff,
                    _ => {}
                }
            }
        }
        self.next = Some(now);
        self.handle_timeout(now);
        for p in 0..self.pairs.len() {
            self.ensure_active(now, p, RoleReason::Takeover);
            // Two running members (one started by another master behind a partition): the
            // standby goes back to pre-operational.
            if let Some(a) = self.pairs[p].active {
                let o = self.pairs[p].member(a.other());
                if o.joined() && o.nmt == Some(NmtState::Operational) {
                    let node = o.node;
                    self.nmt(NmtCommand::EnterPreOperational, node);
                }
            }
        }
    }

    // ----- observations -----

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
                // Deadlines only move later: the cached lower bound stays valid.
                *deadline = now + consumer;
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
    pub fn configured(&mut self, now: Instant, node: NodeId, ok: bool) {
        let Some((p, m)) = self.configuring(node) else {
            return;
        };
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

    /// The pair index and member of `node` if it is being configured.
    fn configuring(&self, node: NodeId) -> Option<(usize, Member)> {
        let (pair, m) = self.locate(node)?;
        let p = pair.0 as usize;
        (self.pairs[p].member(m).phase() == Phase::Configuring).then_some((p, m))
    }

    // ----- commands -----

    /// Makes `to` the active member of `pair` by hand: it is started, the previous active member
    /// sent to pre-operational.
    pub fn switch_over(
        &mut self,
        now: Instant,
        pair: PairId,
        to: Member,
    ) -> Result<(), PairsError> {
        if self.authority != Authority::Command {
            return Err(PairsError::Shadow);
        }
        let p = pair.0 as usize;
        let state = self.pairs.get(p).ok_or(PairsError::NoPair(pair))?;
        if !self.alive(p, to, now) {
            return Err(PairsError::NotAlive(pair, to));
        }
        if state.active == Some(to) {
            return Ok(());
        }
        self.planned_switch(now, p, to, RoleReason::Manual);
        Ok(())
    }

    // ----- time -----

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

    // ----- outputs -----

    /// Next command.
    #[must_use]
    pub fn poll_command(&mut self) -> Option<PairCommand> {
        self.commands.pop()
    }
    /// Next event.
    #[must_use]
    pub fn poll_event(&mut self) -> Option<PairsEvent> {
        self.events.pop()
    }
    /// Commands and events dropped because they were not drained.
    pub fn dropped(&self) -> (u32, u32) {
        (self.commands.dropped(), self.events.dropped())
    }

    // ----- internals -----

    /// The earliest due item of any member: (instant, pair, member).
    fn earliest(&self) -> Option<(Instant, usize, Member)> {
        let mut best: Option<(Instant, usize, Member)> = None;
        for (p, pair) in self.pairs.iter().enumerate() {
            for s in &pair.members {
                if let Some(t) = self.due(s) {
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
            Stage::Joined { .. } => self.silent(t, p, m, s),
            Stage::Waiting { adopt_at, .. } => {
                if adopt_at.is_some_and(|a| a <= t) && self.authority == Authority::Command {
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
        let (why, loss) = if self.is_suspect(s.node) {
            (Some(RoleReason::ActiveSuspect), LossReason::Suspect)
        } else {
            (None, LossReason::Silent { last })
        };
        if self.pairs[p].active == Some(m) {
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
        self.nmt(NmtCommand::ResetNode, s.node);
    }

    fn join(&mut self, now: Instant, p: usize, m: Member) {
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
    fn leave(&mut self, t: Instant, p: usize, m: Member, reason: LossReason) {
        let pair = PairId(p as u8);
        let s = self.pairs[p].member_mut(m);
        let was_joined = s.joined();
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
    }

    /// Makes `to` active, starting it (commanding), and reports the change.
    fn set_role(&mut self, t: Instant, p: usize, to: Option<Member>, reason: RoleReason) {
        let from = self.pairs[p].active;
        if from == to {
            return;
        }
        self.pairs[p].active = to;
        let spec = self.pairs[p].spec;
        if let Some(m) = to {
            // Running it is this table's decision from now on.
            self.by_application &= !bit(spec.node(m));
        }
        if self.authority == Authority::Command {
            if let Some(m) = to {
                // A member already running (adopted) needs no start; nor does a suspect one,
                // which the same instant's timeout replaces (a start would wake a board the
                // table is about to reset).
                if self.pairs[p].member(m).nmt != Some(NmtState::Operational)
                    && !self.is_suspect(spec.node(m))
                {
                    self.nmt(NmtCommand::Start, spec.node(m));
                }
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
    fn planned_switch(&mut self, now: Instant, p: usize, to: Member, reason: RoleReason) {
        let old = self.pairs[p].active;
        self.set_role(now, p, Some(to), reason);
        if let Some(o) = old.filter(|o| *o != to) {
            let node = self.pairs[p].spec.node(o);
            self.nmt(NmtCommand::EnterPreOperational, node);
        }
    }

    /// A pair without an active member but with a live joined member gets one.
    fn ensure_active(&mut self, now: Instant, p: usize, reason: RoleReason) {
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
    fn follow_state(&mut self, now: Instant, p: usize, m: Member, state: NmtState) {
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
    fn follow_command(&mut self, now: Instant, p: usize, m: Member, cmd: NmtCommand) {
        match cmd {
            NmtCommand::Start => {
                if !self.pairs[p].member(m).joined() {
                    self.join(now, p, m);
                }
                self.pairs[p].member_mut(m).nmt = Some(NmtState::Operational);
                self.set_role(now, p, Some(m), RoleReason::Observed);
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

    fn configure(&mut self, p: usize, m: Member) {
        let spec = self.pairs[p].spec;
        self.cmd(PairCommand::Configure {
            node: spec.node(m),
            producer_time: spec.producer_time,
        });
    }

    fn nmt(&mut self, cmd: NmtCommand, node: NodeId) {
        if self.authority == Authority::Command {
            // This table decides again what it runs.
            self.by_application &= !bit(node);
            self.cmd(PairCommand::Nmt { cmd, node });
        }
    }

    fn cmd(&mut self, c: PairCommand) {
        self.commands.push(c);
    }

    fn event(&mut self, e: PairsEvent) {
        self.events.push(e);
    }

    fn lower_next(&mut self, t: Instant) {
        if self.next.is_none_or(|n| t < n) {
            self.next = Some(t);
        }
    }
}

impl fmt::Debug for PairSupervisor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PairSupervisor")
            .field("authority", &self.authority)
            .field("pairs", &self.pairs.len())
            .field("next", &self.next)
            .finish_non_exhaustive()
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
