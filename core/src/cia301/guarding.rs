//! Node guarding (the master polls, the slave answers with its state and a toggle bit) and life
//! guarding (the slave notices the master's silence after guard time × life time factor).
//!
//! In a redundant network both masters guard every slave, so both sides are complete.
//! The slave toggles its answer bit at every request, whoever sent it, so a master that guards
//! beside another one counts the other's requests it observes on the bus
//! ([`GuardMaster::observed_request`]) and checks every answer in the order the slave gave them.

use crate::cia301::nmt::NmtState;
use crate::cia301::service::{ServiceEvent, ServiceOutput};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{shift_back, Duration, Instant};

/// The slave side: answers guarding requests and watches the master's polling.
#[derive(Clone, Debug, Default)]
pub struct GuardSlave {
    toggle: bool,
    life_time: Duration,
    deadline: Option<Instant>,
    lost: bool,
}

/// What life guarding reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LifeEvent {
    /// No guarding request for guard time × life time factor.
    Lost,
    /// Guarding requests arrived again after a loss.
    Resumed,
}

impl GuardSlave {
    /// Sets guard time (0x100C) and life time factor (0x100D). Life guarding runs when both are
    /// non-zero and starts with the first request.
    pub fn configure(&mut self, now: Instant, guard_time: Duration, factor: u8) {
        self.life_time = guard_time.saturating_mul(factor as u64);
        if self.life_time.is_zero() {
            self.deadline = None;
        } else if self.deadline.is_some() {
            self.deadline = Some(now + self.life_time);
        }
    }
    /// Reset communication: the toggle starts again at 0 and life guarding waits for a request.
    pub fn reset(&mut self) {
        self.toggle = false;
        self.deadline = None;
        self.lost = false;
    }
    /// A guarding request arrived: returns the answer byte (state | toggle << 7) and whether life
    /// guarding resumed.
    pub fn request(&mut self, now: Instant, state: NmtState) -> (u8, Option<LifeEvent>) {
        let byte = state.code() | if self.toggle { 0x80 } else { 0 };
        self.toggle = !self.toggle;
        if !self.life_time.is_zero() {
            self.deadline = Some(now + self.life_time);
        }
        let resumed = core::mem::replace(&mut self.lost, false).then_some(LifeEvent::Resumed);
        (byte, resumed)
    }
    /// True from a life-guarding loss until the next request.
    pub fn is_lost(&self) -> bool {
        self.lost
    }
    /// When the master's next request is due at the latest.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.deadline
    }
    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.deadline, by);
    }
    /// Reports a life-guarding loss if the deadline passed.
    pub fn handle_timeout<O: ServiceOutput>(&mut self, now: Instant, out: &mut O) {
        match self.deadline {
            Some(d) if d <= now => {
                self.deadline = None;
                self.lost = true;
                out.event(now, ServiceEvent::Life(LifeEvent::Lost));
            }
            _ => {}
        }
    }
}

/// What the master-side guarding reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GuardEvent {
    /// The node answered with this state (after a valid toggle).
    State {
        /// The node.
        node: NodeId,
        /// Its state.
        state: NmtState,
    },
    /// No valid answer within the node life time (guard time × factor).
    Timeout {
        /// The node.
        node: NodeId,
    },
    /// A valid answer arrived after a timeout.
    Resumed {
        /// The node.
        node: NodeId,
    },
    /// The answer's toggle bit did not alternate; the answer is discarded (CiA 301).
    ToggleError {
        /// The node.
        node: NodeId,
        /// The toggle bit that was expected.
        expected: bool,
    },
}

#[derive(Clone, Copy, Debug)]
struct Guarded {
    node: NodeId,
    guard_time: Duration,
    life_time: Duration,
    next_poll: Instant,
    deadline: Instant,
    /// Requests (own and observed) not answered yet.
    awaiting: u8,
    expect_toggle: bool,
    /// The toggle expected is known: the node booted while guarded, or answered once.
    synced: bool,
    lost: bool,
}

/// Outstanding requests counted at most: a lost answer must not make later frames on the
/// identifier (heartbeats share it) count as answers for long.
const MAX_OUTSTANDING: u8 = 2;

