//! Lag: how much later one bus's copies are stamped than the other's, measured from twins that
//! cannot alias, and the correction the merger's stamps get from it.
//!
//! With receive timestamps taken where the frames arrived, a port whose *reader* runs behind
//! shows no lag at all: its copies keep their stamps, the merger keeps the other port's copies
//! until they are matched (see [`crate::link::merge`]). A lag remains where the frames really
//! reach the port later (a bridge or a gateway in one bus's path), or where the driver has no
//! timestamps and stamps a frame when it hands it over. Such a lag is measured here and
//! *corrected*: the merger is given each copy of the lagging port stamped as the other port
//! would have stamped it, so its window stays the skew window and twins stay apart from their
//! repeats.
//!
//! # Samples that cannot alias
//!
//! A twin measures the lag only if the merger can stand behind the pairing ([`Sample`]): a
//! **fresh** occurrence (no copy of the same content on either port within the horizon before
//! it, nor before what the other port has handed over so far: a reader running behind has not
//! shown its latest repeats yet) that was the only unmatched copy of its key (among what the
//! other port has handed over up to it). An unchanged repeat (SYNC, a heartbeat, a cyclic PDO
//! whose values do not change) is never a sample: its copy may be paired with the neighbouring
//! occurrence, and a lag measured from it would be the true lag modulo its period. Frames whose
//! content changes (a TIME stamp, a counter, SDO traffic, new process data) measure it. So a
//! network that carries only repeats is never thought to lag.
//!
//! A late sample (a twin beyond the window) is taken only if the port of the later copy was
//! intact from the earlier copy's stamp on: ok or suspect for a lag alone, and not since
//! failed, recovering, nor suspect for errors or (if it has receive timestamps) for silence
//! (see [`crate::link::health`]). Otherwise that port may have lost the earlier occurrence,
//! and its copy be a later one of the same content: when a bus is repaired while the other
//! port's reader runs behind, that reader hands over, after the repair, frames from before
//! it, which the repaired bus never carried. (Without timestamps, a port whose copies come
//! late looks silent until its lag is measured: its silence is the lag to measure.)
//!
//! - A sample that shows at least half the skew window (from a matched twin, or from a fresh
//!   twin beyond the window, whose copy is delivered: it cannot be told from a new occurrence
//!   that the other bus missed) is held; a second one within `hold` that agrees within half a
//!   skew window moves the correction by what it shows. One is not enough: a frame that one bus
//!   missed, whose next occurrence came first on that bus, looks exactly like one, and so does a
//!   frame of a queue that drained at once (without timestamps its hand-over time says
//!   nothing). Matched twins start a correction only from three quarters of the window on:
//!   nearer its middle the window takes the skew as it is (a bus whose frames are sent again
//!   after error frames skews each twin by 0 to 3 ms; taken for a lag of 2.5 ms, the
//!   correction stayed after the errors ended and put twins 5.5 ms apart once the other bus
//!   was the late one), and a lag that drifts is still caught before it leaves the window
//!   (only from twins beyond it, a drift of 20 ms in 8 s let 11 frames through twice). A
//!   correction in force follows the lag in steps of half the window. A correction left
//!   below half the window is none (ordinary skew, not carried into the next lag).
//! - A late sample is not taken when the port of its later copy met a fresh twin within the
//!   window after the earlier copy's stamp: a port hands its copies over in order, so that
//!   port did not lag then, and the earlier copy is the later half of a twin whose first half
//!   that port had before it listened (builds with `alloc`; the bare-metal images leave this
//!   rule out, their flash has no room). (A board that booted between a
//!   frame's copy on one bus and its copy on the other, delayed by retransmissions, paired
//!   that copy with the next occurrence of a cyclic frame: a false lag of 8 ms, and every
//!   SYNC after it dropped as the twin of the one before.)
//! - A twin measures the correction in force when *both* its copies were handed over: the
//!   merger takes no sample against a copy it recorded before the correction last changed
//!   (its stamp was corrected by the old amount). A reader running behind hands its copies
//!   over against such records for as long as it runs behind, and each of them showed the
//!   change once more: on a bus whose retransmissions after error frames skewed twins by 0
//!   to 3 ms, a correction of 2.5 ms taken back was at once counted again, the other way,
//!   and twins 3 ms apart on the wire then fell 5.5 ms apart, beyond the window.
//! - A late sample held for a second one is withdrawn when its copy's own twin comes after
//!   all, on the other port within the window ([`crate::link::dual_bus`]): the
//!   copy it was paired with was an earlier occurrence that this bus missed and its sender
//!   repeated. On a network whose only fresh frames are SDO, a bus that flapped every
//!   millisecond lost the first copy of a request and of its answer, both repeated 5 ms later:
//!   two agreeing late samples, a false lag of 5 ms, and every twin after it came twice.
//! - A late sample whose copy on this port is stamped *earlier* than its twin on the other
//!   port (the other port handed its copy over first although it was on the wire later: this
//!   port's reader runs behind, or its correction is too large) only shrinks this port's
//!   correction, to none at most. It cannot be told from a frame the other bus missed (its
//!   sender's port on that bus not back yet) whose repeat came first on that bus while this
//!   port's reader handed its copies over late; and several senders miss frames at once after
//!   a bus fault, so two such samples can agree. A lag of the other port shows from its own
//!   copies, which come after this port's (with this port's reader further behind than that
//!   lag, only once it catches up). Unless the other copy's stamp is within half the window
//!   before the moment this one was handed over: the two reached this node together, where a
//!   reader running behind would have handed its copy over that much later, so a receive
//!   clock is off (two adapters' crystals drifting apart), and the dual-bus layer hands the
//!   sample over as one that is not late: it moves the correction like any other. (Only
//!   shrinking, a drift of 11 ms built up while the other bus was cut was never measured on a
//!   network whose only fresh frames are SDO: every twin came twice for 0.3 s, until the clock
//!   was resynchronised.) Half, not a whole window: a twin late on *its wire* (retransmissions
//!   behind a node destroying frames) beside a copy whose reader runs behind by about as much
//!   comes with it too; 8.3 ms late against 13 ms behind, 4.7 ms apart, was taken for a clock
//!   8.9 ms off, and the correction then dropped SYNCs and heartbeats as twins of the ones
//!   before. A clock that is off shows with readers that hand copies over promptly.
//!
//! # What comes twice
//!
//! While the lag is corrected, nothing: each copy finds its twin in the skew window. When a lag
//! beyond the window appears (or grows past it from none, or changes by more than the window
//! at once), the copies up to the second fresh sample that measures it may come twice ([`MergeStats::slipped`] counts them):
//! on a network with fresh frames, a few; on a network without any, each copy of a frame that
//! repeats slower than twice the window, until one comes. With receive timestamps on both ports
//! that is only a lag on the wire.
//!
//! # Reports
//!
//! [`LinkEventKind::Lag`] when a port's lag changes by a whole millisecond or more, with the
//! window its twins need (skew window + lag); [`LinkEventKind::LagCleared`] when it falls
//! below half the skew window. A lag beyond `max` makes port health call the port suspect
//! (reason [`PortReason::Lag`](crate::link::events::PortReason::Lag)): it is still used, but
//! its bus is in trouble.
//!
//! # Memory
//!
//! One signed correction, one held sample, the lags last reported: fixed.
//!
//! ```
//! use duocan_core::{Duration, Instant};
//! use duocan_redundancy_core::link::lag::LagMeter;
//! use duocan_redundancy_core::link::merge::Sample;
//! use duocan_redundancy_core::link::outbox::Outbox;
//! use duocan_redundancy_core::LinkEventKind;
//!
//! let ms = Duration::from_millis;
//! let mut lag = LagMeter::new(ms(10), ms(40), ms(300));
//! let mut out = Outbox::new();
//! let t = Instant::from_millis;
//! // Two fresh frames show port 1's copies 25 ms late: the second one sets the correction.
//! let late = Sample { skew: 25_000, late: true };
//! assert!(!lag.sample(t(100), 1, late, &mut out));
//! assert!(lag.sample(t(120), 1, late, &mut out));
//! assert_eq!(lag.lag(1), ms(25));
//! assert_eq!(lag.correct(1, t(200)), t(175));
//! let e = out.pop_event().unwrap();
//! assert_eq!(e.kind, LinkEventKind::Lag { port: 1, lag: ms(25), window: ms(35) });
//! ```

