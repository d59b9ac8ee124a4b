//! Heartbeat producer (0x1017) and consumer (0x1016).
//!
//! The consumer keeps a deadline per monitored node and reports a timeout at exactly
//! last heartbeat + consumer time: no scan period is added, the driver is woken at the deadline.

use crate::cia301::nmt::NmtState;
use crate::cia301::service::{ServiceEvent, ServiceOutput};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{next_on_grid, shift_back, Duration, Instant};
use crate::od::abort::AbortCode;

/// Produces the heartbeat on a fixed grid (no drift: the next beat is scheduled from the previous
/// schedule, not from when the driver happened to call). A node beats at once on an NMT state
/// change and on a new producer time ([`beat_now`](Self::beat_now)), and the grid restarts there.
#[derive(Clone, Debug, Default)]
pub struct HeartbeatProducer {
    period: Duration,
    next: Option<Instant>,
}

impl HeartbeatProducer {
    /// (Re)starts with `period` from `now`; a zero period disables it. Writing 0x1017 lands here.
    pub fn restart(&mut self, now: Instant, period: Duration) {
        self.period = period;
        self.next = if period.is_zero() {
            None
        } else {
            Some(now + period)
        };
    }
    /// A heartbeat goes out now (the caller sends it) and the grid restarts from `now`: after
    /// an NMT state change or a new producer time. Returns false when no heartbeat is produced
    /// (period zero).
    pub fn beat_now(&mut self, now: Instant) -> bool {
        if self.period.is_zero() {
            return false;
        }
        self.next = Some(now + self.period);
        true
    }
    /// Stops producing.
    pub fn stop(&mut self) {
        self.next = None;
    }
    /// The configured period.
    pub fn period(&self) -> Duration {
        self.period
    }
    /// When the next heartbeat is due.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }
    /// Asks for the heartbeat if it is due at `now` and the NMT state allows error control; the
    /// schedule advances either way (a node that is stopped keeps its grid).
    pub fn handle_timeout<O: ServiceOutput>(&mut self, now: Instant, out: &mut O) {
        if self.due(now) && out.nmt_state().services().error_control {
            out.event(now, ServiceEvent::HeartbeatDue);
        }
    }
    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.next, by);
    }
    /// True if a heartbeat is due at `now`; advances the schedule.
    pub fn due(&mut self, now: Instant) -> bool {
        match self.next {
            Some(t) if t <= now => {
                // A driver late by more than a period: the phase is kept, the backlog skipped.
                self.next = Some(next_on_grid(t, self.period, now));
                true
            }
            _ => false,
        }
    }
}

/// A 0x1016 sub-entry value: node-ID in bits 16–23, time in ms in bits 0–15.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConsumerSetting {
    /// Monitored node (`None`: entry unused).
    pub node: Option<NodeId>,
    /// Consumer time (zero: entry unused).
    pub time: Duration,
}

impl ConsumerSetting {
    /// Decodes the 0x1016 sub-entry format.
    #[must_use]
    pub fn from_u32(v: u32) -> Self {
        ConsumerSetting {
            node: NodeId::new(((v >> 16) & 0xFF) as u8),
            time: Duration::from_millis((v & 0xFFFF) as u64),
        }
    }
    /// Encodes to the 0x1016 sub-entry format.
    pub fn to_u32(self) -> u32 {
        let node = self.node.map(NodeId::raw).unwrap_or(0) as u32;
        let ms = self.time.as_millis().min(0xFFFF) as u32;
        (node << 16) | ms
    }
    /// True when the entry monitors something.
    pub fn active(&self) -> bool {
        self.node.is_some() && !self.time.is_zero()
    }
}

