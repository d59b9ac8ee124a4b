//! SYNC producer and consumer (0x1005 COB-ID with bit 30 = producer, 0x1006 period in µs,
//! 0x1007 window, 0x1019 counter overflow).
//!
//! The producer runs on a fixed grid: SYNC k is due at start + k·period whatever the driver's
//! latency, so jitter does not accumulate. A period change takes effect from the last SYNC sent.
//! A consumer that becomes the producer (a standby master taking over) continues the grid of the
//! SYNCs it received: the next one is due one period after the last one heard, at once if that
//! is past.

use crate::cia301::service::{ServiceEvent, ServiceOutput};
use crate::frame::cob_id::CobId;
use crate::frame::instant::{next_on_grid, shift_back, Duration, Instant};
use crate::frame::Malformed;
use crate::frame::{Frame, Id};

/// SYNC configuration as the dictionary holds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[non_exhaustive]
pub struct SyncConfig {
    /// 0x1005.
    pub cob_id: CobId,
    /// 0x1006 (µs; 0 = no production).
    pub period: Duration,
    /// 0x1007 (µs; 0 = no window).
    pub window: Duration,
    /// 0x1019 (0 = no counter, 2–240 = counter wraps after this value).
    pub overflow: u8,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl SyncConfig {
    /// The configuration with [`cob_id`](Self::cob_id) replaced.
    #[must_use]
    pub fn with_cob_id(mut self, cob_id: CobId) -> Self {
        self.cob_id = cob_id;
        self
    }
    /// The configuration with [`period`](Self::period) replaced.
    #[must_use]
    pub fn with_period(mut self, period: Duration) -> Self {
        self.period = period;
        self
    }
    /// The configuration with [`window`](Self::window) replaced.
    #[must_use]
    pub fn with_window(mut self, window: Duration) -> Self {
        self.window = window;
        self
    }
    /// The configuration with [`overflow`](Self::overflow) replaced.
    #[must_use]
    pub fn with_overflow(mut self, overflow: u8) -> Self {
        self.overflow = overflow;
        self
    }
}

/// A received or produced SYNC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncTick {
    /// The counter, when SYNC carries one.
    pub counter: Option<u8>,
}

/// SYNC producer and consumer.
#[derive(Clone, Debug, Default)]
pub struct SyncService {
    cfg: SyncConfig,
    id: Option<Id>,
    counter: u8,
    next: Option<Instant>,
    last: Option<Instant>,
}

impl SyncService {
    /// Applies a configuration at `now`. Production starts one period after `now`, or, if SYNC
    /// was already running (produced here, or received from the previous producer), one new
    /// period after the last SYNC (a clean period change; a takeover without a gap).
    pub fn configure(&mut self, now: Instant, cfg: SyncConfig) {
        let was_producing = self.next.is_some() || (self.last.is_some() && !self.is_producer());
        if cfg.overflow != self.cfg.overflow {
            self.counter = 1;
        }
        self.cfg = cfg;
        self.id = cfg.cob_id.can_id();
        self.next = if self.is_producer() && !cfg.period.is_zero() {
            let from = match (was_producing, self.last) {
                (true, Some(last)) => last,
                _ => now,
            };
            Some((from + cfg.period).max(now))
        } else {
            None
        };
        if self.counter == 0 {
            self.counter = 1;
        }
    }

    /// Reset communication: counter back to 1, production restarts from `now`.
    pub fn reset(&mut self, now: Instant, cfg: SyncConfig) {
        self.counter = 1;
        self.next = None;
        self.last = None;
        self.configure(now, cfg);
    }

    /// A producer that knows no grid (it has neither sent nor received a SYNC since its reset)
    /// produces the next one at `now` rather than a period later: a master taking over that
    /// booted after the last SYNC of the one before it cannot continue that grid, and the
    /// consumers have waited the takeover already.
    pub fn start_at_once(&mut self, now: Instant) {
        if self.last.is_none() && self.next.is_some_and(|t| t > now) {
            self.next = Some(now);
        }
    }

