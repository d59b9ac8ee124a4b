//! TIME producer and consumer (0x1012: bit 31 consume, bit 30 produce).
//!
//! A [`TimeBase`] ties a time of day to a monotonic [`Instant`], so the time of day at any later
//! instant follows without drift. A standby master consumes TIME into its base and, when it takes
//! over, produces from that same base: the network's clock does not jump.

use crate::cia301::service::ServiceOutput;
use crate::frame::cob_id::CobId;
use crate::frame::instant::{next_on_grid, shift_back, Duration, Instant};
use crate::frame::Malformed;
use crate::frame::{Frame, Id};

const MS_PER_DAY: u64 = 86_400_000;

/// CiA 301 TIME_OF_DAY: milliseconds after midnight (28 bits) and days since 1984-01-01.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct TimeOfDay {
    /// Days since 1984-01-01.
    pub days: u16,
    /// Milliseconds after midnight, < 86,400,000.
    pub ms: u32,
}

impl TimeOfDay {
    /// The six bytes on the wire.
    pub fn to_bytes(self) -> [u8; 6] {
        let ms = (self.ms & 0x0FFF_FFFF).to_le_bytes();
        let d = self.days.to_le_bytes();
        [ms[0], ms[1], ms[2], ms[3], d[0], d[1]]
    }
    /// Decodes six bytes; the 4 reserved bits are ignored, an out-of-range ms value is refused.
    pub fn from_bytes(b: &[u8]) -> Result<TimeOfDay, Malformed> {
        let [a, b1, c, d, e, f] = b else {
            return Err(Malformed::WrongLength {
                expected: 6,
                got: b.len() as u8,
            });
        };
        let ms = u32::from_le_bytes([*a, *b1, *c, *d]) & 0x0FFF_FFFF;
        if ms as u64 >= MS_PER_DAY {
            return Err(Malformed::BadValue { value: *d });
        }
        Ok(TimeOfDay {
            ms,
            days: u16::from_le_bytes([*e, *f]),
        })
    }
    /// Milliseconds since 1984-01-01 00:00.
    pub fn total_ms(self) -> u64 {
        self.days as u64 * MS_PER_DAY + self.ms as u64
    }
    /// From milliseconds since 1984-01-01 (days saturate at 65535).
    #[must_use]
    pub fn from_total_ms(total: u64) -> TimeOfDay {
        TimeOfDay {
            days: (total / MS_PER_DAY).min(u16::MAX as u64) as u16,
            ms: (total % MS_PER_DAY) as u32,
        }
    }
}

/// A time of day anchored to a monotonic instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimeBase {
    at: Instant,
    /// Microseconds since 1984-01-01 at `at`.
    epoch_us: u64,
}

impl TimeBase {
    /// `tod` was the time of day at `at`.
    #[must_use]
    pub fn new(at: Instant, tod: TimeOfDay) -> Self {
        TimeBase {
            at,
            epoch_us: tod.total_ms() * 1_000,
        }
    }
    /// The time of day at `now` (earlier instants clamp to the anchor).
    pub fn at(&self, now: Instant) -> TimeOfDay {
        // Saturating: at the end of time the day count tops out instead of wrapping.
        let us = self.epoch_us.saturating_add((now - self.at).as_micros());
        TimeOfDay::from_total_ms(us / 1_000)
    }
}

/// TIME producer/consumer.
#[derive(Clone, Debug, Default)]
pub struct TimeService {
    cob: CobId,
    id: Option<Id>,
    base: Option<TimeBase>,
    period: Duration,
    next: Option<Instant>,
}

