//! An arrival judged: the rule of the [module documentation](super) applied to one copy — its
//! key's records found, its twin matched or a record made, the verdict returned.

use super::table::{hash, key, MergeFrame};
use super::{Merger, Sample, Trust, Twin, Verdict};
use duocan_core::{Frame, Instant};

impl<const SLOTS: usize> Merger<SLOTS> {
    /// A frame arrived on `port` (0 or 1) at `now`, stamped `now`, on a trusted port: the
    /// merger for a driver without receive timestamps. Times must not go backwards (a caller
    /// whose clock steps back says so first, [`Merger::step_back`]).
    #[inline]
    pub fn arrive(&mut self, now: Instant, port: usize, frame: &Frame) -> Verdict {
        self.arrive_at(now, now, port, frame, Trust::Trusted).0
    }

    /// A frame that arrived on `port` (0 or 1) at `at`, its receive timestamp, handled at `now`;
    /// `trust` says whether the layer trusts the port yet. Returns the verdict, and a lag
    /// sample when the arrival measured one (see the module documentation). A stamp later
    /// than `now` is taken as `now`.
    #[inline]
    pub fn arrive_at(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &Frame,
        trust: Trust,
    ) -> (Verdict, Option<Sample>) {
        self.arrive_any(now, at, port, frame, trust)
    }

    /// [`Merger::arrive_at`] for a frame of either kind (classic, or CAN FD with `fd`).
    #[inline]
    pub(super) fn arrive_any<F: MergeFrame>(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &F,
        trust: Trust,
    ) -> (Verdict, Option<Sample>) {
        self.expire(now);
        self.now = self.now.max(now.as_micros());
        if port > 1 {
            self.stats.bad_port += 1;
            self.stats.delivered += 1;
            return (Verdict::Deliver, None);
        }
        let s = at.min(now).as_micros();
        let trust = match trust {
            // Every record of the other port stamped from a window before this copy is still
            // held (each is kept at least the horizon after its stamp: it was handed over no
            // earlier): that no twin is among them proves the other bus did not carry it.
            Trust::Unproven if now.as_micros() - s < self.horizon.saturating_sub(self.window) => {
                Trust::Trusted
            }
            t => t,
        };
        let (verdict, sample) = self.judge(now.as_micros(), s, port, frame, trust);
        if self.frontier[port] < s {
            self.frontier[port] = s;
        }
        // Its reader's delay: from the stamp as taken, before the correction.
        self.behind[port] = now
            .as_micros()
            .saturating_sub(s.saturating_add(self.corrected[port]));
        match verdict {
            Verdict::Deliver => self.stats.delivered += 1,
            Verdict::Duplicate => self.stats.duplicates += 1,
            Verdict::Late => self.stats.late += 1,
            Verdict::Unproven => self.stats.unproven += 1,
        }
        (verdict, sample)
    }

    /// How far port `p` has handed over its copies at `now` (µs, corrected stamps), as far as
    /// the merger can tell: its newest stamp, or, if it has been quiet since, `now` less how
    /// far behind its reader ran at its newest copy (and less its correction). A port whose
    /// reader runs behind may still hold copies stamped after that: it has not shown them yet.
    #[inline]
    pub(super) fn shown(&self, p: usize, now: u64) -> u64 {
        let reached = now.saturating_sub(self.behind[p] + self.corrected[p]);
        self.frontier[p].max(reached)
    }

    /// Whether port `p`'s reader holds back copies that were on its bus by now: it ran more
    /// than a window behind at its newest copy.
    #[inline]
    fn holds_back(&self, p: usize) -> bool {
        self.behind[p] > self.window
    }

    #[inline]
    fn judge<F: MergeFrame>(
        &mut self,
        now: u64,
        s: u64,
        port: usize,
        frame: &F,
        trust: Trust,
    ) -> (Verdict, Option<Sample>) {
        let other = 1 - port;
        let (hi, lo) = frame.key();
        let hash = frame.hash(hi, lo);
        let shown = self.shown(other, now);
        let fresh = self.recent.observe(hash, s, shown, self.horizon);
        let found = frame.find(&self.table, hi, lo, hash);
        let (mut sample, mut skipped) = (None, false);
        if let Some(slot) = found {
            match self.twin(slot, port, s, shown) {
                Twin::Found(t) => return (Verdict::Duplicate, t),
                Twin::None { skipped: k, seen } => (skipped, sample) = (k, seen),
            }
        }
        // No twin held. Its twin may have been among the copies forgotten...
        if self.recent.twin_forgotten(hash, port, s, self.window) {
            return (Verdict::Late, None);
        }
        // ...or, on a port not proven yet, be no occurrence at all.
        if trust == Trust::Unproven && self.frontier[other] >= s {
            return (Verdict::Unproven, None);
        }
        if skipped {
            self.stats.slipped += 1;
        }
        // Kept while its twin may come; a fresh copy also when the other port seems past it:
        // stamps corrected for a lag that changed come early, and only a kept copy shows it.
        if fresh || self.frontier[other] < s.saturating_add(self.window) {
            self.record(found, frame, hi, lo, hash, port, s, now, fresh);
        }
        (Verdict::Deliver, sample)
    }