    /// The configuration in force.
    pub fn config(&self) -> SyncConfig {
        self.cfg
    }

    /// True when 0x1005 bit 30 makes this node the SYNC producer.
    pub fn is_producer(&self) -> bool {
        self.cfg.cob_id.bit30()
    }

    /// The identifier SYNC uses, if valid.
    pub fn id(&self) -> Option<Id> {
        self.id
    }

    /// Next SYNC due.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.next, by);
        shift_back(&mut self.last, by);
    }

    /// When the last SYNC was produced or received.
    pub fn last(&self) -> Option<Instant> {
        self.last
    }

    /// Produces the SYNC due at `now`, if any: its frame, then [`ServiceEvent::SyncProduced`].
    /// A state without SYNC (stopped) keeps the grid and the counter running silently.
    pub fn handle_timeout<O: ServiceOutput>(&mut self, now: Instant, out: &mut O) {
        if let Some((frame, tick)) = self.produce(now) {
            if out.nmt_state().services().sync {
                out.send(frame);
                out.event(now, ServiceEvent::SyncProduced(tick));
            }
        }
    }

    /// Advances the schedule past `now` and builds the SYNC that was due, if any.
    fn produce(&mut self, now: Instant) -> Option<(Frame, SyncTick)> {
        let due = self.next.filter(|t| *t <= now)?;
        let id = self.id?;
        // More than one period late: keep the phase, drop the backlog (one SYNC, not a burst).
        self.next = Some(next_on_grid(due, self.cfg.period, now));
        self.last = Some(now);
        let tick = self.tick();
        let frame = match tick.counter {
            Some(c) => Frame::from_array(id, [c]),
            None => Frame::from_array(id, []),
        };
        Some((frame, tick))
    }

    fn tick(&mut self) -> SyncTick {
        if self.cfg.overflow < 2 {
            return SyncTick { counter: None };
        }
        let c = self.counter;
        self.counter = if c >= self.cfg.overflow { 1 } else { c + 1 };
        SyncTick { counter: Some(c) }
    }

    /// A frame on the SYNC identifier arrived (consumer side).
    pub fn received(&mut self, now: Instant, frame: &Frame) -> Result<SyncTick, Malformed> {
        if frame.is_remote() {
            return Err(Malformed::UnexpectedRemote);
        }
        let expected = if self.cfg.overflow >= 2 { 1 } else { 0 };
        match frame.data() {
            [] if expected == 0 => {}
            [c] if expected == 1 => {
                self.last = Some(now);
                // A consumer that takes over production continues the counter it heard.
                self.counter = if *c >= self.cfg.overflow || *c == 0 {
                    1
                } else {
                    c + 1
                };
                return Ok(SyncTick { counter: Some(*c) });
            }
            d => {
                return Err(Malformed::WrongLength {
                    expected,
                    got: d.len() as u8,
                })
            }
        }
        self.last = Some(now);
        Ok(SyncTick { counter: None })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg(period_us: u64, overflow: u8) -> SyncConfig {
        SyncConfig {
            cob_id: CobId(0x4000_0080),
            period: Duration::from_micros(period_us),
            window: Duration::ZERO,
            overflow,
        }
    }

    #[test]
    fn counter_runs_1_to_overflow_and_wraps() {
        let mut s = SyncService::default();
        s.configure(Instant::ZERO, cfg(1000, 3));
        let mut got = std::vec::Vec::new();
        let mut t = Instant::ZERO;
        for _ in 0..5 {
            t = s.poll_timeout().unwrap();
            let (f, _) = s.produce(t).unwrap();
            got.push(f.data()[0]);
        }
        assert_eq!(got, [1, 2, 3, 1, 2]);
        assert_eq!(t, Instant::from_millis(5));
    }

    #[test]
    fn a_producer_without_a_grid_starts_at_once_when_asked_one_with_a_grid_keeps_it() {
        // Became producer at 5 ms having heard no SYNC: a period later, unless asked.
        let mut s = SyncService::default();
        s.configure(Instant::from_millis(5), cfg(10_000, 0));
        assert_eq!(s.poll_timeout(), Some(Instant::from_millis(15)));
        s.start_at_once(Instant::from_millis(5));
        assert_eq!(s.poll_timeout(), Some(Instant::from_millis(5)));
        // A consumer that heard SYNC at 2 ms continues that grid: asking changes nothing.
        let mut s = SyncService::default();
        s.configure(
            Instant::ZERO,
            SyncConfig {
                cob_id: CobId(0x80),
                ..cfg(10_000, 0)
            },
        );
        s.received(
            Instant::from_millis(2),
            &Frame::from_array(Id::Standard(0x80), []),
        )
        .unwrap();
        s.configure(Instant::from_millis(5), cfg(10_000, 0));
        assert_eq!(s.poll_timeout(), Some(Instant::from_millis(12)));
        s.start_at_once(Instant::from_millis(5));
        assert_eq!(s.poll_timeout(), Some(Instant::from_millis(12)));
    }

    #[test]
    fn without_counter_sync_is_empty() {
        let mut s = SyncService::default();
        s.configure(Instant::ZERO, cfg(1000, 0));
        let (f, tick) = s.produce(Instant::from_millis(1)).unwrap();
        assert_eq!(f.dlc(), 0);
        assert_eq!(f.id(), Id::Standard(0x80));
        assert_eq!(tick.counter, None);
    }

    #[test]
    fn period_change_counts_from_the_last_sync() {
        let mut s = SyncService::default();
        s.configure(Instant::ZERO, cfg(10_000, 0));
        s.produce(Instant::from_millis(10)).unwrap();
        s.configure(Instant::from_millis(13), cfg(5_000, 0));
        assert_eq!(s.poll_timeout(), Some(Instant::from_millis(15)));
        s.configure(Instant::from_millis(13), cfg(1_000, 0));
        assert_eq!(
            s.poll_timeout(),
            Some(Instant::from_millis(13)),
            "never in the past"
        );
    }

    #[test]
    fn produced_sync_is_sent_then_reported_and_kept_silent_when_stopped() {
        use crate::cia301::nmt::NmtState;
        use crate::cia301::service::Recorder;
        let mut s = SyncService::default();
        s.configure(Instant::ZERO, cfg(1000, 3));
        let mut out = Recorder::new(NmtState::PreOperational);
        s.handle_timeout(Instant::from_millis(1), &mut out);
        assert_eq!(out.frames, [Frame::from_array(Id::Standard(0x80), [1])]);
        assert_eq!(
            out.events,
            [(
                Instant::from_millis(1),
                ServiceEvent::SyncProduced(SyncTick { counter: Some(1) })
            )]
        );
        // Stopped: no SYNC, but the grid and the counter run on.
        let mut out = Recorder::new(NmtState::Stopped);
        s.handle_timeout(Instant::from_millis(2), &mut out);
        assert!(out.frames.is_empty() && out.events.is_empty());
        let mut out = Recorder::new(NmtState::Operational);
        s.handle_timeout(Instant::from_millis(3), &mut out);
        assert_eq!(out.frames, [Frame::from_array(Id::Standard(0x80), [3])]);
    }

    #[test]
    fn consumer_checks_length() {
        let mut s = SyncService::default();
        s.configure(
            Instant::ZERO,
            SyncConfig {
                cob_id: CobId(0x80),
                ..cfg(0, 0)
            },
        );
        let one = Frame::new(Id::Standard(0x80), &[1]).unwrap();
        assert_eq!(
            s.received(Instant::ZERO, &one),
            Err(Malformed::WrongLength {
                expected: 0,
                got: 1
            })
        );
        let none = Frame::new(Id::Standard(0x80), &[]).unwrap();
        assert_eq!(
            s.received(Instant::ZERO, &none),
            Ok(SyncTick { counter: None })
        );
    }
}