/// The master side: polls up to `N` nodes with remote frames and checks the answers.
#[derive(Clone, Debug)]
pub struct GuardMaster<const N: usize> {
    nodes: heapless::Vec<Guarded, N>,
}

impl<const N: usize> Default for GuardMaster<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> GuardMaster<N> {
    /// Guards nobody.
    #[must_use]
    pub const fn new() -> Self {
        GuardMaster {
            nodes: heapless::Vec::new(),
        }
    }

    /// Starts (or re-times) guarding `node`: first request at `now`, then every `guard_time`;
    /// timeout after `guard_time × factor` without a valid answer. Returns false when full.
    ///
    /// A node guarded already keeps its toggle expectation (the slave's toggle runs on). A node
    /// not guarded before may have answered other masters: its first answer sets the toggle
    /// expected next, unless its boot-up is seen first (then the first answer must carry 0).
    pub fn guard(&mut self, now: Instant, node: NodeId, guard_time: Duration, factor: u8) -> bool {
        let life_time = guard_time.saturating_mul(factor.max(1) as u64);
        if let Some(g) = self.nodes.iter_mut().find(|g| g.node == node) {
            g.guard_time = guard_time;
            g.life_time = life_time;
            g.next_poll = now;
            g.deadline = now + life_time;
            return true;
        }
        self.nodes
            .push(Guarded {
                node,
                guard_time,
                life_time,
                next_poll: now,
                deadline: now + life_time,
                awaiting: 0,
                expect_toggle: false,
                synced: false,
                lost: false,
            })
            .is_ok()
    }

    /// Stops guarding `node`.
    pub fn unguard(&mut self, node: NodeId) {
        self.nodes.retain(|g| g.node != node);
    }

    /// The node booted (its toggle restarts at 0).
    pub fn booted(&mut self, node: NodeId) {
        if let Some(g) = self.nodes.iter_mut().find(|g| g.node == node) {
            g.expect_toggle = false;
            g.synced = true;
        }
    }

    /// Another master's guarding request for `node` was seen on the bus: the slave's next
    /// answer is to it, and toggles the bit like an answer to this master. Returns false if
    /// `node` is not guarded here.
    pub fn observed_request(&mut self, node: NodeId) -> bool {
        match self.nodes.iter_mut().find(|g| g.node == node) {
            Some(g) => {
                g.awaiting = (g.awaiting + 1).min(MAX_OUTSTANDING);
                true
            }
            None => false,
        }
    }

    /// An answer (data frame on the node's guarding identifier) arrived. Ignored unless a
    /// request is outstanding: with the predefined set, heartbeats share the identifier.
    pub fn answer(
        &mut self,
        now: Instant,
        node: NodeId,
        state: NmtState,
        toggle: bool,
        mut out: impl FnMut(GuardEvent),
    ) {
        let Some(g) = self.nodes.iter_mut().find(|g| g.node == node) else {
            return;
        };
        if g.awaiting == 0 {
            return;
        }
        g.awaiting -= 1;
        if !g.synced {
            g.synced = true;
            g.expect_toggle = toggle;
        }
        if toggle != g.expect_toggle {
            out(GuardEvent::ToggleError {
                node,
                expected: g.expect_toggle,
            });
            // Resynchronise so one lost answer gives one error, not an endless series.
            g.expect_toggle = !toggle;
            return;
        }
        g.expect_toggle = !g.expect_toggle;
        g.deadline = now + g.life_time;
        if core::mem::replace(&mut g.lost, false) {
            out(GuardEvent::Resumed { node });
        }
        out(GuardEvent::State { node, state });
    }

