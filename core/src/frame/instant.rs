//! Time as an input.
//!
//! The core never reads a clock. Every machine is handed the current [`Instant`] by its driver:
//! the simulator's virtual clock or the runtime's monotonic clock. Both are plain microsecond
//! counters, so a failover timing observed in simulation is the exact number the code computed.
//!
//! # The clock contract
//!
//! What a machine does when the time it is given misbehaves. The simulator and the tokio runtime
//! never make it misbehave; an embedded driver's timer may (a wrap, a resynchronised RTC, a
//! glitch), and every machine copes with it in the same way:
//!
//! - **A jump ahead** is time that passed: every timeout due in between fires once; a periodic
//!   producer (heartbeat, SYNC, TIME, event-timer PDOs) sends once, not a burst of the periods it
//!   missed, and keeps its phase.
//! - **A step back** is noticed on the next input that carries the earlier time (a frame, a
//!   `handle_timeout`, a boot; [`TimeWatch`] does the noticing). The machine then moves every time
//!   it holds — deadlines, "last sent", "last heard" — back by the size of the step: no timer
//!   gains or loses remaining time, as if the clock had always read the new way. A glitch to one
//!   hour ahead and back costs one period of each service, not an hour of silence. A driver
//!   whose clock can step back calls `handle_timeout(now)` once after the step, so that a machine
//!   with no traffic re-anchors too.
//! - **[`Instant::MAX`] is the end of time.** A deadline that would fall at or beyond it is
//!   "never": `poll_timeout` does not report it ([`earliest`] and [`earliest_of`] drop it), so a
//!   driver loop at `Instant::MAX` handles what is due once and then waits, instead of spinning on
//!   a deadline that stays due forever.
//!
//! ```
//! use duocan_core::frame::instant::{earliest, shift_back, TimeWatch};
//! use duocan_core::{Duration, Instant};
//!
//! let mut watch = TimeWatch::new();
//! let glitch = Instant::from_secs(3600);
//! assert_eq!(watch.step_back(glitch), None); // a glitch ahead is time that passed
//! let step = watch.step_back(Instant::from_millis(5)); // and back: re-anchor
//! assert_eq!(step, Some(glitch - Instant::from_millis(5)));
//! assert_eq!(watch.step_back(Instant::from_millis(6)), None); // normal again
//!
//! // A heartbeat scheduled 100 ms after the glitch comes 100 ms after the new time.
//! let mut next = Some(glitch + Duration::from_millis(100));
//! shift_back(&mut next, step.unwrap());
//! assert_eq!(next, Some(Instant::from_millis(105)));
//!
//! // Nothing is ever due at the end of time.
//! assert_eq!(earliest(Some(Instant::MAX), None), None);
//! ```

use core::fmt;
use core::ops::{Add, AddAssign, Sub};

/// A point on a monotonic microsecond clock owned by the caller (real or simulated).
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Instant(u64);

/// A span of time in microseconds.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Duration(u64);

impl Instant {
    /// The clock's origin (power-on of the simulation, start of the runtime).
    pub const ZERO: Instant = Instant(0);
    /// The far future: later than any deadline a machine can compute.
    pub const MAX: Instant = Instant(u64::MAX);

    /// An instant `us` microseconds after the origin.
    #[must_use]
    pub const fn from_micros(us: u64) -> Self {
        Instant(us)
    }
    /// An instant `ms` milliseconds after the origin.
    #[must_use]
    pub const fn from_millis(ms: u64) -> Self {
        Instant(ms.saturating_mul(1_000))
    }
    /// An instant `s` seconds after the origin.
    #[must_use]
    pub const fn from_secs(s: u64) -> Self {
        Instant(s.saturating_mul(1_000_000))
    }
    /// Microseconds since the origin.
    pub const fn as_micros(self) -> u64 {
        self.0
    }
    /// Time elapsed from `earlier` to `self`, zero if `earlier` is later.
    pub const fn saturating_since(self, earlier: Instant) -> Duration {
        Duration(self.0.saturating_sub(earlier.0))
    }
    /// `self + d`, saturating at [`Instant::MAX`] instead of wrapping.
    #[must_use]
    pub const fn saturating_add(self, d: Duration) -> Instant {
        Instant(self.0.saturating_add(d.0))
    }
    /// `self - d`, saturating at [`Instant::ZERO`].
    #[must_use]
    pub const fn saturating_sub(self, d: Duration) -> Instant {
        Instant(self.0.saturating_sub(d.0))
    }
}