    /// Looks for the twin of a copy stamped `s` on `port` among the other port's unmatched
    /// records of `slot` (consumed if found); the other port has handed over its copies up to
    /// `shown` ([`Merger::shown`]).
    #[inline]
    fn twin(&mut self, slot: usize, port: usize, s: u64, shown: u64) -> Twin {
        let sl = self.table.slots[slot];
        if sl.unmatched == 0 || sl.side as usize == port {
            return Twin::None {
                skipped: false,
                seen: None,
            };
        }
        let only = sl.unmatched == 1;
        let mut seen = None;
        let mut skipped = false;
        // Too old: their twins would have come before this copy.
        loop {
            let st = self.table.slots[slot];
            if st.unmatched == 0 {
                return Twin::None { skipped, seen };
            }
            let r = self.ring[st.first as usize];
            if r.at.saturating_add(self.window) > s {
                break;
            }
            // A lagging twin, not the repeat of one this port lost in an outage: this port
            // was receiving after the record's time (an outage leaves it nothing in between),
            // and not on time: a port hands its copies over in order, so one that met a fresh
            // twin within the window after the record's stamp did not lag then (the record is
            // the later half of a twin whose other half this port had before it listened: a
            // board that booted between a frame's two copies). Builds with `alloc` only.
            // And the record is the one copy of its key the other port carried up to this
            // copy: that port holds nothing back, or has handed over everything stamped up to
            // a window before it (a reader running behind may still hold repeats, sent on its
            // bus only while this bus missed them).
            if only
                && r.fresh
                && s - r.at < self.horizon
                && self.frontier[port] > r.at
                && self.late_since(port, r.at)
                && (!self.holds_back(1 - port) || shown.saturating_add(self.window) >= s)
            {
                seen = Some(Sample {
                    skew: (s - r.at) as i64,
                    late: true,
                });
            }
            self.unlink_first(slot);
            self.stats.expired += 1;
            skipped = true;
        }
        // The oldest of the rest, if within the window: repeats that follow each other faster
        // than the skew between the buses are matched in the order each bus kept.
        let st = self.table.slots[slot];
        let r = self.ring[st.first as usize];
        if r.at >= s.saturating_add(self.window) {
            // The other port's copies are all newer: it missed this one, or this port's stamps
            // are corrected for a lag it no longer has (its copies now come early).
            if only && r.fresh && r.at - s < self.horizon {
                seen = Some(Sample {
                    skew: s as i64 - r.at as i64,
                    late: true,
                });
            }
            return Twin::None { skipped, seen };
        }
        let single = only && st.unmatched == 1;
        self.unlink_first(slot);
        let measured = single && r.fresh && self.since_shift(&r, 1 - port);
        #[cfg(feature = "alloc")]
        if measured {
            self.on_time[port] = self.on_time[port].max(s);
        }
        Twin::Found(measured.then(|| Sample {
            skew: s as i64 - r.at as i64,
            late: false,
        }))
    }

    /// Whether record `r` of port `p` was handed over after `p`'s correction last changed: its
    /// stamp is corrected as `p`'s copies are now. One from before measures the change once
    /// more (a reader running behind hands its copies over against the other port's records
    /// made before it: after port 0's correction of 2.5 ms was taken back, two more copies of
    /// port 1 showed the same 2.5 ms, and the correction went as far the other way). Its
    /// hand-over time is kept rounded up to the millisecond: a record handed over within one
    /// after the change is not taken either.
    #[inline]
    fn since_shift(&self, r: &super::Record, p: usize) -> bool {
        let shifted = self.shifted[p];
        shifted == 0 || r.handed() > shifted.saturating_add(1_000)
    }

    /// Whether port `port` met no fresh twin on time after `at` (always, without `alloc`).
    #[inline]
    fn late_since(&self, port: usize, at: u64) -> bool {
        #[cfg(feature = "alloc")]
        return self.on_time[port] <= at;
        #[cfg(not(feature = "alloc"))]
        {
            let _ = (port, at);
            true
        }
    }

    /// Unmatched records of `frame`'s key, with the port holding them.
    pub fn unmatched(&self, frame: &Frame) -> Option<(usize, u16)> {
        let (hi, lo) = key(frame);
        let s = self.table.find(hi, lo, hash(hi, lo))?;
        let slot = &self.table.slots[s];
        (slot.unmatched > 0).then_some((slot.side as usize, slot.unmatched))
    }
}