use crate::link::events::{LinkEvent, LinkEventKind};
use crate::link::merge::Sample;
use crate::link::outbox::Outbox;
use duocan_core::{Duration, Instant};

#[cfg(doc)]
use crate::link::merge::MergeStats;

const MS: u64 = 1_000;

/// Whole milliseconds of a lag (µs, bounded by the horizon): in 32 bits, as a 64-bit division
/// would bring the general division routine (almost 1 KB) into a 32-bit device's image.
fn whole_ms(us: u64) -> u32 {
    us.min(u64::from(u32::MAX)) as u32 / MS as u32
}

/// The lag between the two ports' stamps and its correction (see the module documentation).
#[derive(Clone, Debug)]
pub struct LagMeter {
    base: u64,
    max: u64,
    horizon: u64,
    hold: u64,
    /// How much later port 1's copies are stamped than port 0's (µs; negative: port 0's).
    offset: i64,
    /// A late sample (port 1 minus port 0, on top of the offset) waiting for a second one, and
    /// when it came.
    pending: Option<(i64, u64)>,
    /// Per port, the lag last reported (µs).
    reported: [u64; 2],
}

impl LagMeter {
    /// A meter for a skew window `base`, calling a lag beyond `max` (at least `base`) a fault
    /// of the bus, correcting lags up to the horizon (twice `max`); a late sample waits `hold`
    /// (at least 1 ms) for a second one.
    #[must_use]
    pub fn new(base: Duration, max: Duration, hold: Duration) -> Self {
        let base = base.as_micros();
        let max = max.as_micros().max(base);
        LagMeter {
            base,
            max,
            horizon: max.saturating_mul(2),
            hold: hold.as_micros().max(MS),
            offset: 0,
            pending: None,
            reported: [0; 2],
        }
    }