impl Duration {
    /// No time at all.
    pub const ZERO: Duration = Duration(0);
    /// A duration longer than any real one.
    pub const MAX: Duration = Duration(u64::MAX);

    /// `us` microseconds.
    #[must_use]
    pub const fn from_micros(us: u64) -> Self {
        Duration(us)
    }
    /// `ms` milliseconds.
    #[must_use]
    pub const fn from_millis(ms: u64) -> Self {
        Duration(ms.saturating_mul(1_000))
    }
    /// `s` seconds.
    #[must_use]
    pub const fn from_secs(s: u64) -> Self {
        Duration(s.saturating_mul(1_000_000))
    }
    /// Length in microseconds.
    pub const fn as_micros(self) -> u64 {
        self.0
    }
    /// Length in whole milliseconds (rounded down).
    pub const fn as_millis(self) -> u64 {
        div_u64(self.0, 1_000)
    }
    /// True for the zero duration (CiA 301 uses 0 to mean "disabled").
    pub const fn is_zero(self) -> bool {
        self.0 == 0
    }
    /// `self * n`, saturating.
    #[must_use]
    pub const fn saturating_mul(self, n: u64) -> Duration {
        Duration(self.0.saturating_mul(n))
    }
}

impl Add<Duration> for Instant {
    type Output = Instant;
    fn add(self, d: Duration) -> Instant {
        self.saturating_add(d)
    }
}
impl AddAssign<Duration> for Instant {
    fn add_assign(&mut self, d: Duration) {
        *self = *self + d;
    }
}
impl Sub<Instant> for Instant {
    type Output = Duration;
    fn sub(self, earlier: Instant) -> Duration {
        self.saturating_since(earlier)
    }
}
impl Sub<Duration> for Instant {
    type Output = Instant;
    fn sub(self, d: Duration) -> Instant {
        self.saturating_sub(d)
    }
}
impl Add for Duration {
    type Output = Duration;
    fn add(self, o: Duration) -> Duration {
        Duration(self.0.saturating_add(o.0))
    }
}
impl Sub for Duration {
    type Output = Duration;
    fn sub(self, o: Duration) -> Duration {
        Duration(self.0.saturating_sub(o.0))
    }
}

impl From<core::time::Duration> for Duration {
    /// Whole microseconds (saturating): seconds and the sub-second part apart, as `as_micros`
    /// would divide 128 bits, a library call on every frame of a runtime reading its clock.
    fn from(d: core::time::Duration) -> Self {
        Duration(
            d.as_secs()
                .saturating_mul(1_000_000)
                .saturating_add(u64::from(d.subsec_micros())),
        )
    }
}
impl From<Duration> for core::time::Duration {
    fn from(d: Duration) -> Self {
        core::time::Duration::from_micros(d.0)
    }
}

/// Formats as seconds with microsecond precision, e.g. `12.000150s`: the unit every timeline uses.
impl fmt::Display for Instant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:06}s", self.0 / 1_000_000, self.0 % 1_000_000)
    }
}
impl fmt::Debug for Instant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}
impl fmt::Display for Duration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_multiple_of(1_000) {
            write!(f, "{}ms", self.0 / 1_000)
        } else {
            write!(f, "{}.{:03}ms", self.0 / 1_000, self.0 % 1_000)
        }
    }
}
impl fmt::Debug for Duration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// Earliest of two optional deadlines: what a composite machine reports from its parts. A
/// deadline at [`Instant::MAX`] is "never" (the clock contract) and is dropped.
#[inline]
pub fn earliest(a: Option<Instant>, b: Option<Instant>) -> Option<Instant> {
    earliest_of([a, b])
}

/// Earliest of any number of optional deadlines: a machine lists its named timers in one array
/// (`earliest_of([self.retry, self.timeout, …])`), so that its next deadline is computed in one
/// place and a new timer is one more element. No allocation; an array folds like a written-out
/// chain of [`earliest`]. A deadline at [`Instant::MAX`] is "never" and is dropped.
#[inline]
pub fn earliest_of(deadlines: impl IntoIterator<Item = Option<Instant>>) -> Option<Instant> {
    // "Never" is the latest instant while folding: one comparison a deadline, no branches on
    // which of two are set (a fraction of the code where every machine folds its timers).
    let t = deadlines
        .into_iter()
        .fold(Instant::MAX, |m, d| m.min(d.unwrap_or(Instant::MAX)));
    (t != Instant::MAX).then_some(t)
}

