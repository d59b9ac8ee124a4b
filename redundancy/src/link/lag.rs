//! Lag: how much later one port's copies arrive than the other port's, measured from matched
//! twins; the merge window that follows it; and distrust of a port that lags beyond the maximum.
//!
//! A bus whose frames reach this node late (a driver or gateway queue that runs behind, a
//! loaded segment) makes every twin older than the skew window: each of its copies would come up
//! a second time. The merger keeps unmatched copies recognisable as *late* records up to its
//! horizon (see [`crate::link::merge`]); this part measures the lag the twins show, reports it,
//! sets the merge window and tells the merger which port may match late copies.
//!
//! # Measuring
//!
//! Every twin seen for an arrival on port `p` whose age is known exactly (the only pending copy
//! of its key, or a late copy: [`Twin::lag`]) is a *sample* of `p`'s lag, unless it is out of
//! order: each bus keeps its order, so a twin of a frame more than half a skew window older than
//! one `p` is known to have had already (its own twins, and the other port's twins of its
//! copies, say which) is a copy paired one repeat off, not a lag. Samples below half the skew
//! window are ordinary skew. Of the others, each port keeps the two largest of the current period
//! and of the previous one; periods are `hold` long (the silence limit of port health), one after
//! the other from time zero (a step back of the clock moves them back with it). **The lag of a
//! port is the second largest of those four samples** (zero without two):
//!
//! - it is known at the second sample that shows it, and follows a lag that grows;
//! - it is forgotten between one and two periods after the last sample that showed it;
//! - one sample is not enough: a frame that one bus missed, whose next unchanged repeat comes
//!   first on that bus, looks exactly like one lagging twin.
//!
//! # Unchanged repeats
//!
//! A frame repeated unchanged (cyclic data that does not change, a heartbeat) says nothing about
//! which occurrence a copy is. When a bus comes back from an outage, its first copies of such
//! frames find the other port's copies of *earlier* occurrences, received during the outage,
//! and look exactly like twins lagging by a multiple of their period; so does a lagging bus
//! whose lag is close to such a multiple. Both readings explain the copies, and the one without
//! a lag is kept: a sample taken from the twin of a frame is **withdrawn** when a copy of the
//! same frame arrives on the other port less than half a skew window later (that copy is the
//! real twin, with ordinary skew). Until then the sample counts: a lag shown by two twins is
//! known at once, as above, and is revised when the copies that contradict it come.
//!
//! - A port whose traffic is all unchanged repeats (SRDOs, heartbeats) is therefore never taken
//!   for lagging after an outage, and a failure of the other bus later does not find it
//!   distrusted.
//! - A real lag is still measured from every frame that changes (a counter, new data): only the
//!   samples of the repeats it cannot tell apart are withdrawn, each one exactly (samples are
//!   tagged), and the others keep the lag.
//! - Withdrawing takes a sample out of the two largest of its period; a smaller one it had
//!   displaced is not brought back (the next sample that shows the lag takes its place).
//!
//! # The window
//!
//! A port lags when its lag is at least half the skew window. Its window is then the skew
//! window plus the lag, rounded down to whole milliseconds (so a full skew window is left for
//! jitter on top of the lag), and the skew window otherwise. The merge window is the larger of
//! the two ports' windows; it never goes below the configured skew window. A lagging port
//! matches the other port's late copies (its twins); what it delivered before its lag was known
//! is forgotten.
//!
//! - Up to `max_skew_window` the lagging port stays trusted: both ports deliver whatever comes
//!   first, with the wider window.
//! - Beyond it the port is **distrusted**: port health shows it suspect (reason
//!   [`PortReason::Lag`](crate::link::events::PortReason::Lag)), and its frames only match
//!   twins of the other port's copies, never delivered while the other port is working, unless
//!   the other port is *silent*. Its window (capped at the horizon) still covers its lag, so that
//!   its twins keep being matched and measured. Only one port is distrusted at a time.
//! - The horizon is twice `max_skew_window`: the longest lag that can be measured at all.
//!
//! # Silent
//!
//! For a distrusted port `d`, the other port `g` is silent when it has received nothing for half
//! a skew window (a port receiving now may be behind, the lag having changed sides) and
//!
//! - nothing since the copy that `d`'s last twin was matched with (`d` has caught up with
//!   everything `g` received, so an unmatched frame of `d` was never on `g`), or
//! - nothing for `d`'s window (any copy `g` had of it would have been matched).
//!
//! Then `d`'s unmatched frames are delivered (and not recorded: they have no twin to wait for).
//! So when `g` dies, the frames `d` carries after `g`'s last one are delivered and nothing is lost;
//! a frame that only `g` missed while it kept working is not taken from a bus that lags beyond
//! the maximum. A failed or recovering `g` leaves `d` as the trusted port of port health.
//!
//! # What comes twice: the exact bound
//!
//! With both buses carrying every frame and a lag within the horizon less a skew window (70 ms
//! by default):
//!
//! - Once a port's lag is known, none of its copies is delivered a second time: its twins are
//!   matched in the window or as late records (a late record lasts until ¼ of the merger's slots
//!   of newer records have been made at least: 256 with the default 1024).
//! - Before that, a twin older than the window cannot be told from a new frame: the twins that
//!   show the lag are delivered a second time. A port not known to lag whose lag jumps past the
//!   window costs **exactly two frames**, its first two late twins, and none after
//!   (`MergeStats::slipped` counts them). A port known to lag (at least half a skew window)
//!   matches late twins at once, so a lag that grows further, or that appears below the window
//!   and then grows, costs none. A lag that comes back after it was forgotten costs two again.
//! - When the lag changes sides in one step while the port that lagged beyond the maximum is
//!   still distrusted, the new laggard is silent until its first late frame arrives, and the
//!   frames the distrusted port delivers meanwhile come again from the new laggard: at most the
//!   frames sent during that silence, the new lag.
//! - A frame that repeats unchanged faster than the lag may be paired one occurrence off when the
//!   lag appears (its newer copy is in the window, its twin already late); nothing is lost or
//!   doubled while it keeps repeating, and one copy comes twice when it stops.
//! - After an outage, when the repaired bus's copies of two unchanged repeats both come before
//!   the other bus's copies of them, a lag is known for that moment (see "Unchanged repeats"):
//!   those two repeats come twice, and the lag goes with their twins. When the other bus's
//!   copy comes first (or between them), nothing comes twice.
//! - Beyond the horizon a twin cannot be recognised: every copy of that bus comes twice.
//!
//! Nothing is lost in any of these cases: a copy is dropped only as the twin of one delivered, or,
//! from a distrusted port, while the other port delivers.
//!
//! # Reports
//!
//! [`LinkEventKind::Lag`] whenever a port's window changes (it starts lagging, or its lag moves
//! by whole milliseconds, or it becomes distrusted or trusted again), with the lag and the window;
//! [`LinkEventKind::LagCleared`] when it no longer lags. Distrust and trust show as port-state
//! changes too. Changes found when a period ends carry that instant.
//!
//! # Memory
//!
//! Four samples (with their tags), a window and a flag per port, and the samples of the last
//! half skew window with their frames ([`recent::RECENT`] per port; a newer one takes the place
//! of the oldest, which then stays): fixed.
//!
//! ```
//! use duocan::{Duration, Instant};
//! use duocan_redundancy::link::lag::LagMeter;
//! use duocan_redundancy::link::outbox::Outbox;
//! use duocan_redundancy::LinkEventKind;
//!
//! let ms = Duration::from_millis;
//! let mut lag = LagMeter::new(ms(10), ms(40), ms(300));
//! let mut out = Outbox::new();
//! let t = Instant::from_millis;
//! // Port 1's twins come 12 ms late: the second one sets its lag and widens the window.
//! assert!(!lag.sample(t(100), 1, ms(12), &mut out));
//! assert!(lag.sample(t(120), 1, ms(12), &mut out));
//! assert_eq!((lag.lag(1), lag.window()), (ms(12), ms(22)));
//! assert!(!lag.distrusted(1));
//! let e = out.pop_event().unwrap();
//! assert_eq!(e.kind, LinkEventKind::Lag { port: 1, lag: ms(12), window: ms(22) });
//! ```

