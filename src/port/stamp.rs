//! The kernel's receive timestamps (`SO_TIMESTAMPNS`) on the runtime's monotonic clock.
//!
//! **Why.** A reader thread that the scheduler holds up for 30 ms hands its frames over 30 ms
//! late; stamped when it reads them, a frame's copy on that port looks 30 ms younger than its
//! twin on the other port. The kernel stamps every frame (a CAN frame, a UDP datagram) when it
//! enters the network stack, before any socket queue: that stamp does not move with the reader.
//!
//! **The rule.** The kernel's stamps are `CLOCK_REALTIME` (wall clock); the runtime's clock is
//! monotonic ([`std::time::Instant`]). After each read the reader takes both clocks once, back
//! to back ([`KernelClock::read`]); a frame stamped `s` arrived `age = wall − s` before the
//! monotonic reading `mono`, so it is put at `mono − age`, and then clamped:
//!
//! - **never after the read** (`mono`): a stamp ahead of the wall clock is no later than the
//!   read that returned it;
//! - **never before the floor**: when the last read that found the socket empty began
//!   ([`KernelClock::drained`]), since everything read after it arrived after that, or until
//!   then the time the socket was opened ([`KernelClock::new`]). When it *began*: a clock read
//!   after the call returned may be late by as long as the thread was held up in between, and
//!   a floor that late would pull the stamps of frames that arrived meanwhile up to it.
//!
//! **A step of the wall clock.** The conversion holds while the wall clock runs with the
//! monotonic one between a frame's arrival and its read (NTP *slewing*, a few hundred parts per
//! million, moves a stamp by microseconds). A *step* (`settimeofday`, an NTP step, a manual
//! `date -s`) between a frame's arrival and its read moves that frame's converted time by the
//! step: a step back makes it younger, at most up to its read time (as if the port had no
//! stamps for that read); a step forward makes it older, at most back to the floor (the reader
//! was behind by no more than that). Frames that arrive after the step convert right again: the
//! clocks are read afresh for every read, so a step spoils at most what was queued across it.
//!
//! **The first stamps.** The kernel stamps on arrival once some socket has asked for stamps;
//! the very first request on a system only schedules that switch (a deferred work item), and a
//! frame read before it ran is stamped as it is read: its time is its read time, as without
//! stamps.
//!
//! **Reading the clocks.** A thread held up between reading the two clocks would shift every
//! stamp of that read by the hold-up; the monotonic clock is read between two readings of the
//! wall clock, and a bracket wider than a few microseconds is tried again ([`KernelClock::read`]).
//!
//! **Memory.** The floor, one instant; a reading is three. No allocation.
//!
//! **The queue behind the reader.** The same control messages carry the socket's count of
//! frames the kernel dropped because its receive queue was full (`SO_RXQ_OVFL`): a reader that
//! fell that far behind lost them, and the port counts them
//! ([`PortCountersSnapshot::rx_overrun`](crate::port::PortCountersSnapshot)) instead of losing
//! them silently. The queue is made [`RX_QUEUE`] bytes long ([`enlarge_queue`]): the kernel's
//! default (about 208 KiB, some 250 datagrams of a UDP bus) fills in a few milliseconds when a
//! bus runs unthrottled, as python-can's UDP bus does on loopback, and in 30 ms of a full
//! 1 Mbit/s CAN bus.

use nix::sys::socket::{getsockopt, setsockopt, sockopt, ControlMessageOwned, RecvMsg};
use std::os::fd::AsFd;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Asks the kernel for a receive timestamp with every frame read from `socket`, and for its
/// count of frames dropped on a full queue (best effort: without it, none are counted).
pub(crate) fn enable(socket: &impl AsFd) -> std::io::Result<()> {
    let _ = setsockopt(socket, sockopt::RxqOvfl, &1);
    setsockopt(socket, sockopt::ReceiveTimestampns, &true).map_err(std::io::Error::from)
}

/// The receive queue a port asks for, in bytes of kernel memory (a frame takes several hundred):
/// a reader the scheduler holds up for a while finds what arrived meanwhile still queued.
pub(crate) const RX_QUEUE: usize = 4 << 20;

/// Makes `socket`'s receive queue [`RX_QUEUE`] bytes long: within the system's limit
/// (`net.core.rmem_max`) as anyone may, past it where the process may (`CAP_NET_ADMIN`).
/// Returns the length the kernel granted.
pub(crate) fn enlarge_queue(socket: &impl AsFd) -> usize {
    let granted = |s| getsockopt(s, sockopt::RcvBuf).unwrap_or(0);
    let _ = setsockopt(socket, sockopt::RcvBuf, &RX_QUEUE);
    // The kernel doubles what it is asked for (its bookkeeping) and reports that.
    if granted(socket) < RX_QUEUE {
        let _ = setsockopt(socket, sockopt::RcvBufForce, &RX_QUEUE);
    }
    granted(socket)
}