impl TimeService {
    /// Applies 0x1012.
    pub fn configure(&mut self, now: Instant, cob: CobId) {
        self.cob = cob;
        self.id = CobId(cob.0 & !(CobId::INVALID | CobId::BIT30)).can_id();
        self.reschedule(now);
    }
    /// True when bit 31 makes this node a TIME consumer.
    pub fn is_consumer(&self) -> bool {
        self.cob.0 & CobId::INVALID != 0
    }
    /// True when bit 30 makes this node the TIME producer.
    pub fn is_producer(&self) -> bool {
        self.cob.bit30()
    }
    /// The TIME identifier.
    pub fn id(&self) -> Option<Id> {
        self.id
    }
    /// Sets the local clock: `tod` is the time of day at `now`.
    pub fn set(&mut self, now: Instant, tod: TimeOfDay) {
        self.base = Some(TimeBase::new(now, tod));
    }
    /// The local clock, if set (by [`TimeService::set`] or a received TIME).
    pub fn base(&self) -> Option<TimeBase> {
        self.base
    }
    /// Produce TIME every `period` (zero: only on request) while this node is producer.
    pub fn set_period(&mut self, now: Instant, period: Duration) {
        self.period = period;
        self.reschedule(now);
    }
    fn reschedule(&mut self, now: Instant) {
        self.next = (self.is_producer() && !self.period.is_zero()).then(|| now + self.period);
    }
    /// The TIME frame for `now`, if producer with a valid identifier and a clock.
    pub fn frame(&self, now: Instant) -> Option<Frame> {
        if !self.is_producer() {
            return None;
        }
        let tod = self.base?.at(now);
        Some(Frame::from_array(self.id?, tod.to_bytes()))
    }
    /// Next periodic TIME.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next
    }
    /// Periodic production: the TIME due at `now`, if the NMT state allows TIME (the period
    /// runs on either way).
    pub fn handle_timeout<O: ServiceOutput>(&mut self, now: Instant, out: &mut O) {
        let Some(due) = self.next.filter(|t| *t <= now) else {
            return;
        };
        self.next = Some(next_on_grid(due, self.period, now));
        if let Some(f) = self.frame(now) {
            if out.nmt_state().services().time {
                out.send(f);
            }
        }
    }
    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]): the
    /// next TIME keeps its distance, and the time of day goes on from where it was instead of
    /// standing still until the old clock is reached again.
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.next, by);
        if let Some(b) = self.base.as_mut() {
            b.at = b.at - by;
        }
    }
    /// A TIME frame arrived: the local clock follows it when this node consumes TIME.
    pub fn received(&mut self, now: Instant, frame: &Frame) -> Result<TimeOfDay, Malformed> {
        if frame.is_remote() {
            return Err(Malformed::UnexpectedRemote);
        }
        let tod = TimeOfDay::from_bytes(frame.data())?;
        if self.is_consumer() {
            self.base = Some(TimeBase::new(now, tod));
        }
        Ok(tod)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_of_day_bytes_round_trip() {
        let t = TimeOfDay {
            days: 0x3456,
            ms: 0x0123_4567,
        };
        let b = t.to_bytes();
        assert_eq!(b, [0x67, 0x45, 0x23, 0x01, 0x56, 0x34]);
        assert_eq!(TimeOfDay::from_bytes(&b), Ok(t));
        assert!(TimeOfDay::from_bytes(&b[..5]).is_err());
        let bad = TimeOfDay {
            days: 0,
            ms: 86_400_000,
        }
        .to_bytes();
        assert!(TimeOfDay::from_bytes(&bad).is_err());
    }

    #[test]
    fn base_advances_across_midnight() {
        let base = TimeBase::new(
            Instant::from_secs(10),
            TimeOfDay {
                days: 5,
                ms: 86_399_500,
            },
        );
        assert_eq!(
            base.at(Instant::from_millis(10_600)),
            TimeOfDay { days: 6, ms: 100 }
        );
    }

    #[test]
    fn periodic_time_goes_out_where_the_state_allows_it() {
        use crate::cia301::nmt::NmtState;
        use crate::cia301::service::Recorder;
        let mut t = TimeService::default();
        t.configure(Instant::ZERO, CobId(0x4000_0100));
        t.set(Instant::ZERO, TimeOfDay { days: 1, ms: 0 });
        t.set_period(Instant::ZERO, Duration::from_millis(10));
        let mut out = Recorder::new(NmtState::Stopped);
        t.handle_timeout(Instant::from_millis(10), &mut out);
        assert!(out.frames.is_empty());
        assert_eq!(t.poll_timeout(), Some(Instant::from_millis(20)));
        let mut out = Recorder::new(NmtState::Operational);
        t.handle_timeout(Instant::from_millis(20), &mut out);
        assert_eq!(
            out.frames,
            [Frame::from_array(
                Id::Standard(0x100),
                TimeOfDay { days: 1, ms: 20 }.to_bytes()
            )]
        );
        assert!(out.events.is_empty());
    }

    #[test]
    fn consumer_adopts_the_producers_clock() {
        let mut t = TimeService::default();
        t.configure(Instant::ZERO, CobId(0x8000_0100));
        let f = Frame::from_array(
            Id::Standard(0x100),
            TimeOfDay { days: 1, ms: 1000 }.to_bytes(),
        );
        t.received(Instant::from_secs(1), &f).unwrap();
        assert_eq!(
            t.base().unwrap().at(Instant::from_secs(2)),
            TimeOfDay { days: 1, ms: 2000 }
        );
        // Becoming producer continues from the adopted clock.
        t.configure(Instant::from_secs(2), CobId(0x4000_0100));
        assert_eq!(
            t.frame(Instant::from_secs(3)).unwrap().data(),
            &TimeOfDay { days: 1, ms: 3000 }.to_bytes()
        );
    }
}
