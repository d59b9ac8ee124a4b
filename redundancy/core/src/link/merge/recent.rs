//! What the merger remembers of keys beyond their records: when each was seen last, to tell a
//! *fresh* occurrence (its content not seen on either port within the horizon, counted back
//! from the older of its stamp and how far the other port has handed over its copies) from an
//! unchanged repeat, and when one of its unmatched copies was *forgotten* with its twin still
//! possible.
//!
//! - Only a fresh occurrence can measure a lag: the twin of a repeat may be paired with a
//!   neighbouring occurrence, one period off, and a lag measured from it would be the true lag
//!   modulo the period.
//! - A copy of the other port that comes after its twin was forgotten (a reader further behind
//!   than the horizon) is known for what it is by its key, not by a time alone: frames of other
//!   keys that only its bus carried meanwhile (one bus flooded, the other carrying the traffic)
//!   are not taken for late twins.
//!
//! The table is two-way set-associative, indexed by the key's hash: a key takes the older line
//! of its set, so two keys that repeat side by side keep their lines. A key whose line a third
//! key took since is taken for fresh and forgotten nothing (at worst a lag sample more, checked
//! by the other conditions a sample needs, or a late copy delivered twice). The merger has as
//! many lines as slots, 12 bytes each (the two low bits of the hash a line keeps say whether a
//! copy of the key was forgotten, and on which port). Times are kept in microseconds from a
//! base, in 32 bits: when a time runs the whole of half their range (35 minutes) past the base,
//! the base moves forward to a quarter of the range before it, and every time held moves with
//! it, those older landing on the base: a jump of the clock is never read as a small age, and a
//! copy stamped before a jump that comes after it still finds the mark of its forgotten twin.

#[derive(Clone, Copy, Default)]
struct Line {
    /// The key's hash with its two low bits taken by [`FORGOT`] and [`SIDE`].
    tag: u32,
    /// Microseconds from the base of the key's latest arrival, plus one: 0 is an empty line.
    at: u32,
    /// Microseconds from the base of the newest copy of the key forgotten (valid with
    /// [`FORGOT`]).
    forgot: u32,
}

/// A copy of the key was forgotten.
const FORGOT: u32 = 1;
/// On port 1 (else port 0).
const SIDE: u32 = 2;
const FLAGS: u32 = FORGOT | SIDE;
/// Times run this far past the base at most (half the 32-bit range).
const SPAN: u64 = 1 << 31;

impl Line {
    fn is(&self, hash: u32) -> bool {
        self.at != 0 && (self.tag ^ hash) & !FLAGS == 0
    }
}

pub(super) struct Recent<const LINES: usize> {
    lines: [Line; LINES],
    /// The time (µs) the lines count from.
    base: u64,
}

impl<const LINES: usize> Recent<LINES> {
    /// Sets of two lines; a power of two (the merger's slot count is one).
    const SHIFT: u32 = 64 - (LINES / 2).trailing_zeros();

    pub(super) fn new() -> Self {
        Recent {
            lines: [Line::default(); LINES],
            base: 0,
        }
    }

    /// `at_us` from the base, moving the base first when it is too far past (see
    /// [`Recent::rebase`]); `None` for a time before the base.
    fn rel(&mut self, at_us: u64) -> Option<u32> {
        let d = at_us.checked_sub(self.base)?;
        if d >= SPAN {
            self.rebase(at_us - SPAN / 2);
            return Some((SPAN / 2) as u32);
        }
        Some(d as u32)
    }

    /// As [`Recent::rel`], a time before the base counting as the base: older than anything
    /// held, which is what a forgotten copy's mark and the copies it covers need.
    fn rel_or_base(&mut self, at_us: u64) -> u32 {
        self.rel(at_us).unwrap_or(0)
    }

    /// Moves the base forward to `base`: every time held moves with it, those before it landing
    /// on it (a line stays taken, a mark stays set: a copy stamped before the jump that comes
    /// after it is still known for a late twin). Runs through the table: once per half the
    /// 32-bit range of time, or at a jump of the clock.
    #[cold]
    fn rebase(&mut self, base: u64) {
        let by = base - self.base;
        let back = |t: u32| u32::try_from(u64::from(t).saturating_sub(by)).unwrap_or(0);
        for l in self.lines.iter_mut().filter(|l| l.at != 0) {
            l.at = back(l.at).max(1);
            l.forgot = back(l.forgot);
        }
        self.base = base;
    }