/// What the consumer reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConsumerEvent {
    /// No heartbeat for the consumer time. `last` is the last heartbeat; the event fires at
    /// `last + time` exactly.
    Timeout {
        /// The silent node.
        node: NodeId,
        /// When it was last heard.
        last: Instant,
    },
    /// A heartbeat arrived after a timeout.
    Resumed {
        /// The node heard again.
        node: NodeId,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Watch {
    /// Configured; monitoring starts with the first heartbeat (CiA 301).
    Waiting,
    /// Heard; times out at `last + time`.
    Running,
    /// Timed out; waiting to be heard again.
    Lost,
}

/// 16 bytes: a no_std node carries 127 of these.
#[derive(Clone, Copy, Debug)]
struct Entry {
    last: Instant,
    time_ms: u16,
    node: NodeId,
    sub: u8,
    watch: Watch,
}

impl Entry {
    fn deadline(&self) -> Instant {
        self.last + Duration::from_millis(self.time_ms as u64)
    }
}

/// Heartbeat consumer for up to `N` producers (CiA 301 allows 127).
#[derive(Clone, Debug)]
pub struct HeartbeatConsumer<const N: usize> {
    entries: heapless::Vec<Entry, N>,
    /// node-ID → entry index + 1 (0 = not monitored): O(1) per received heartbeat.
    by_node: [u8; 128],
    next: Option<Instant>,
}

impl<const N: usize> Default for HeartbeatConsumer<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> HeartbeatConsumer<N> {
    /// An empty table.
    #[must_use]
    pub const fn new() -> Self {
        HeartbeatConsumer {
            entries: heapless::Vec::new(),
            by_node: [0; 128],
            next: None,
        }
    }

    /// Applies 0x1016 sub `sub` = `setting`. A second active entry for the same node is refused
    /// with 0x06040043 (CiA 301); capacity exhaustion with 0x05040005.
    pub fn configure(&mut self, sub: u8, setting: ConsumerSetting) -> Result<(), AbortCode> {
        if let Some(node) = setting.node.filter(|_| setting.active()) {
            if let Some(e) = self.entry_of(node) {
                if e.sub != sub {
                    return Err(AbortCode::PARAMETER_INCOMPATIBLE);
                }
            }
        }
        self.entries.retain(|e| e.sub != sub);
        if let (Some(node), true) = (setting.node, setting.active()) {
            self.entries
                .push(Entry {
                    node,
                    sub,
                    time_ms: setting.time.as_millis().min(u16::MAX as u64) as u16,
                    last: Instant::ZERO,
                    watch: Watch::Waiting,
                })
                .map_err(|_| AbortCode::OUT_OF_MEMORY)?;
        }
        self.reindex();
        Ok(())
    }

    /// Would `configure(sub, setting)` be accepted? (Checked before the dictionary is written.)
    pub fn check(&self, sub: u8, setting: ConsumerSetting) -> Result<(), AbortCode> {
        if let Some(node) = setting.node.filter(|_| setting.active()) {
            if let Some(e) = self.entry_of(node) {
                if e.sub != sub {
                    return Err(AbortCode::PARAMETER_INCOMPATIBLE);
                }
            } else if self.entries.is_full() && !self.entries.iter().any(|e| e.sub == sub) {
                return Err(AbortCode::OUT_OF_MEMORY);
            }
        }
        Ok(())
    }

    /// Removes every entry (reset communication).
    pub fn clear(&mut self) {
        self.entries.clear();
        self.reindex();
    }

    fn reindex(&mut self) {
        self.by_node = [0; 128];
        for (i, e) in self.entries.iter().enumerate() {
            self.by_node[e.node.raw() as usize] = (i + 1) as u8;
        }
        self.recompute_next();
    }

    fn entry_of(&self, node: NodeId) -> Option<&Entry> {
        match self.by_node[node.raw() as usize] {
            0 => None,
            i => self.entries.get(i as usize - 1),
        }
    }

    fn recompute_next(&mut self) {
        self.next = self
            .entries
            .iter()
            .filter(|e| e.watch == Watch::Running)
            .map(Entry::deadline)
            .min();
    }

    /// A heartbeat (or boot-up) of `node` arrived. Returns `Resumed` if it had timed out.
    /// O(1): the cached next deadline is a lower bound that only ever moves earlier here; the
    /// exact minimum is recomputed when it is reached (one scan per expiry, not per heartbeat).
    #[inline]
    pub fn heard(&mut self, node: NodeId, now: Instant) -> Option<ConsumerEvent> {
        let i = match self.by_node[node.raw() as usize] {
            0 => return None,
            i => i as usize - 1,
        };
        let e = &mut self.entries[i];
        let was_lost = e.watch == Watch::Lost;
        e.last = now;
        e.watch = Watch::Running;
        let deadline = e.deadline();
        if self.next.is_none_or(|n| deadline < n) {
            self.next = Some(deadline);
        }
        was_lost.then_some(ConsumerEvent::Resumed { node })
    }

    /// When `handle_timeout` must run next: never later than the earliest deadline (it may be
    /// earlier, after heartbeats moved the earliest entry on; the call then just re-arms).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }

    /// Reports (through `out`) every entry whose deadline is at or before `now`.
    pub fn handle_timeout<O: ServiceOutput>(&mut self, now: Instant, out: &mut O) {
        match self.next {
            Some(n) if n <= now => {}
            _ => return,
        }
        for e in self.entries.iter_mut() {
            if e.watch == Watch::Running && e.deadline() <= now {
                e.watch = Watch::Lost;
                out.event(
                    now,
                    ServiceEvent::Consumer(ConsumerEvent::Timeout {
                        node: e.node,
                        last: e.last,
                    }),
                );
            }
        }
        self.recompute_next();
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        for e in self.entries.iter_mut() {
            e.last = e.last - by;
        }
        // The cached bound moves with the deadlines (as early as it was: the node wakes when it
        // would have on a clock that never stepped), and takes in any it did not cover.
        let moved = self.next.map(|t| t - by);
        self.recompute_next();
        self.next = match (moved, self.next) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
    }

    /// Monitored nodes with their consumer time and whether they are currently lost.
    pub fn monitored(&self) -> impl Iterator<Item = (NodeId, Duration, bool)> + '_ {
        self.entries.iter().map(|e| {
            (
                e.node,
                Duration::from_millis(e.time_ms as u64),
                e.watch == Watch::Lost,
            )
        })
    }

    /// Is any monitored node currently timed out?
    pub fn any_lost(&self) -> bool {
        self.entries.iter().any(|e| e.watch == Watch::Lost)
    }

    /// Is `node` monitored and currently timed out?
    pub fn is_lost(&self, node: NodeId) -> bool {
        self.entry_of(node).is_some_and(|e| e.watch == Watch::Lost)
    }
}