use crate::link::events::{LinkEvent, LinkEventKind};
use crate::link::lag::recent::{Recent, RecentSamples};
use crate::link::outbox::Outbox;
use duocan::frame::instant::next_on_grid;
use duocan::{Duration, Frame, Instant};

pub mod recent;

#[cfg(doc)]
use crate::link::merge::Twin;

const MS: u64 = 1_000;

/// One port's samples and what they made of it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct PortLag {
    /// The two largest samples (µs) of the current period, largest first.
    cur: [u64; 2],
    /// The same for the previous period.
    prev: [u64; 2],
    /// Which samples `cur` and `prev` hold: their tags (0: not withdrawable).
    cur_tag: [u32; 2],
    prev_tag: [u32; 2],
    /// The window as last applied and reported (µs).
    window: u64,
    distrusted: bool,
    /// When the other port's copy of this port's last measured twin arrived (µs).
    last_twin: Option<u64>,
    /// The newest frame this port is known to have received, by its arrival on the other port
    /// (µs): from its own twins, and from the other port's twins of its copies.
    seen: u64,
    /// The samples of the last half skew window, with their frames.
    recent: RecentSamples,
}

impl PortLag {
    fn holds_samples(&self) -> bool {
        self.cur[0] != 0 || self.prev[0] != 0
    }
    /// The second largest of the four samples.
    fn estimate(&self) -> u64 {
        let [a, b] = self.cur;
        let [c, d] = self.prev;
        // Both pairs are sorted: the second largest is the larger of the two runners-up and the
        // smaller of the two leaders.
        a.min(c).max(b).max(d)
    }
}