    /// The two lines `hash` may be in.
    #[inline]
    fn set(&mut self, hash: u32) -> &mut [Line] {
        // Multiplicative hashing: the top bits are the best mixed.
        let set = ((hash as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> Self::SHIFT) as usize;
        &mut self.lines[2 * set..2 * set + 2]
    }

    /// The line of `hash`, taking the empty or older line of its set if it has none.
    #[inline]
    fn line(&mut self, hash: u32) -> (&mut Line, bool) {
        let pair = self.set(hash);
        match pair.iter().position(|l| l.is(hash)) {
            Some(i) => (&mut pair[i], true),
            None => {
                let i =
                    usize::from(pair[0].at != 0 && (pair[1].at == 0 || pair[1].at < pair[0].at));
                pair[i] = Line {
                    tag: hash & !FLAGS,
                    ..Line::default()
                };
                (&mut pair[i], false)
            }
        }
    }

    /// A copy of the key `hash` stamped `at_us` arrived while the other port has handed over
    /// its copies stamped up to `reported_us`: returns whether no copy of the key arrived (on
    /// either port) within `horizon_us` before the earlier of the two, nor stamped after it
    /// (the line keeps the newest stamp only), and remembers this one.
    /// (A port whose reader runs behind has not shown its copies of the last moments yet: a
    /// repeat it holds back must not make this copy look fresh.)
    #[inline]
    pub(super) fn observe(
        &mut self,
        hash: u32,
        at_us: u64,
        reported_us: u64,
        horizon_us: u64,
    ) -> bool {
        let Some(now) = self.rel(at_us) else {
            return true;
        };
        let base = self.base;
        let (line, known) = self.line(hash);
        let last = line.at.wrapping_sub(1);
        // What both ports have shown, counted from the base (nothing yet: the base itself).
        let shown = u64::from(now).min(reported_us.saturating_sub(base));
        // A copy stamped before the newest one seen is no fresh occurrence either: what came
        // before it is not known (the line keeps the newest stamp only), and it may well be a
        // repeat (a node heard on one bus only, answering beside a node on both, just after
        // the twin of the other's answer).
        let fresh = !known || (now >= last && shown.saturating_sub(u64::from(last)) > horizon_us);
        line.at = line.at.max(now + 1);
        fresh
    }

    /// A copy of the key `hash` on port `side`, stamped `at_us`, was forgotten while its twin
    /// could still come.
    pub(super) fn forgot(&mut self, hash: u32, side: usize, at_us: u64) {
        let stamp = self.rel_or_base(at_us);
        let (line, known) = self.line(hash);
        if !known {
            line.at = stamp + 1;
        }
        line.forgot = stamp;
        line.tag = (line.tag & !FLAGS) | FORGOT | if side == 1 { SIDE } else { 0 };
    }

    /// Whether a copy of the key `hash` stamped `at_us` on port `port` may be the twin of a copy
    /// the other port forgot: its stamp is no later than the newest forgotten one's plus
    /// `window_us`.
    #[inline]
    pub(super) fn twin_forgotten(
        &mut self,
        hash: u32,
        port: usize,
        at_us: u64,
        window_us: u64,
    ) -> bool {
        let now = self.rel_or_base(at_us);
        let Some(line) = self.set(hash).iter().find(|l| l.is(hash)) else {
            return false;
        };
        let side = usize::from(line.tag & SIDE != 0);
        line.tag & FORGOT != 0
            && side != port
            && u64::from(now) < u64::from(line.forgot) + window_us
    }

    /// The caller's clock stepped back `by_us`: every time held moves back with it.
    pub(super) fn step_back(&mut self, by_us: u64) {
        match self.base.checked_sub(by_us) {
            Some(b) => self.base = b,
            // Older than the origin: nothing held can be placed.
            None => *self = Recent::new(),
        }
    }
}