/// The heartbeat payload: the state byte.
pub fn heartbeat_payload(state: NmtState) -> [u8; 1] {
    [state.code()]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia301::service::Recorder;

    /// Runs the consumer's timeout and returns what it reported.
    fn expire<const N: usize>(
        c: &mut HeartbeatConsumer<N>,
        now: Instant,
    ) -> std::vec::Vec<ConsumerEvent> {
        let mut out = Recorder::new(NmtState::Operational);
        c.handle_timeout(now, &mut out);
        out.kinds()
            .into_iter()
            .map(|e| match e {
                ServiceEvent::Consumer(e) => e,
                other => panic!("not a consumer event: {other:?}"),
            })
            .collect()
    }

    fn setting(node: u8, ms: u64) -> ConsumerSetting {
        ConsumerSetting {
            node: NodeId::new(node),
            time: Duration::from_millis(ms),
        }
    }

    #[test]
    fn producer_asks_for_the_heartbeat_only_where_the_state_allows_it() {
        let mut p = HeartbeatProducer::default();
        p.restart(Instant::ZERO, Duration::from_millis(10));
        let mut out = Recorder::new(NmtState::Operational);
        p.handle_timeout(Instant::from_millis(9), &mut out);
        p.handle_timeout(Instant::from_millis(10), &mut out);
        assert_eq!(
            out.events,
            [(Instant::from_millis(10), ServiceEvent::HeartbeatDue)]
        );
        assert!(out.frames.is_empty(), "the identifier is the composer's");
        // Initialising allows no error control: the grid advances, nothing is asked for.
        let mut out = Recorder::new(NmtState::Initialising);
        p.handle_timeout(Instant::from_millis(20), &mut out);
        assert!(out.events.is_empty());
        assert_eq!(p.poll_timeout(), Some(Instant::from_millis(30)));
    }

    #[test]
    fn producer_keeps_its_grid_when_called_late() {
        let mut p = HeartbeatProducer::default();
        p.restart(Instant::ZERO, Duration::from_millis(10));
        assert!(!p.due(Instant::from_millis(9)));
        assert!(p.due(Instant::from_millis(10)));
        assert_eq!(p.poll_timeout(), Some(Instant::from_millis(20)));
        assert!(p.due(Instant::from_millis(35)));
        assert_eq!(p.poll_timeout(), Some(Instant::from_millis(40)));
        p.restart(Instant::from_millis(36), Duration::ZERO);
        assert_eq!(p.poll_timeout(), None);
    }

    #[test]
    fn consumer_times_out_exactly_at_last_plus_time() {
        let mut c: HeartbeatConsumer<4> = HeartbeatConsumer::new();
        c.configure(1, setting(5, 150)).unwrap();
        assert_eq!(
            c.poll_timeout(),
            None,
            "monitoring starts at the first heartbeat"
        );
        c.heard(NodeId::must(5), Instant::from_millis(100));
        assert_eq!(c.poll_timeout(), Some(Instant::from_millis(250)));
        let mut evs = expire(&mut c, Instant::from_micros(249_999));
        assert!(evs.is_empty());
        evs.extend(expire(&mut c, Instant::from_millis(250)));
        assert_eq!(
            evs,
            [ConsumerEvent::Timeout {
                node: NodeId::must(5),
                last: Instant::from_millis(100)
            }]
        );
        assert_eq!(c.poll_timeout(), None, "one timeout per loss");
        assert_eq!(
            c.heard(NodeId::must(5), Instant::from_millis(300)),
            Some(ConsumerEvent::Resumed {
                node: NodeId::must(5)
            })
        );
    }

    #[test]
    fn duplicate_node_is_refused_with_0x06040043() {
        let mut c: HeartbeatConsumer<4> = HeartbeatConsumer::new();
        c.configure(1, setting(5, 150)).unwrap();
        assert_eq!(
            c.configure(2, setting(5, 100)),
            Err(AbortCode::PARAMETER_INCOMPATIBLE)
        );
        c.configure(1, setting(5, 100)).unwrap();
        c.configure(2, setting(6, 100)).unwrap();
        assert_eq!(c.monitored().count(), 2);
        c.configure(2, setting(6, 0)).unwrap();
        assert_eq!(c.monitored().count(), 1);
    }

    #[test]
    fn cached_deadline_is_a_lower_bound_re_armed_on_expiry() {
        let mut c: HeartbeatConsumer<4> = HeartbeatConsumer::new();
        c.configure(1, setting(1, 100)).unwrap();
        c.configure(2, setting(2, 50)).unwrap();
        c.heard(NodeId::must(1), Instant::ZERO);
        c.heard(NodeId::must(2), Instant::ZERO);
        assert_eq!(c.poll_timeout(), Some(Instant::from_millis(50)));
        c.heard(NodeId::must(2), Instant::from_millis(40));
        // A lower bound: waking at 50 ms finds nothing due and re-arms at the true minimum.
        assert_eq!(c.poll_timeout(), Some(Instant::from_millis(50)));
        let mut fired = expire(&mut c, Instant::from_millis(50)).len();
        assert_eq!(fired, 0);
        assert_eq!(c.poll_timeout(), Some(Instant::from_millis(90)));
        c.heard(NodeId::must(2), Instant::from_millis(80));
        fired += expire(&mut c, Instant::from_millis(90)).len();
        assert_eq!(fired, 0);
        assert_eq!(c.poll_timeout(), Some(Instant::from_millis(100)));
    }
}