/// The next instant of a periodic schedule after the one `due` was handled at `now`: the next
/// point of the grid `due + k × period` (k ≥ 1) later than `now`. A driver that was late by more
/// than a period gets one send and the phase kept, not a burst of the periods it missed (the
/// clock contract's jump ahead). A zero period counts as 1 µs.
#[inline]
#[must_use]
pub fn next_on_grid(due: Instant, period: Duration, now: Instant) -> Instant {
    let next = due + period;
    if next > now {
        return next;
    }
    let p = period.as_micros().max(1);
    let behind = div_u64((now - due).as_micros(), p);
    due + Duration::from_micros(p).saturating_mul(behind + 1)
}

/// `n / d` for `d > 0`, exact. A 64-bit target divides; a 32-bit one (a microcontroller, whose
/// processor divides 32-bit numbers at most) divides in 32 bits when both fit and otherwise by
/// shifting and subtracting ([`div_u64_by_shifts`]), which keeps the general 64-bit division
/// routine (almost 1 KB of code) out of the image. Each use is off the per-frame path.
#[inline]
const fn div_u64(n: u64, d: u64) -> u64 {
    if cfg!(target_pointer_width = "64") {
        n / d
    } else if n >> 32 == 0 && d >> 32 == 0 {
        (n as u32 / d as u32) as u64
    } else {
        div_u64_by_shifts(n, d)
    }
}

/// `n / d` for `d > 0` by long division in base 2: one step per bit of the quotient.
const fn div_u64_by_shifts(n: u64, d: u64) -> u64 {
    if d > n {
        return 0;
    }
    // `d` aligned under the highest bit of `n`; the quotient has `shift + 1` bits.
    let shift = d.leading_zeros() - n.leading_zeros();
    let mut d = d << shift;
    let mut r = n;
    let mut q = 0;
    let mut i = 0;
    while i <= shift {
        q <<= 1;
        if r >= d {
            r -= d;
            q |= 1;
        }
        d >>= 1;
        i += 1;
    }
    q
}

/// Notices the caller's clock stepping back: a machine keeps one and asks it on every input that
/// carries a time (the clock contract above). One comparison per input; no allocation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TimeWatch {
    latest: Instant,
}

impl TimeWatch {
    /// A watch that has seen no time yet.
    #[must_use]
    pub const fn new() -> Self {
        TimeWatch {
            latest: Instant::ZERO,
        }
    }
    /// Records `now`; when it is earlier than the latest time seen before, returns by how much the
    /// caller's clock stepped back (the machine moves every time it holds back by as much). From
    /// then on `now` is the latest time.
    #[inline]
    #[must_use]
    pub fn step_back(&mut self, now: Instant) -> Option<Duration> {
        let back = (now < self.latest).then(|| self.latest - now);
        self.latest = now;
        back
    }
    /// The latest time seen.
    pub const fn latest(&self) -> Instant {
        self.latest
    }
}

/// Moves a held time (a deadline, a "last sent") back with a clock that stepped back `by`
/// (saturating at [`Instant::ZERO`]): the time still to run, or run already, stays the same.
#[inline]
pub fn shift_back(t: &mut Option<Instant>, by: Duration) {
    if let Some(t) = t {
        *t = *t - by;
    }
}

#[cfg(test)]
mod tests {
    /// A standard duration is its whole microseconds, saturating, as `as_micros` gives them.
    #[test]
    fn a_std_duration_is_its_whole_microseconds() {
        let max_secs = u64::MAX / 1_000_000;
        for (secs, nanos) in [
            (0, 0),
            (0, 999),
            (0, 1_000),
            (1, 1_999),
            (3, 999_999_999),
            (max_secs, 551_615_999),
            (max_secs, 551_616_000),
            (max_secs, 999_999_999),
            (u64::MAX, 999_999_999),
        ] {
            let d = core::time::Duration::new(secs, nanos);
            let want = u64::try_from(d.as_micros()).unwrap_or(u64::MAX);
            assert_eq!(super::Duration::from(d).as_micros(), want, "{d:?}");
        }
    }

    #[test]
    fn division_by_shifts_is_exact() {
        use super::div_u64_by_shifts as div;
        let edges = [
            1,
            2,
            3,
            7,
            999,
            1_000,
            1_001,
            u32::MAX as u64,
            1 << 32,
            u64::MAX / 3,
        ];
        let mut rng = fastrand::Rng::with_seed(11);
        for _ in 0..20_000 {
            // Every size of dividend and divisor, from one bit to 64.
            let n = rng.u64(..) >> rng.u32(0..64);
            let d = (rng.u64(..) >> rng.u32(0..64)).max(1);
            assert_eq!(div(n, d), n / d, "{n} / {d}");
        }
        for &d in &edges {
            for n in [0, 1, d - 1, d, d + 1, u64::MAX - 1, u64::MAX] {
                assert_eq!(div(n, d), n / d, "{n} / {d}");
            }
        }
        assert_eq!(super::div_u64(u64::MAX, 1_000), u64::MAX / 1_000);
    }