/// The room a read's control messages need: the stamp (`struct timespec` in a `cmsghdr`) and
/// the drop count (a `u32` in another).
pub(crate) fn control_space() -> Vec<u8> {
    nix::cmsg_space!(nix::sys::time::TimeSpec, u32)
}

/// The socket's count of frames dropped on a full queue since it was opened, as of the frame
/// read (absent while it is zero).
pub(crate) fn dropped<S>(m: &RecvMsg<'_, '_, S>) -> Option<u32> {
    m.cmsgs().ok()?.find_map(|c| match c {
        ControlMessageOwned::RxqOvfl(n) => Some(n),
        _ => None,
    })
}

/// The kernel's receive timestamp of a message read (since the Unix epoch on the wall clock),
/// if it carries one.
pub(crate) fn of_message<S>(m: &RecvMsg<'_, '_, S>) -> Option<Duration> {
    m.cmsgs().ok()?.find_map(|c| match c {
        ControlMessageOwned::ScmTimestampns(t) => {
            // Before 1970 (a wall clock set wrong): nothing to go by.
            let secs = u64::try_from(t.tv_sec()).ok()?;
            let nanos = u32::try_from(t.tv_nsec()).ok()?;
            Some(Duration::new(secs, nanos))
        }
        _ => None,
    })
}

/// Brackets of the two clocks tried at most per reading (see [`KernelClock::read`]).
const TRIES: usize = 4;
/// A bracket this tight is taken at once: three clock reads take well under a microsecond
/// when the thread is not held up.
const TIGHT: Duration = Duration::from_micros(20);

/// A socket's side of the conversion: the floor (the last read that found it empty, or when
/// it was opened).
#[derive(Clone, Copy, Debug)]
pub(crate) struct KernelClock {
    floor: Instant,
}

impl KernelClock {
    /// For a socket about to be opened: nothing it reads arrived before now.
    pub(crate) fn new() -> Self {
        KernelClock {
            floor: Instant::now(),
        }
    }
    /// Both clocks, read now: call it right after a read returned.
    ///
    /// The two are read one after the other, and a thread held up in between (a loaded
    /// machine) would see them that far apart: every stamp of the read would be off by as
    /// much. So the monotonic clock is read between two readings of the wall clock, up to
    /// [`TRIES`] times, and the tightest bracket kept (its wall time the middle of the two).
    pub(crate) fn read(&self) -> Reading {
        let wall = || {
            SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .unwrap_or(Duration::ZERO)
        };
        self.read_with(wall, Instant::now)
    }

    /// [`KernelClock::read`] with the clocks given.
    fn read_with(
        &self,
        mut wall: impl FnMut() -> Duration,
        mut mono: impl FnMut() -> Instant,
    ) -> Reading {
        let mut best: Option<(Duration, Duration, Instant)> = None;
        for _ in 0..TRIES {
            let before = wall();
            let m = mono();
            let after = wall();
            let gap = after.saturating_sub(before);
            if best.is_none_or(|(g, _, _)| gap < g) {
                best = Some((gap, before + gap / 2, m));
            }
            if gap <= TIGHT {
                break;
            }
        }
        let (_, wall, mono) = best.unwrap_or_else(|| (Duration::ZERO, wall(), mono()));
        Reading {
            wall,
            mono,
            floor: self.floor,
        }
    }

    /// A read that began at `at` found the socket empty: later reads return only frames that
    /// arrived after that.
    pub(crate) fn drained(&mut self, at: Instant) {
        self.floor = self.floor.max(at);
    }
}

/// Both clocks at one read, and the floor then.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Reading {
    /// The wall clock, since the Unix epoch.
    wall: Duration,
    /// The monotonic clock: the read time.
    pub(crate) mono: Instant,
    floor: Instant,
}