/// The lag of both ports, the merge window and the distrust of a port lagging beyond the
/// maximum (see the module documentation).
#[derive(Clone, Debug)]
pub struct LagMeter {
    base: u64,
    max: u64,
    horizon: u64,
    hold: u64,
    /// Samples below this are ordinary skew (half the base).
    threshold: u64,
    /// The end of the current period (µs).
    period_end: u64,
    /// The tag of the next withdrawable sample (never 0).
    next_tag: u32,
    ports: [PortLag; 2],
}

impl LagMeter {
    /// A meter for a skew window `base`, widening it up to `max` (at least `base`), forgetting
    /// a lag between one and two `hold` periods after its last sample (`hold` at least 1 ms).
    #[must_use]
    pub fn new(base: Duration, max: Duration, hold: Duration) -> Self {
        let base = base.as_micros();
        let max = max.as_micros().max(base);
        let port = PortLag {
            window: base,
            ..PortLag::default()
        };
        LagMeter {
            base,
            max,
            horizon: max.saturating_mul(2),
            hold: hold.as_micros().max(MS),
            threshold: base / 2,
            period_end: hold.as_micros().max(MS),
            next_tag: 1,
            ports: [port; 2],
        }
    }

    /// How long after its window a copy still finds its twin: twice the maximum window, the
    /// longest lag that can be measured.
    pub fn horizon(&self) -> Duration {
        Duration::from_micros(self.horizon)
    }
    /// The merge window now: the larger of the two ports' windows.
    pub fn window(&self) -> Duration {
        Duration::from_micros(self.ports[0].window.max(self.ports[1].window))
    }
    /// The window port `p`'s lag needs (the skew window when it does not lag).
    pub fn port_window(&self, p: usize) -> Duration {
        Duration::from_micros(self.ports[p.min(1)].window)
    }
    /// The lag of port `p` (0 or 1; others read port 1): zero while fewer than two samples show one.
    pub fn lag(&self, p: usize) -> Duration {
        Duration::from_micros(self.ports[p.min(1)].estimate())
    }
    /// True while port `p` lags (its window is wider than the skew window).
    #[inline]
    pub fn lagging(&self, p: usize) -> bool {
        self.ports[p.min(1)].window > self.base
    }
    /// True while port `p` lags beyond the maximum window.
    #[inline]
    pub fn distrusted(&self, p: usize) -> bool {
        self.ports[p.min(1)].distrusted
    }