    use super::*;

    #[test]
    fn arithmetic_saturates_instead_of_wrapping() {
        assert_eq!(Instant::MAX + Duration::from_secs(1), Instant::MAX);
        assert_eq!(Instant::ZERO - Duration::from_secs(1), Instant::ZERO);
        assert_eq!(
            Instant::from_millis(5) - Instant::from_millis(7),
            Duration::ZERO
        );
        assert_eq!(
            Instant::from_millis(7) - Instant::from_millis(5),
            Duration::from_millis(2)
        );
    }

    #[test]
    fn display_is_seconds_with_micros() {
        assert_eq!(
            format!("{}", Instant::from_micros(12_000_150)),
            "12.000150s"
        );
        assert_eq!(format!("{}", Duration::from_micros(1_500)), "1.500ms");
        assert_eq!(format!("{}", Duration::from_millis(10)), "10ms");
    }

    #[test]
    fn earliest_picks_the_minimum() {
        let a = Some(Instant::from_millis(3));
        let b = Some(Instant::from_millis(2));
        assert_eq!(earliest(a, b), b);
        assert_eq!(earliest(a, None), a);
        assert_eq!(earliest(None, None), None);
    }

    #[test]
    fn the_end_of_time_is_never_due() {
        let t = |ms| Some(Instant::from_millis(ms));
        assert_eq!(earliest(Some(Instant::MAX), None), None);
        assert_eq!(earliest(Some(Instant::MAX), t(4)), t(4));
        assert_eq!(earliest_of([Some(Instant::MAX), None]), None);
        assert_eq!(earliest_of([Some(Instant::MAX), t(9), t(8)]), t(8));
    }

    #[test]
    fn a_late_periodic_send_keeps_the_phase_and_skips_the_backlog() {
        let ms = Instant::from_millis;
        let p = Duration::from_millis(10);
        assert_eq!(next_on_grid(ms(100), p, ms(100)), ms(110));
        assert_eq!(next_on_grid(ms(100), p, ms(109)), ms(110));
        assert_eq!(next_on_grid(ms(100), p, ms(110)), ms(120));
        assert_eq!(next_on_grid(ms(100), p, ms(3_600_005)), ms(3_600_010));
        assert_eq!(
            next_on_grid(ms(100), Duration::ZERO, ms(100)),
            ms(100) + Duration::from_micros(1)
        );
        assert_eq!(next_on_grid(ms(100), p, Instant::MAX), Instant::MAX);
    }

    #[test]
    fn a_step_back_is_noticed_once_with_its_size() {
        let mut w = TimeWatch::new();
        assert_eq!(w.step_back(Instant::from_millis(10)), None);
        assert_eq!(w.step_back(Instant::from_millis(10)), None);
        assert_eq!(
            w.step_back(Instant::from_millis(9)),
            Some(Duration::from_millis(1))
        );
        assert_eq!(w.step_back(Instant::from_millis(9)), None);
        assert_eq!(w.latest(), Instant::from_millis(9));
        let mut d = Some(Instant::from_secs(100));
        shift_back(&mut d, Duration::from_secs(99));
        assert_eq!(d, Some(Instant::from_secs(1)));
        shift_back(&mut d, Duration::from_secs(99));
        assert_eq!(d, Some(Instant::ZERO), "saturates at the origin");
        let mut none = None;
        shift_back(&mut none, Duration::from_secs(1));
        assert_eq!(none, None);
    }

    #[test]
    fn earliest_of_folds_any_number_of_timers() {
        let t = |ms| Some(Instant::from_millis(ms));
        assert_eq!(earliest_of([t(5), None, t(3), t(4)]), t(3));
        assert_eq!(earliest_of([None, None]), None);
        assert_eq!(earliest_of([] as [Option<Instant>; 0]), None);
        assert_eq!(earliest_of([t(7)]), t(7));
        // Ties and the order of the list do not matter.
        assert_eq!(
            earliest_of([t(2), t(2), None]),
            earliest_of([None, t(2), t(2)])
        );
    }
}
