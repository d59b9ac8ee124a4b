//! The flying-master machine: one master-capable device's part of the protocol, its inputs
//! (frames, heartbeats, foreign activity), its commands (hand over, take over) and its timers.

use super::config::FlyingMasterConfig;
use super::events::{FlyingEvent, FlyingMasterError, MasterReason, MasterRole, MasterRoleChange};
use super::frames::{
    Rank, ACTIVE_MASTER_REQUEST, ACTIVE_MASTER_RESPONSE, FORCE_NEGOTIATION, MASTER_CAPABLE_REQUEST,
    MASTER_CAPABLE_RESPONSE, NEGOTIATION_REQUEST,
};
use super::state::{Active, Peer, State, MAX_PEERS};
use core::fmt;
use duocan_core::frame::instant::{earliest_of, shift_back};
use duocan_core::frame::queue::Bounded;
use duocan_core::{Duration, Frame, Id, Instant, NodeId};
use heapless::Vec;

/// One master-capable device's part of the flying-master protocol.
pub struct FlyingMaster {
    cfg: FlyingMasterConfig,
    state: State,
    peers: Vec<Peer, MAX_PEERS>,
    tx: Bounded<Frame, 16>,
    events: Bounded<FlyingEvent, 16>,
}

impl FlyingMaster {
    /// A device that has not started.
    #[must_use]
    pub fn new(cfg: FlyingMasterConfig) -> Self {
        FlyingMaster {
            cfg,
            state: State::Off,
            peers: Vec::new(),
            tx: Bounded::new(),
            events: Bounded::new(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &FlyingMasterConfig {
        &self.cfg
    }
    /// This device's rank.
    pub fn rank(&self) -> Rank {
        self.cfg.rank
    }
    /// The role now.
    pub fn role(&self) -> MasterRole {
        self.state.role()
    }
    /// True when active.
    pub fn is_active(&self) -> bool {
        matches!(self.state, State::Active(_))
    }
    /// Active and not suspended: NMT commands to slaves may be sent at `now`.
    pub fn may_command(&self, now: Instant) -> bool {
        matches!(self.state, State::Active(a) if a.suspended_until.is_none_or(|u| now >= u))
    }
    /// The other master-capable devices known.
    pub fn peers(&self) -> &[Peer] {
        &self.peers
    }
    /// The active master, as far as this device knows (itself when active).
    pub fn active_master(&self) -> Option<Rank> {
        match self.state {
            State::Active(_) => Some(self.cfg.rank),
            State::Standby { master, .. } => master,
            _ => None,
        }
    }

    /// Declares another master-capable device (its heartbeat is then watched).
    pub fn add_peer(&mut self, rank: Rank) -> Result<(), FlyingMasterError> {
        self.learn(rank)
            .map(|_| ())
            .ok_or(FlyingMasterError::PeersFull)
    }

    /// Power-on: ask for the active master. Called again, it starts over from the detection,
    /// whatever the role was.
    pub fn start(&mut self, now: Instant) {
        self.send(ACTIVE_MASTER_REQUEST, &[]);
        let until = now + self.cfg.detection_timeout;
        self.change(now, State::Detecting { until }, MasterReason::PowerOn);
    }

    // ----- inputs -----

    /// A frame from the bus; true if it was a flying-master frame.
    pub fn handle_frame(&mut self, now: Instant, frame: &Frame) -> bool {
        let Id::Standard(id) = frame.id() else {
            return false;
        };
        if !(ACTIVE_MASTER_RESPONSE..=FORCE_NEGOTIATION).contains(&id) || frame.is_remote() {
            return false;
        }
        let rank = Rank::from_payload(frame.data());
        if let Some(r) = rank.filter(|r| r.node != self.cfg.rank.node) {
            let _ = self.learn(r);
        }
        match (id, rank) {
            (ACTIVE_MASTER_RESPONSE, Some(r)) => self.on_announcement(now, r),
            (NEGOTIATION_REQUEST, _) => match self.state {
                State::Active(_) => self.announce(),
                State::Negotiating { .. } | State::Off => {}
                _ => self.negotiate(now, MasterReason::NegotiationRequested),
            },
            (ACTIVE_MASTER_REQUEST, _) if self.is_active() => self.announce(),
            (MASTER_CAPABLE_REQUEST, _) if self.state != State::Off => {
                self.send(MASTER_CAPABLE_RESPONSE, &self.cfg.rank.payload());
            }
            (FORCE_NEGOTIATION, Some(r)) if r.node != self.cfg.rank.node => self.on_force(now, r),
            _ => {}
        }
        true
    }

    /// A heartbeat of `node`; `boot_up` if it is a boot-up message. Tracks the other masters:
    /// only heartbeats (not flying-master frames) move the takeover deadline, so that it is
    /// exactly the active master's last heartbeat + the timeout.
    pub fn heartbeat(&mut self, now: Instant, node: NodeId, boot_up: bool) {
        let timeout = self.cfg.master_timeout;
        let Some(p) = self.peers.iter_mut().find(|p| p.rank.node == node) else {
            return;
        };
        let gap = p.last.is_none_or(|l| l + timeout <= now);
        let returned = p.lost || (gap && p.last.is_some());
        if gap {
            p.continuous = false;
        }
        p.last = Some(now);
        p.lost = false;
        let rank = p.rank;
        // A master that was lost while this one was active and comes back without booting may
        // have been active behind a partition. A rebooted one starts by detecting: no conflict.
        if returned && !boot_up && self.is_active() {
            self.suspect(now);
        }
        if matches!(self.state, State::Standby { master: Some(m), .. } if m == rank) {
            if boot_up {
                // The active master rebooted (faster than the timeout): it is not active any
                // more and starts by detecting; take over now rather than leave the network
                // without a master for a whole negotiation.
                return self.lose_master(now, rank, MasterReason::MasterRebooted(node));
            }
            self.state = State::Standby {
                master: Some(rank),
                takeover_at: now + timeout,
                confirm_by: self.confirm_by(),
            };
        }
        self.plan_handback(now);
    }

    /// A SYNC or NMT command this device did not send: if active, another master may be.
    pub fn foreign_activity(&mut self, now: Instant) {
        if self.is_active() {
            self.suspect(now);
        }
    }

    // ----- commands -----

    /// Hands the role to `to` (or the best live peer): announces it on 0x71 and becomes its
    /// standby.
    pub fn hand_over(&mut self, now: Instant, to: Option<Rank>) -> Result<Rank, FlyingMasterError> {
        if !self.is_active() {
            return Err(FlyingMasterError::WrongRole(self.role()));
        }
        let to = match to {
            Some(r) => r,
            None => self
                .best_live_peer(now)
                .ok_or(FlyingMasterError::NoSuccessor)?,
        };
        self.send(ACTIVE_MASTER_RESPONSE, &to.payload());
        self.follow(now, to, MasterReason::HandedOver(to));
        Ok(to)
    }

    /// Takes the role by hand (standby): announces itself. An active master that has heard this
    /// one alive all along steps down.
    pub fn take_over(&mut self, now: Instant) -> Result<(), FlyingMasterError> {
        match self.state {
            State::Standby { .. } | State::Negotiating { .. } | State::Detecting { .. } => {
                self.activate(now, MasterReason::Manual);
                Ok(())
            }
            _ => Err(FlyingMasterError::WrongRole(self.role())),
        }
    }

    /// A revertive hand-back that became due (the supervisor performs it between two SYNCs).
    pub fn take_handback(&mut self) -> Option<Rank> {
        match &mut self.state {
            State::Active(a) => a.handback.take(),
            _ => None,
        }
    }

    // ----- time -----

    /// Earliest deadline.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        match self.state {
            State::Off => None,
            State::Detecting { until } | State::Negotiating { until } => Some(until),
            State::Standby {
                takeover_at: until,
                confirm_by,
                ..
            } => earliest_of([Some(until), confirm_by]),
            State::Active(a) => earliest_of([a.detect_at, a.suspended_until, a.handback_at]),
        }
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::supervisor`]):
    /// every peer's last heartbeat and the deadlines of the phase (detection, negotiation,
    /// takeover, the active master's detection cycle, suspension and hand-back) move back with
    /// it, so that each keeps the time it had to run. The machine does not watch the clock
    /// itself; its owner tells it.
    pub fn step_back(&mut self, by: Duration) {
        for p in self.peers.iter_mut() {
            shift_back(&mut p.last, by);
        }
        match &mut self.state {
            State::Off => {}
            State::Detecting { until } | State::Negotiating { until } => *until = *until - by,
            State::Standby {
                takeover_at,
                confirm_by,
                ..
            } => {
                *takeover_at = *takeover_at - by;
                shift_back(confirm_by, by);
            }
            State::Active(a) => {
                shift_back(&mut a.detect_at, by);
                shift_back(&mut a.suspended_until, by);
                shift_back(&mut a.handback_at, by);
            }
        }
    }

    /// The caller's clock jumped ahead from `from` to `to` without this machine being given
    /// anything in between (the clock contract, see [`crate::supervisor`]): the other masters
    /// are observed again rather than judged on time nobody watched. A peer heard within the
    /// master timeout before `from` counts as heard at `to` (not lost, its next heartbeat no
    /// return from a loss); a standby's takeover falls at the earliest `to` + the timeout. The
    /// active master's own timers run as for time that passed.
    pub fn jumped(&mut self, from: Instant, to: Instant) {
        let timeout = self.cfg.master_timeout;
        for p in self.peers.iter_mut() {
            if let Some(l) = p.last.filter(|l| *l + timeout > from) {
                p.last = Some(l.max(to));
            }
        }
        let detection = self.cfg.detection_timeout;
        if let State::Standby {
            takeover_at,
            confirm_by,
            ..
        } = &mut self.state
        {
            if *takeover_at > from {
                *takeover_at = (*takeover_at).max(to + timeout);
            }
            if let Some(c) = confirm_by.filter(|c| *c > from) {
                *confirm_by = Some(c.max(to + detection));
            }
        }
    }

    /// Does what is due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        if let Some(t) = self.confirm_by().filter(|t| *t <= now) {
            // The master followed did not answer: nobody may be active. Negotiate.
            self.set_confirm_by(None);
            self.send(NEGOTIATION_REQUEST, &[]);
            return self.negotiate(t, MasterReason::NoActiveMaster);
        }
        match self.state {
            State::Off => {}
            State::Active(a) => self.active_timers(now, a),
            State::Detecting { until: t } if t <= now => {
                self.send(NEGOTIATION_REQUEST, &[]);
                self.negotiate(t, MasterReason::NoActiveMaster);
            }
            State::Negotiating { until: t } if t <= now => {
                self.activate(t, MasterReason::NegotiationWon)
            }
            State::Standby {
                master: Some(master),
                takeover_at: t,
                ..
            } if t <= now => self.master_silent(t, master),
            State::Standby {
                master: None,
                takeover_at: t,
                ..
            } if t <= now => {
                // A pending takeover (better live peers had their slots first).
                self.activate(t, MasterReason::NoActiveMaster)
            }
            _ => {}
        }
    }

    // ----- outputs -----

    /// Next frame to send.
    #[must_use]
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.tx.pop()
    }
    /// Next event.
    #[must_use]
    pub fn poll_event(&mut self) -> Option<FlyingEvent> {
        self.events.pop()
    }

    // ----- internals -----

    /// The active master's timers due at `now`; `a` is its data, written back at the end (no
    /// timer changes the role).
    fn active_timers(&mut self, now: Instant, mut a: Active) {
        if a.suspended_until.is_some_and(|u| u <= now) {
            a.suspended_until = None;
        }
        if let Some(t) = a.detect_at.filter(|t| *t <= now) {
            self.send(FORCE_NEGOTIATION, &self.cfg.rank.payload());
            // On the cycle's grid; after a jump of the clock past further cycles, one cycle
            // after `now`: one request for all the missed ones, not a burst of them.
            let next = t + self.cfg.detect_cycle;
            a.detect_at = self.detection_after(if next <= now { now } else { t });
        }
        if let Some(t) = a.handback_at.filter(|t| *t <= now) {
            a.handback_at = None;
            a.handback = self.better_live_peer(t);
        }
        self.state = State::Active(a);
    }

    fn on_announcement(&mut self, now: Instant, r: Rank) {
        if r == self.cfg.rank {
            // Named by someone else's 0x71: a hand-over to this device.
            if !self.is_active() {
                self.activate(now, MasterReason::Appointed);
            }
            return;
        }
        match self.state {
            State::Active(_) => {
                let planned = self
                    .peers
                    .iter()
                    .any(|p| p.rank == r && p.continuous && !p.lost);
                if r < self.cfg.rank || planned {
                    self.yield_to(now, r);
                } else {
                    // A worse master claims the role: assert ours.
                    self.send(FORCE_NEGOTIATION, &self.cfg.rank.payload());
                    self.suspect(now);
                }
            }
            State::Off => {}
            _ => {
                // An active master announced itself: whatever was to be confirmed is.
                self.set_confirm_by(None);
                self.follow(now, r, MasterReason::ActiveMasterFound(r));
            }
        }
    }

    /// Steps down for `r` after a conflict, and asks for the active master: `r` answers if
    /// it still is (its claim may have crossed one of this device's, and it may have stepped
    /// down for it meanwhile).
    ///
    /// Stepping down for a better master, it also hands the role to it (an announcement of
    /// `r`'s rank, which `r` takes only if it is no longer active). Claims cross when this
    /// device took over because `r`'s heartbeats stopped reaching it (both buses down for a
    /// moment) while `r` lived: `r`, having heard this one all along, may have taken the claim
    /// for a take-over by hand and stepped down for it. Without the hand-over both would follow
    /// the other until the confirmation ran out and a negotiation ended (600 ms without a
    /// master). Only the worse of the two hands over, so the two cannot pass the role back and
    /// forth.
    fn yield_to(&mut self, now: Instant, r: Rank) {
        self.follow(now, r, MasterReason::ConflictLost(r));
        if r < self.cfg.rank {
            self.send(ACTIVE_MASTER_RESPONSE, &r.payload());
        }
        self.send(ACTIVE_MASTER_REQUEST, &[]);
        self.set_confirm_by(Some(now + self.cfg.detection_timeout));
    }

    fn on_force(&mut self, now: Instant, r: Rank) {
        match self.state {
            State::Active(_) => {
                if r < self.cfg.rank {
                    self.yield_to(now, r);
                } else {
                    // We rank better: tell the other one (and everyone) who is active.
                    self.announce();
                }
            }
            // The periodic detection of the master followed (which shows it active), or of a
            // worse one (which the better one will deal with).
            State::Standby {
                master: Some(m), ..
            } if m <= r => {
                if m == r {
                    self.set_confirm_by(None);
                }
            }
            State::Off => {}
            _ => self.follow(now, r, MasterReason::ActiveMasterFound(r)),
        }
    }

    fn master_silent(&mut self, t: Instant, master: Rank) {
        let last = t - self.cfg.master_timeout;
        let reason = MasterReason::HeartbeatLost {
            master: master.node,
            last,
        };
        self.lose_master(t, master, reason);
    }

    fn lose_master(&mut self, t: Instant, master: Rank, reason: MasterReason) {
        if let Some(p) = self.peers.iter_mut().find(|p| p.rank == master) {
            p.lost = true;
            p.continuous = false;
        }
        let better = self
            .peers
            .iter()
            .filter(|p| p.rank < self.cfg.rank && p.rank != master && self.alive(p, t))
            .count() as u64;
        if better == 0 {
            self.activate(t, reason);
        } else {
            let takeover_at = t + self.cfg.device_slot.saturating_mul(better);
            let pending = State::Standby {
                master: None,
                takeover_at,
                confirm_by: self.confirm_by(),
            };
            self.change(t, pending, reason);
        }
    }

    /// The next periodic detection, a cycle after `from`; none with a zero cycle (a request
    /// due again at the instant it was sent would never let time move on).
    fn detection_after(&self, from: Instant) -> Option<Instant> {
        let cycle = self.cfg.detect_cycle;
        (!cycle.is_zero()).then(|| from + cycle)
    }

    fn negotiate(&mut self, now: Instant, reason: MasterReason) {
        let until = now + self.cfg.negotiation_wait();
        self.change(now, State::Negotiating { until }, reason);
    }

    fn activate(&mut self, now: Instant, reason: MasterReason) {
        for p in self.peers.iter_mut() {
            p.continuous = p.last.is_some_and(|l| l + self.cfg.master_timeout > now);
        }
        self.announce();
        let active = Active {
            detect_at: self.detection_after(now),
            ..Active::default()
        };
        self.change(now, State::Active(active), reason);
        self.plan_handback(now);
    }

    fn follow(&mut self, now: Instant, r: Rank, reason: MasterReason) {
        // Watched from its last heartbeat if that is recent, else from now.
        let timeout = self.cfg.master_timeout;
        let last = self
            .peers
            .iter()
            .find(|p| p.rank == r)
            .and_then(|p| p.last)
            .filter(|l| *l + timeout > now)
            .unwrap_or(now);
        let standby = State::Standby {
            master: Some(r),
            takeover_at: last + timeout,
            confirm_by: self.confirm_by(),
        };
        self.change(now, standby, reason);
    }

    /// Active: another active master may be there; commands stop until the detection timeout
    /// has passed without a conflict.
    fn suspect(&mut self, now: Instant) {
        let until = now + self.cfg.detection_timeout;
        let State::Active(a) = &mut self.state else {
            return;
        };
        let fresh = a.suspended_until.is_none();
        a.suspended_until = Some(until);
        if fresh {
            self.send(FORCE_NEGOTIATION, &self.cfg.rank.payload());
            self.events.push(FlyingEvent::Suspended { at: now, until });
        }
    }

    fn plan_handback(&mut self, now: Instant) {
        let planned = match self.state {
            State::Active(a) => a.handback_at.is_some(),
            _ => return,
        };
        if !self.cfg.revertive || planned || self.better_live_peer(now).is_none() {
            return;
        }
        if let State::Active(a) = &mut self.state {
            a.handback_at = Some(now + self.cfg.handback_delay);
        }
    }

    fn announce(&mut self) {
        self.send(ACTIVE_MASTER_RESPONSE, &self.cfg.rank.payload());
    }

    fn alive(&self, p: &Peer, now: Instant) -> bool {
        p.last.is_some_and(|l| l + self.cfg.master_timeout > now)
    }

    fn best_live_peer(&self, now: Instant) -> Option<Rank> {
        self.peers
            .iter()
            .filter(|p| self.alive(p, now))
            .map(|p| p.rank)
            .min()
    }

    fn better_live_peer(&self, now: Instant) -> Option<Rank> {
        self.best_live_peer(now).filter(|r| *r < self.cfg.rank)
    }

    fn learn(&mut self, r: Rank) -> Option<usize> {
        if let Some(i) = self.peers.iter().position(|p| p.rank.node == r.node) {
            self.peers[i].rank = r;
            return Some(i);
        }
        self.peers
            .push(Peer {
                rank: r,
                last: None,
                continuous: false,
                lost: false,
            })
            .ok()?;
        Some(self.peers.len() - 1)
    }

    /// A standby's deadline for the master it follows to show it is active (see
    /// [`State::Standby`]).
    fn confirm_by(&self) -> Option<Instant> {
        match self.state {
            State::Standby { confirm_by, .. } => confirm_by,
            _ => None,
        }
    }

    fn set_confirm_by(&mut self, at: Option<Instant>) {
        if let State::Standby { confirm_by, .. } = &mut self.state {
            *confirm_by = at;
        }
    }

    fn send(&mut self, id: u16, data: &[u8]) {
        if let Ok(f) = Frame::new(Id::Standard(id), data) {
            self.tx.push(f);
        }
    }

    /// Enters `to`; reports a role change if the role differs (following the same master
    /// again only re-times its deadline).
    fn change(&mut self, at: Instant, to: State, reason: MasterReason) {
        let from = self.role();
        self.state = to;
        let to = self.role();
        if from == to {
            return;
        }
        self.events.push(FlyingEvent::Role(MasterRoleChange {
            at,
            from,
            to,
            reason,
        }));
    }
}

impl fmt::Debug for FlyingMaster {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FlyingMaster")
            .field("rank", &self.cfg.rank)
            .field("role", &self.role())
            .field("peers", &self.peers)
            .finish_non_exhaustive()
    }
}