impl Reading {
    /// The monotonic instant of a frame the kernel stamped `stamp` (since the Unix epoch on the
    /// wall clock), clamped between the floor and the read time.
    pub(crate) fn convert(&self, stamp: Duration) -> Instant {
        let age = self.wall.saturating_sub(stamp);
        let floor = self.floor.min(self.mono);
        match self.mono.checked_sub(age) {
            Some(t) if t >= floor => t,
            // Older than the floor (or than the monotonic clock can show): the floor.
            _ => floor,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);
    /// The wall clock at the readings below: 100,000 s since the epoch.
    const WALL: Duration = Duration::from_secs(100_000);

    fn reading(mono: Instant, floor: Instant) -> Reading {
        Reading {
            wall: WALL,
            mono,
            floor,
        }
    }

    /// A frame the kernel stamped 30 ms before a read (a reader held up that long) is put 30 ms
    /// before the read on the monotonic clock, to the nanosecond.
    #[test]
    fn a_stamp_keeps_its_age_on_the_monotonic_clock() {
        let mono = Instant::now() + Duration::from_secs(10);
        let r = reading(mono, mono - Duration::from_secs(10));
        assert_eq!(r.convert(WALL - 30 * MS), mono - 30 * MS);
        let ns = Duration::from_nanos(1_234_567);
        assert_eq!(r.convert(WALL - ns), mono - ns);
        assert_eq!(r.convert(WALL), mono);
    }

    /// A stamp ahead of the wall clock (it was stepped back between arrival and read) is put at
    /// the read time, never after it.
    #[test]
    fn a_stamp_ahead_of_the_wall_clock_is_the_read_time() {
        let mono = Instant::now() + Duration::from_secs(10);
        let r = reading(mono, mono - Duration::from_secs(10));
        assert_eq!(r.convert(WALL + 5 * MS), mono);
        assert_eq!(r.convert(WALL * 4), mono);
    }

    /// A stamp older than the last read that found the socket empty (the wall clock was stepped
    /// forward meanwhile) is put at that read: the frame came after it.
    #[test]
    fn a_stamp_older_than_the_last_empty_read_is_that_read() {
        let mono = Instant::now() + Duration::from_secs(10);
        let floor = mono - 50 * MS;
        let r = reading(mono, floor);
        // 20 ms old: after the floor, kept.
        assert_eq!(r.convert(WALL - 20 * MS), mono - 20 * MS);
        // 50 ms old: at the floor, kept.
        assert_eq!(r.convert(WALL - 50 * MS), floor);
        // An hour old (a step forward of an hour): the floor.
        assert_eq!(r.convert(WALL - Duration::from_secs(3_600)), floor);
        // The wall clock's epoch, and a stamp older than the monotonic clock can show.
        assert_eq!(r.convert(Duration::ZERO), floor);
        let far = Reading {
            wall: Duration::from_secs(u64::MAX / 4),
            ..r
        };
        assert_eq!(far.convert(Duration::ZERO), floor);
    }

    /// The floor starts when the socket is opened and only rises; a reading carries the floor
    /// at its read, and a floor after the read (it cannot be) is the read time.
    #[test]
    fn the_floor_is_the_latest_empty_read() {
        let before = Instant::now();
        let mut k = KernelClock::new();
        let first = k.read();
        assert!(first.floor >= before && first.floor <= first.mono);
        let t = first.mono;
        k.drained(t + 10 * MS);
        k.drained(t + 5 * MS);
        assert_eq!(k.read().floor, t + 10 * MS);
        let r = reading(t, t + 10 * MS);
        assert_eq!(r.convert(WALL - 30 * MS), t);
        let now = k.read();
        assert!(
            now.wall >= Duration::from_secs(1_600_000_000),
            "wall clock since 1970"
        );
    }

    /// A thread held up between the clock reads (the first bracket 5 ms wide, the second 2 ms)
    /// is read again; the tight third bracket is taken, its wall time the middle of the two.
    #[test]
    fn a_wide_bracket_is_read_again() {
        let base = Instant::now();
        let walls = [0, 5_000, 10_000, 12_000, 20_000, 20_010, 99_999];
        let mut w = walls.iter().map(|us| WALL + Duration::from_micros(*us));
        let mut m = (1..).map(|k| base + k * MS);
        let r = KernelClock::new().read_with(|| w.next().unwrap(), || m.next().unwrap());
        assert_eq!(r.mono, base + 3 * MS);
        assert_eq!(r.wall, WALL + Duration::from_micros(20_005));
        // Four wide brackets: the tightest of them.
        let walls = [0, 9_000, 10_000, 12_000, 20_000, 30_000, 40_000, 47_000];
        let mut w = walls.iter().map(|us| WALL + Duration::from_micros(*us));
        let mut m = (1..).map(|k| base + k * MS);
        let r = KernelClock::new().read_with(|| w.next().unwrap(), || m.next().unwrap());
        assert_eq!(
            (r.mono, r.wall),
            (base + 2 * MS, WALL + Duration::from_millis(11))
        );
    }
}