    /// Whether the other port is silent for distrusted port `p` at `now`, given when the other
    /// port last received a frame (see the module documentation).
    pub fn other_silent(&self, now: Instant, p: usize, other_last_rx: Option<Instant>) -> bool {
        let Some(last) = other_last_rx.map(Instant::as_micros) else {
            return true;
        };
        let port = &self.ports[p.min(1)];
        let quiet = now.as_micros().saturating_sub(last);
        // Quiet for half a skew window at least: a port that is receiving now may be the one
        // behind (the lag changed sides) and get this frame in a moment.
        quiet >= self.threshold
            && (port.last_twin.is_some_and(|t| last <= t) || quiet >= port.window)
    }

    /// A twin matched for an arrival on port `p` at `now` came `lag` after the other port's
    /// copy. Returns true when a window or a distrust changed (the events are queued).
    #[inline]
    pub fn sample(&mut self, now: Instant, p: usize, lag: Duration, out: &mut Outbox) -> bool {
        self.sample_inner(now, p, lag, 0, out).1
    }

    /// As [`LagMeter::sample`], for the twin of `frame`: a sample kept is remembered for half a
    /// skew window, during which a copy of the same frame on the other port withdraws it
    /// ([`LagMeter::contradicted`]).
    #[inline]
    pub fn sample_frame(
        &mut self,
        now: Instant,
        p: usize,
        lag: Duration,
        frame: &Frame,
        out: &mut Outbox,
    ) -> bool {
        let tag = self.next_tag;
        let (kept, changed) = self.sample_inner(now, p, lag, tag, out);
        if kept {
            self.next_tag = tag.checked_add(1).unwrap_or(1);
            self.ports[p.min(1)].recent.push(Recent {
                frame: *frame,
                at: now.as_micros(),
                tag,
            });
        }
        changed
    }

    /// True while port `p` holds samples that a copy on the other port may still withdraw.
    #[inline]
    pub fn withdrawable(&self, p: usize) -> bool {
        self.ports[p.min(1)].recent.any()
    }

    /// `frame` arrived on port `q` at `now`: if the other port took a sample from a twin of the
    /// same frame less than half a skew window ago, that twin was an earlier repeat and this
    /// copy is the real one, arriving with it: the sample is withdrawn. Returns true when a
    /// window or a distrust changed (the events are queued).
    pub fn contradicted(
        &mut self,
        now: Instant,
        q: usize,
        frame: &Frame,
        out: &mut Outbox,
    ) -> bool {
        let p = 1 - q.min(1);
        let now_us = now.as_micros();
        let Some(r) = self.ports[p].recent.take(now_us, self.threshold, frame) else {
            return false;
        };
        let mut changed = self.roll(now_us, out).is_some();
        let port = &mut self.ports[p];
        for (lags, tags) in [
            (&mut port.cur, &mut port.cur_tag),
            (&mut port.prev, &mut port.prev_tag),
        ] {
            if let Some(i) = tags.iter().position(|&t| t == r.tag) {
                // Out of the two largest; the runner-up moves up (one it displaced is not
                // brought back: the next sample that shows the lag takes its place).
                if i == 0 {
                    (lags[0], tags[0]) = (lags[1], tags[1]);
                }
                (lags[1], tags[1]) = (0, 0);
                break;
            }
        }
        changed |= self.evaluate(now_us, out);
        changed
    }

    /// The sample: whether it was kept, and whether a window or a distrust changed.
    #[inline]
    fn sample_inner(
        &mut self,
        now: Instant,
        p: usize,
        lag: Duration,
        tag: u32,
        out: &mut Outbox,
    ) -> (bool, bool) {
        let p = p.min(1);
        let (now_us, lag) = (now.as_micros(), lag.as_micros());
        let copy = now_us.saturating_sub(lag);
        // Each bus keeps its order: a twin of a frame older than one this port has already had
        // (by more than the reordering two buses may show) is a copy paired one repeat off, not
        // a lag.
        let in_order = copy.saturating_add(self.threshold) >= self.ports[p].seen;
        let port = &mut self.ports[p];
        port.last_twin = Some(copy);
        port.seen = port.seen.max(copy);
        let other = &mut self.ports[1 - p];
        other.seen = other.seen.max(now_us);
        if lag < self.threshold || !in_order {
            // Ordinary skew (the frequent case), or no lag: nothing to keep.
            return (false, false);
        }
        (true, self.keep(now_us, p, lag, tag, out))
    }