    /// Earliest poll or timeout.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.nodes
            .iter()
            .map(|g| {
                if g.lost {
                    g.next_poll
                } else {
                    g.next_poll.min(g.deadline)
                }
            })
            .min()
    }

    /// Reports timeouts and asks for the due requests ([`ServiceEvent::GuardRequest`]: the
    /// composer sends the remote frame), node by node.
    pub fn handle_timeout<O: ServiceOutput>(&mut self, now: Instant, out: &mut O) {
        for g in self.nodes.iter_mut() {
            if !g.lost && g.deadline <= now {
                g.lost = true;
                out.event(
                    now,
                    ServiceEvent::Guard(GuardEvent::Timeout { node: g.node }),
                );
            }
            if g.next_poll <= now {
                out.event(now, ServiceEvent::GuardRequest { node: g.node });
                g.awaiting = (g.awaiting + 1).min(MAX_OUTSTANDING);
                g.next_poll += g.guard_time.max(Duration::from_micros(1));
                if g.next_poll <= now {
                    g.next_poll = now + g.guard_time;
                }
            }
        }
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        for g in self.nodes.iter_mut() {
            g.next_poll = g.next_poll - by;
            g.deadline = g.deadline - by;
        }
    }

    /// Guarded nodes and whether each is currently lost.
    pub fn guarded(&self) -> impl Iterator<Item = (NodeId, bool)> + '_ {
        self.nodes.iter().map(|g| (g.node, g.lost))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia301::service::Recorder;
    use std::vec::Vec;

    /// Runs the master's timeout: requests asked for go to `reqs`, reports to `evs`.
    fn tick<const N: usize>(
        m: &mut GuardMaster<N>,
        now: Instant,
        reqs: &mut Vec<NodeId>,
        evs: &mut Vec<GuardEvent>,
    ) {
        let mut out = Recorder::new(NmtState::Operational);
        m.handle_timeout(now, &mut out);
        assert!(out.frames.is_empty(), "the identifiers are the composer's");
        for e in out.kinds() {
            match e {
                ServiceEvent::GuardRequest { node } => reqs.push(node),
                ServiceEvent::Guard(e) => evs.push(e),
                other => panic!("not a guarding output: {other:?}"),
            }
        }
    }

    /// Runs the slave's timeout: what life guarding reported.
    fn life(s: &mut GuardSlave, now: Instant) -> Option<LifeEvent> {
        let mut out = Recorder::new(NmtState::Operational);
        s.handle_timeout(now, &mut out);
        match out.kinds()[..] {
            [] => None,
            [ServiceEvent::Life(e)] => Some(e),
            ref other => panic!("not one life-guarding event: {other:?}"),
        }
    }

    #[test]
    fn slave_toggle_starts_at_zero_and_alternates() {
        let mut s = GuardSlave::default();
        let t = Instant::ZERO;
        assert_eq!(s.request(t, NmtState::PreOperational).0, 0x7F);
        assert_eq!(s.request(t, NmtState::PreOperational).0, 0xFF);
        assert_eq!(s.request(t, NmtState::Operational).0, 0x05);
        s.reset();
        assert_eq!(s.request(t, NmtState::Operational).0, 0x05);
    }

    #[test]
    fn life_guarding_fires_after_guard_time_times_factor() {
        let mut s = GuardSlave::default();
        s.configure(Instant::ZERO, Duration::from_millis(100), 3);
        assert_eq!(s.poll_timeout(), None, "starts with the first request");
        s.request(Instant::from_millis(10), NmtState::Operational);
        assert_eq!(s.poll_timeout(), Some(Instant::from_millis(310)));
        assert_eq!(life(&mut s, Instant::from_millis(309)), None);
        assert_eq!(
            life(&mut s, Instant::from_millis(310)),
            Some(LifeEvent::Lost)
        );
        assert_eq!(
            s.request(Instant::from_millis(400), NmtState::Operational)
                .1,
            Some(LifeEvent::Resumed)
        );
    }

    #[test]
    fn master_polls_checks_toggle_and_times_out() {
        let mut m: GuardMaster<4> = GuardMaster::new();
        let n = NodeId::must(7);
        m.guard(Instant::ZERO, n, Duration::from_millis(100), 2);
        let mut reqs = Vec::new();
        let mut evs = Vec::new();
        tick(&mut m, Instant::ZERO, &mut reqs, &mut evs);
        assert_eq!(reqs, [n]);
        m.answer(
            Instant::from_millis(1),
            n,
            NmtState::Operational,
            false,
            |e| evs.push(e),
        );
        assert_eq!(
            evs,
            [GuardEvent::State {
                node: n,
                state: NmtState::Operational
            }]
        );
        evs.clear();
        assert_eq!(m.poll_timeout(), Some(Instant::from_millis(100)));
        tick(&mut m, Instant::from_millis(100), &mut reqs, &mut evs);
        // Same toggle again: the slave's answer was lost or it did not alternate.
        m.answer(
            Instant::from_millis(101),
            n,
            NmtState::Operational,
            false,
            |e| evs.push(e),
        );
        assert_eq!(
            evs,
            [GuardEvent::ToggleError {
                node: n,
                expected: true
            }]
        );
        evs.clear();
        // No valid answer since 1 ms: life time 200 ms → timeout at 201 ms.
        tick(&mut m, Instant::from_millis(200), &mut reqs, &mut evs);
        assert!(evs.is_empty());
        assert_eq!(m.poll_timeout(), Some(Instant::from_millis(201)));
        tick(&mut m, Instant::from_millis(201), &mut reqs, &mut evs);
        assert_eq!(evs, [GuardEvent::Timeout { node: n }]);
    }

    #[test]
    fn two_masters_guarding_one_slave_see_no_toggle_error() {
        // Master X guards at 0, 100, 200 …; master Y at 50, 150, … and 160 (close to X's 200):
        // the slave toggles at every request, X counts Y's requests it observes.
        let n = NodeId::must(7);
        let mut x: GuardMaster<4> = GuardMaster::new();
        let mut slave = GuardSlave::default();
        x.guard(Instant::ZERO, n, Duration::from_millis(100), 3);
        let mut evs = Vec::new();
        let mut t = 0;
        let mut answered = 0;
        for step in 0..40u64 {
            let now = Instant::from_millis(step * 50);
            if step % 2 == 0 {
                let mut asked = Vec::new();
                tick(&mut x, now, &mut asked, &mut evs);
                assert!(!asked.is_empty());
            } else {
                assert!(x.observed_request(n));
            }
            if step % 7 == 3 {
                // Y asks again before the slave answered: two answers follow.
                assert!(x.observed_request(n));
                let (b, _) = slave.request(now, NmtState::Operational);
                x.answer(now, n, NmtState::Operational, b & 0x80 != 0, |e| {
                    evs.push(e)
                });
                answered += 1;
            }
            let (b, _) = slave.request(now, NmtState::Operational);
            x.answer(now, n, NmtState::Operational, b & 0x80 != 0, |e| {
                evs.push(e)
            });
            answered += 1;
            t = step;
        }
        assert!(answered > 40 && t == 39);
        assert!(
            evs.iter().all(|e| matches!(e, GuardEvent::State { .. })),
            "{evs:?}"
        );
        // A node X does not guard is not its business.
        assert!(!x.observed_request(NodeId::must(8)));
    }

    #[test]
    fn re_guarding_keeps_the_toggle_and_a_boot_up_resets_it() {
        let n = NodeId::must(7);
        let mut m: GuardMaster<4> = GuardMaster::new();
        let mut slave = GuardSlave::default();
        let mut evs = Vec::new();
        m.guard(Instant::ZERO, n, Duration::from_millis(100), 3);
        for k in 0..3u64 {
            let now = Instant::from_millis(k * 100);
            tick(&mut m, now, &mut Vec::new(), &mut evs);
            let (b, _) = slave.request(now, NmtState::Operational);
            m.answer(now, n, NmtState::Operational, b & 0x80 != 0, |e| {
                evs.push(e)
            });
            // Re-timed (a configuration run again): the slave's toggle runs on.
            m.guard(now, n, Duration::from_millis(100), 3);
        }
        assert!(evs.iter().all(|e| matches!(e, GuardEvent::State { .. })));
        // The slave reboots: its first answer carries 0, and 1 would be an error.
        m.booted(n);
        tick(&mut m, Instant::from_millis(300), &mut Vec::new(), &mut evs);
        evs.clear();
        m.answer(
            Instant::from_millis(301),
            n,
            NmtState::PreOperational,
            true,
            |e| evs.push(e),
        );
        assert_eq!(
            evs,
            [GuardEvent::ToggleError {
                node: n,
                expected: false
            }]
        );
    }
}