    /// The longest lag corrected, and how long the merger keeps an unmatched copy after it was
    /// handed over: twice the maximum.
    pub fn horizon(&self) -> Duration {
        Duration::from_micros(self.horizon)
    }
    /// How much later port `p`'s (0 or 1; others read port 1) copies are stamped than the
    /// other port's: zero unless a lag was measured.
    pub fn lag(&self, p: usize) -> Duration {
        Duration::from_micros(self.lag_us(p.min(1)))
    }
    fn lag_us(&self, p: usize) -> u64 {
        let o = if p == 1 { self.offset } else { -self.offset };
        o.max(0) as u64
    }
    /// True while port `p` lags (by half the skew window or more).
    #[inline]
    pub fn lagging(&self, p: usize) -> bool {
        self.lag_us(p.min(1)) >= self.base / 2
    }
    /// True while port `p` lags beyond the maximum: a fault of its bus, reported.
    #[inline]
    pub fn beyond(&self, p: usize) -> bool {
        self.lag_us(p.min(1)) > self.max
    }
    /// The time twins may take to come: the skew window plus the larger lag, if a port lags.
    pub fn window(&self) -> Duration {
        let lag = self.lag_us(0).max(self.lag_us(1));
        Duration::from_micros(self.base + if lag >= self.base / 2 { lag } else { 0 })
    }
    /// A stamp of port `p`, as the other port would have stamped the same occurrence.
    #[inline]
    pub fn correct(&self, p: usize, at: Instant) -> Instant {
        let lag = self.lag_us(p.min(1));
        if lag == 0 {
            at
        } else {
            Instant::from_micros(at.as_micros().saturating_sub(lag))
        }
    }

    /// The merger measured `sample` for an arrival on port `p` at `now`. Returns true when the
    /// correction changed (the events are queued).
    pub fn sample(&mut self, now: Instant, p: usize, sample: Sample, out: &mut Outbox) -> bool {
        let p = p.min(1);
        let mut d = if p == 1 { sample.skew } else { -sample.skew };
        if sample.late && sample.skew < 0 {
            // This port's copy came after the other port's, stamped a window or more later:
            // its reader runs behind, or its correction is too large. Only the correction can
            // shrink (to none at most); a lag of the other port shows from its own copies.
            let own = self.lag_us(p) as i64;
            if own == 0 {
                return false;
            }
            d = if p == 1 { d.max(-own) } else { d.min(own) };
        }
        let half = (self.base / 2) as i64;
        let now = now.as_micros();
        // A correction in force moves from half the window; none starts short of 3/4 of it.
        let least = if self.offset == 0 {
            half + half / 2
        } else {
            half
        };
        if !sample.late && d.abs() < least {
            // Ordinary skew: and no confirmation of a held sample either. Nor does a twin
            // short of the window's edge start a correction (see the module documentation).
            return false;
        }
        // A second sample that agrees, in time: one alone may be a frame one bus missed, or a
        // frame of a queue that drained at once (its hand-over times say nothing).
        match self.pending.take() {
            Some((held, at)) if now.saturating_sub(at) <= self.hold && (held - d).abs() < half => {}
            _ => {
                self.pending = Some((d, now));
                return false;
            }
        }
        let h = self.horizon as i64;
        self.offset = (self.offset + d).clamp(-h, h);
        if self.offset.abs() < half {
            // Ordinary skew: no lag, and none left over to add to the next one.
            self.offset = 0;
        }
        self.report(now, out);
        true
    }

    /// The sample held (waiting for a second one that agrees) turned out to be no lag: its
    /// copy had a twin of its own within the window ([`crate::link::dual_bus`]).
    pub(crate) fn withdraw(&mut self) {
        self.pending = None;
    }

    /// Queues the reports of a changed correction.
    fn report(&mut self, at: u64, out: &mut Outbox) {
        for p in 0..2 {
            let (lag, was) = (self.lag_us(p), self.reported[p]);
            let kind = if lag < self.base / 2 {
                if was < self.base / 2 {
                    continue;
                }
                LinkEventKind::LagCleared { port: p as u8 }
            } else {
                if whole_ms(lag) == whole_ms(was) {
                    continue;
                }
                LinkEventKind::Lag {
                    port: p as u8,
                    lag: Duration::from_micros(lag),
                    window: Duration::from_micros(self.base + lag),
                }
            };
            self.reported[p] = lag;
            out.event(LinkEvent {
                at: Instant::from_micros(at),
                kind,
            });
        }
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): a held
    /// sample keeps the time it has left.
    pub fn step_back(&mut self, by: Duration) {
        if let Some((_, at)) = &mut self.pending {
            *at = at.saturating_sub(by.as_micros());
        }
    }
}

#[cfg(test)]
mod tests;