    /// A sample that shows a lag: kept, and what it changes.
    #[cold]
    fn keep(&mut self, now_us: u64, p: usize, lag: u64, tag: u32, out: &mut Outbox) -> bool {
        let mut changed = self.roll(now_us, out).is_some();
        let port = &mut self.ports[p];
        let (cur, tags) = (&mut port.cur, &mut port.cur_tag);
        if lag > cur[0] {
            *cur = [lag, cur[0]];
            *tags = [tag, tags[0]];
        } else if lag > cur[1] {
            cur[1] = lag;
            tags[1] = tag;
        }
        changed |= self.evaluate(now_us, out);
        changed
    }

    /// Ends the periods that are over at `now`. Returns the instant of the last change of a
    /// window or a distrust, if any (the events are queued).
    pub fn handle_timeout(&mut self, now: Instant, out: &mut Outbox) -> Option<Instant> {
        self.roll(now.as_micros(), out).map(Instant::from_micros)
    }

    /// The end of the current period while samples are held (their end changes the lag).
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        let held = self.ports.iter().any(PortLag::holds_samples);
        held.then_some(Instant::from_micros(self.period_end))
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): the
    /// periods and the times of the twins seen move back with it.
    pub fn step_back(&mut self, by: Duration) {
        let by = by.as_micros();
        self.period_end = self.period_end.saturating_sub(by);
        for port in &mut self.ports {
            port.recent.step_back(by);
            port.seen = port.seen.saturating_sub(by);
            if let Some(t) = port.last_twin.as_mut() {
                *t = t.saturating_sub(by);
            }
        }
    }

    /// Moves to the period of `now`, one period end at a time so that each change carries its
    /// instant. At most three rounds: two period ends forget every sample, and then the period
    /// of `now` is computed, not stepped to (a jump ahead costs no round per period missed).
    fn roll(&mut self, now: u64, out: &mut Outbox) -> Option<u64> {
        let mut last = None;
        while self.period_end <= now {
            if !self.ports.iter().any(PortLag::holds_samples) {
                // Nothing left to forget: to the period of `now`, on the same grid.
                let end = Instant::from_micros(self.period_end);
                let hold = Duration::from_micros(self.hold);
                self.period_end = next_on_grid(end, hold, Instant::from_micros(now)).as_micros();
                break;
            }
            let at = self.period_end;
            self.period_end = at.saturating_add(self.hold);
            for port in &mut self.ports {
                port.prev = port.cur;
                port.cur = [0, 0];
                port.prev_tag = port.cur_tag;
                port.cur_tag = [0, 0];
            }
            if self.evaluate(at, out) {
                last = Some(at);
            }
        }
        last
    }

    /// Derives each port's window and distrust from its lag; reports changes at `at`.
    fn evaluate(&mut self, at: u64, out: &mut Outbox) -> bool {
        let mut changed = false;
        for p in 0..2 {
            let other_distrusted = self.ports[1 - p].distrusted;
            let port = &self.ports[p];
            let lag = port.estimate();
            let (window, distrusted) = if lag < self.threshold {
                (self.base, false)
            } else {
                // Whole milliseconds: `as_millis` divides without the 64-bit division routine
                // on a microcontroller.
                let wanted = self
                    .base
                    .saturating_add(Duration::from_micros(lag).as_millis() * MS);
                if wanted <= self.max {
                    (wanted, false)
                } else if other_distrusted {
                    // Only one port can be the backup: this one keeps the maximum.
                    (self.max, false)
                } else {
                    (wanted.min(self.horizon), true)
                }
            };
            if (window, distrusted) == (port.window, port.distrusted) {
                continue;
            }
            let kind = if window == self.base {
                LinkEventKind::LagCleared { port: p as u8 }
            } else {
                LinkEventKind::Lag {
                    port: p as u8,
                    lag: Duration::from_micros(lag),
                    window: Duration::from_micros(window),
                }
            };
            out.event(LinkEvent {
                at: Instant::from_micros(at),
                kind,
            });
            let port = &mut self.ports[p];
            port.window = window;
            port.distrusted = distrusted;
            changed = true;
        }
        changed
    }
}

#[cfg(test)]
mod tests;
