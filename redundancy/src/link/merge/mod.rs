//! The receive merger: every frame *occurrence* sent on both buses is delivered exactly once.
//!
//! # The rule
//!
//! Frames carry no sequence number and identical frames legitimately repeat (heartbeats, cyclic
//! PDOs with unchanged values), so "drop a frame equal to one seen recently" loses data. Instead,
//! per key (identifier, RTR, DLC, data) the merger keeps the *unmatched arrivals*: copies that
//! arrived on one port and whose twin has not yet arrived on the other.
//!
//! - An arrival on port `p` when the other port holds an unmatched arrival of the same key is the
//!   twin: it consumes the oldest such record and is dropped ([`Verdict::Duplicate`]).
//! - Otherwise it is delivered ([`Verdict::Deliver`]) and recorded as unmatched for `p`.
//! - A record is matched only while it is younger than the skew window: one arriving at `t`
//!   expires at `t + window`. The window must exceed the worst inter-bus skew.
//!
//! At any time only one port of a key holds records (an arrival on the other would have consumed
//! them), so a key needs a side, a count and a FIFO of arrival times.
//!
//! # A lagging bus: late records
//!
//! A bus that hands its frames over later than the window (a queue that runs behind) would make
//! every twin a new occurrence. A merger built [`with_horizon`](Merger::with_horizon) keeps an
//! unmatched record that leaves the window as a *late* record until the horizon:
//!
//! - an arrival of the other port that finds no live twin but a late record of its key *sees*
//!   it: the record is used up (oldest first), the arrival reports how late it is
//!   ([`Merger::arrive_measured`]) and is delivered and recorded as without a horizon
//!   ([`MergeStats::slipped`]). A lagging twin and the repeat of a frame one bus missed look the
//!   same; delivering keeps the rule's count for the repeat, and costs the lagging twin one
//!   duplicate;
//! - on a port known to lag ([`Merger::set_late_match`], set by the layer from the measured lag,
//!   see [`crate::link::lag`]) it *matches* it instead: a twin, dropped ([`MergeStats::late`]);
//! - a twin's lag is reported exactly when it matched the only pending record of its key (the
//!   newest) or a late one; with several pending, which one is the twin is a convention.
//!
//! Copies of a port whose twins cannot come (the other port failed or recovering: lost, not late)
//! are not kept late ([`Merger::keep_late`]), and a port that turns out to lag forgets what it
//! delivered before ([`Merger::forget`]): those were twins, and no copy of the other port is to
//! come for them. Without a horizon nothing changes.
//!
//! # Memory
//!
//! Records live in one ring in arrival order (so expiry pops from the front and is O(1) per
//! record), keys in a fixed arena indexed by an open-addressing table. A record stores its key's
//! arena slot and the key's arrival sequence number; since records of a key are consumed and
//! expired oldest first, the live records of a key are always its `unmatched` newest ones, and a
//! record at the front of the ring is live exactly when its sequence number is among them. No
//! live record is ever searched for or moved.
//!
//! A `Merger<SLOTS>` has `SLOTS` slots (a power of two) and holds at most [`Merger::capacity`] =
//! ¾·SLOTS records, keeping the table at most ¾ full. Two saturated 1 Mbit/s buses deliver at most
//! about 21,300 frames/s each, i.e. ~430 records in a 10 ms window, which the default
//! `SLOTS = 1024` holds with room to spare. With one bus dead every record expires unmatched after
//! the window, so the occupancy is bounded by the live bus's rate × window: memory is constant by
//! construction.
//!
//! Late records take no memory of their own: they are the ring positions behind its head (at
//! least ¼ of them), the records that left it most recently, until new arrivals overwrite them.
//! A late record keeps its key's slot, which counts its late records; only an arrival whose key
//! has late records of the other port searches for them, behind the head and down to the
//! horizon. When a new key would fill the table beyond ¾, the oldest late records give their
//! slots back. So a late record is recognised until SLOTS − (records held) newer records have
//! been made, and at most until the horizon.
//!
//! # Overflow
//!
//! When the ring is full, the oldest record is evicted before its window ends (counted in
//! [`MergeStats::evicted`] when it was still unmatched). A delivery is never refused: the only
//! possible harm is that the twin of the evicted arrival, arriving later, is delivered as a
//! duplicate (at most one per eviction; with a horizon the evicted record stays recognisable as a
//! late record while the ring has room). Losing a frame is worse than a counted duplicate.
//!
//! # Failed ports
//!
//! The merger itself treats both ports alike. The layer feeds it arrivals from a port that is
//! failed or recovering (while the other port is healthy) through [`Merger::match_only`]: such
//! an arrival may consume a pending twin but is never delivered or recorded, because a repaired
//! segment can first flush frames older than the window, which would otherwise come up a second
//! time (see [`crate::link::health`]). With both ports unhealthy, both deliver normally. A port
//! lagging beyond the maximum window goes through it too (matching late twins).
//!
//! # Order
//!
//! Each occurrence is delivered at its first arrival, so when both buses deliver everything the
//! per-sender order is the order sent (each bus keeps it, and the earlier of two ordered arrival
//! pairs is ordered). When one bus *drops* a frame, two things cannot be told apart by any merger
//! that delivers without waiting, and the sender's order may then differ from the order sent
//! (never the count):
//!
//! - the bus that dropped it is ahead and carries the sender's *next* frame before the dropped
//!   frame arrives on the other bus: the next frame is delivered first;
//! - the bus that dropped it carries a *repeat* of the same frame within the window: the repeat
//!   looks exactly like the lost twin and is matched with it; the repeat itself is delivered
//!   when its own copy arrives on the other bus, possibly after the sender's next frame.
//!
//! A lagging bus that drops frames, a dead bus, or two complete buses keep every sender's order
//! exactly; so does a bus that lags beyond the window while it lags (its copies are all twins,
//! matched or, until its lag is known, delivered a second time after the first). When its lag
//! ends while the layer still distrusts it (see [`crate::link::lag`]) and it then leads by the
//! skew, a frame it had first is taken from the other bus, possibly after the sender's next one.
//! The property tests (`tests/merge_properties.rs`, `tests/lag_properties.rs`) check these
//! statements.

use duocan::{Duration, Frame, Instant};

mod late;

/// What to do with an arrival.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// First copy of an occurrence: deliver it upward.
    Deliver,
    /// Twin of an occurrence already delivered: drop it.
    Duplicate,
}

/// The other port's copy an arrival was matched with, or (late) only seen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Twin {
    /// How long after the other port's copy this one arrived, when that is known exactly: the
    /// copy was the only pending one of its key, or a late one. `None` when several copies of
    /// the key were pending (which of them is the twin is then a convention, not a fact).
    pub lag: Option<Duration>,
    /// The other copy had already left the window: a late copy, within the horizon.
    pub late: bool,
}

/// What a merger has done since it was created.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MergeStats {
    /// Arrivals delivered.
    pub delivered: u64,
    /// Arrivals dropped as twins (late ones included).
    pub duplicates: u64,
    /// Arrivals dropped as twins of a copy that had already left the window (within the
    /// horizon, on a port that may match late copies: see [`Merger::set_late_match`]).
    pub late: u64,
    /// Arrivals delivered although a late copy of them was pending, on a port that may not
    /// match late copies: either a lagging twin (delivered a second time) or a repeat of a
    /// frame the other port missed; the two look the same (see the module documentation).
    pub slipped: u64,
    /// Unmatched records that left the window (their twin had not come: one bus missed the
    /// frame, or lags; with a horizon, a lagging twin may still be matched, see `late`).
    pub expired: u64,
    /// Unmatched records evicted early because the table was full (without a horizon each may
    /// cause one duplicate later; with one, they stay matchable as late records while the ring
    /// has room).
    pub evicted: u64,
    /// Arrivals on a port other than 0 and 1 (delivered, not recorded).
    pub bad_port: u64,
    /// Most records held at once.
    pub high_water: u32,
}

#[derive(Clone, Copy)]
struct Slot {
    hi: u64,
    lo: u64,
    hash: u32,
    /// Arrivals recorded for this key so far (wrapping); the next record gets this number.
    recorded: u16,
    /// Live (unmatched) records: the newest `unmatched` recorded ones.
    unmatched: u16,
    /// Records pointing here, in the ring or late behind it; the slot is freed at zero.
    refs: u16,
    /// Ring position of the newest record: the age of the only live record.
    last_pos: u16,
    /// Late records of this key (all of the port in [`LATE_SIDE`]).
    late: u16,
    /// Bit 0: the port holding the live records; [`LATE_SIDE`]: the port of the late ones.
    flags: u8,
}

/// The bit of [`Slot::flags`] naming the port of the late records.
const LATE_SIDE: u8 = 2;

impl Slot {
    const EMPTY: Slot = Slot {
        hi: 0,
        lo: 0,
        hash: 0,
        recorded: 0,
        unmatched: 0,
        refs: 0,
        last_pos: 0,
        late: 0,
        flags: 0,
    };
    #[inline]
    fn side(&self) -> u8 {
        self.flags & 1
    }
    #[inline]
    fn late_side(&self) -> u8 {
        (self.flags & LATE_SIDE) >> 1
    }
}

/// One arrival: in the ring while its window lasts, then, if unmatched and kept, a *late*
/// record behind the ring (still pointing to its slot) until the horizon or until overwritten.
#[derive(Clone, Copy)]
struct Record {
    at: u64,
    seq: u16,
    slot: u16,
    /// Behind the ring: a late record (its slot counts it in `late` and `refs`).
    late: bool,
}

impl Record {
    const EMPTY: Record = Record {
        at: 0,
        seq: 0,
        slot: 0,
        late: false,
    };
}

/// The active-active receive merger for two ports (0 and 1), with `SLOTS` slots.
///
/// ```
/// use duocan::{Duration, Frame, Id, Instant};
/// use duocan_redundancy::link::merge::{Merger, Verdict};
///
/// let mut m: Merger<64> = Merger::new(Duration::from_millis(10));
/// let hb = Frame::from_array(Id::Standard(0x705), [5]);
/// let t = Instant::from_millis;
/// // Sent twice in a row (a legitimate repeat), seen on both buses with 3 ms of skew.
/// assert_eq!(m.arrive(t(0), 0, &hb), Verdict::Deliver);
/// assert_eq!(m.arrive(t(1), 0, &hb), Verdict::Deliver);
/// assert_eq!(m.arrive(t(3), 1, &hb), Verdict::Duplicate);
/// assert_eq!(m.arrive(t(4), 1, &hb), Verdict::Duplicate);
///
/// // With a horizon, a copy that comes after the window is still recognised and measured;
/// // it is matched once its port is known to lag.
/// let mut m: Merger<64> =
///     Merger::with_horizon(Duration::from_millis(10), Duration::from_millis(80));
/// let tpdo = |v| Frame::from_array(Id::Standard(0x185), [v]);
/// assert_eq!(m.arrive_measured(t(0), 0, &tpdo(1)), (Verdict::Deliver, None));
/// let (verdict, seen) = m.arrive_measured(t(25), 1, &tpdo(1));
/// assert_eq!(verdict, Verdict::Deliver);
/// assert_eq!(seen.and_then(|s| s.lag), Some(Duration::from_millis(25)));
/// m.set_late_match(1, true);
/// assert_eq!(m.arrive(t(40), 0, &tpdo(2)), Verdict::Deliver);
/// assert_eq!(m.arrive(t(65), 1, &tpdo(2)), Verdict::Duplicate);
/// ```
pub struct Merger<const SLOTS: usize> {
    window: u64,
    /// How long an unmatched record stays recognisable behind the ring (0: not at all).
    horizon: u64,
    ring: [Record; SLOTS],
    head: usize,
    len: usize,
    slots: [Slot; SLOTS],
    free: [u16; SLOTS],
    free_len: usize,
    /// Open addressing, linear probing: 0 = empty, else arena slot + 1.
    index: [u16; SLOTS],
    /// Late records behind the ring (those past the horizon included, until overwritten).
    late: usize,
    /// Per port: its unmatched records that arrived from this instant (µs) on are kept as late
    /// records (the other port can deliver their twins); `None`: none are.
    keep_late: [Option<u64>; 2],
    /// Per port: its arrivals may match late records of the other port (it is known to lag);
    /// otherwise they only see them.
    late_match: [bool; 2],
    stats: MergeStats,
}

/// Arena slot numbers are stored as `u16 + 1`.
const MAX_SLOTS: usize = 1 << 15;

impl<const SLOTS: usize> Merger<SLOTS> {
    const CHECK: () = assert!(
        SLOTS.is_power_of_two() && SLOTS >= 4 && SLOTS <= MAX_SLOTS,
        "merger slots must be a power of two between 4 and 32768"
    );
    const CAP: usize = SLOTS - SLOTS / 4;
    const MASK: usize = SLOTS - 1;
    const SHIFT: u32 = 64 - SLOTS.trailing_zeros();

    /// An empty merger matching twins up to `window` apart.
    #[must_use]
    pub fn new(window: Duration) -> Self {
        Self::with_horizon(window, Duration::ZERO)
    }

    /// An empty merger matching twins up to `window` apart, which also recognises a twin that
    /// comes up to `horizon` after its copy on the other port (a lagging bus): see the module
    /// documentation. A horizon not beyond the window is none.
    #[must_use]
    pub fn with_horizon(window: Duration, horizon: Duration) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        let mut free = [0u16; SLOTS];
        // Hand out low slots first (free list is a stack).
        for (i, f) in free.iter_mut().enumerate() {
            *f = (SLOTS - 1 - i) as u16;
        }
        let (window, horizon) = (window.as_micros(), horizon.as_micros());
        Merger {
            window,
            horizon: if horizon > window { horizon } else { 0 },
            ring: [Record::EMPTY; SLOTS],
            head: 0,
            len: 0,
            slots: [Slot::EMPTY; SLOTS],
            free,
            free_len: SLOTS,
            index: [0; SLOTS],
            late: 0,
            keep_late: [Some(0); 2],
            late_match: [false; 2],
            stats: MergeStats::default(),
        }
    }

    /// Records it can hold (¾ of the slots).
    pub const fn capacity(&self) -> usize {
        Self::CAP
    }
    /// Records held now (live or already consumed, until they leave the ring).
    pub fn len(&self) -> usize {
        self.len
    }
    /// True when no record is held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Distinct keys held now.
    pub fn keys(&self) -> usize {
        SLOTS - self.free_len
    }
    /// The skew window.
    pub fn window(&self) -> Duration {
        Duration::from_micros(self.window)
    }
    /// Changes the skew window (applies to records already held, too).
    pub fn set_window(&mut self, window: Duration) {
        self.window = window.as_micros();
    }
    /// How long after its arrival an unmatched record is still recognised by a lagging copy
    /// (zero: not after its window).
    pub fn horizon(&self) -> Duration {
        Duration::from_micros(self.horizon)
    }
    /// Lets arrivals on `port` match late records of the other port (`true`: the port is known
    /// to lag), or only see them (`false`, the default: they are delivered as before).
    pub fn set_late_match(&mut self, port: usize, matches: bool) {
        if let Some(m) = self.late_match.get_mut(port) {
            *m = matches;
        }
    }
    /// Whether arrivals on `port` match late records (see [`Merger::set_late_match`]).
    pub fn late_match(&self, port: usize) -> bool {
        self.late_match.get(port).copied().unwrap_or(false)
    }
    /// Counters.
    pub fn stats(&self) -> MergeStats {
        self.stats
    }
    /// Forgets every record (counters are kept).
    pub fn clear(&mut self) {
        *self = Merger {
            stats: self.stats,
            horizon: self.horizon,
            late_match: self.late_match,
            keep_late: self.keep_late,
            ..Merger::new(self.window())
        };
    }

    /// Drops every record whose window has passed at `now`.
    pub fn expire(&mut self, now: Instant) {
        let now = now.as_micros();
        while self.len > 0 {
            let r = self.ring[self.head];
            if now.saturating_sub(r.at) < self.window {
                break;
            }
            self.pop_front(false);
        }
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): every
    /// record's arrival time moves back with it, so that a record keeps the time its window
    /// (and its horizon) still has to run. A record older than the new time line's origin
    /// arrived at the origin. Runs through the whole ring: rare, not on the frame path.
    #[cold]
    pub fn step_back(&mut self, by: Duration) {
        let by = by.as_micros();
        for r in self.ring.iter_mut() {
            r.at = r.at.saturating_sub(by);
        }
        for k in self.keep_late.iter_mut().flatten() {
            *k = k.saturating_sub(by);
        }
    }

    /// A frame arrived on `port` (0 or 1) at `now`. Times must not go backwards: a caller whose
    /// clock steps back says so first ([`Merger::step_back`]); otherwise the merger stays
    /// consistent but records from before the step keep their window until the clock is back
    /// where it was.
    #[inline]
    pub fn arrive(&mut self, now: Instant, port: usize, frame: &Frame) -> Verdict {
        self.arrive_inner::<false>(now, port, frame).0
    }

    /// As [`Merger::arrive`], reporting the other port's copy: for a duplicate, the twin it
    /// matched; for a delivered arrival, a late copy it saw without matching it (its port may
    /// not match late copies), or `None`: a first copy.
    pub fn arrive_measured(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
    ) -> (Verdict, Option<Twin>) {
        self.arrive_inner::<true>(now, port, frame)
    }

    /// The arrival, measuring the twin's lag only if asked (`arrive` does not: one memory read
    /// less on the hot path).
    #[inline(always)]
    fn arrive_inner<const MEASURE: bool>(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
    ) -> (Verdict, Option<Twin>) {
        self.expire(now);
        if port > 1 {
            self.stats.bad_port += 1;
            self.stats.delivered += 1;
            return (Verdict::Deliver, None);
        }
        let side = port as u8;
        let (hi, lo) = key(frame);
        let hash = hash(hi, lo);
        let at = now.as_micros();
        let seen = match self.find(hi, lo, hash) {
            Ok(s) => {
                if let Some(twin) = self.consume::<MEASURE>(s, side, at) {
                    return (Verdict::Duplicate, Some(twin));
                }
                // Pinned: taking a late record may release the slot's last reference.
                self.slots[s].refs += 1;
                let seen = self.take_late(s, side, at);
                self.slots[s].refs -= 1;
                if seen.is_some() && self.late_match[port] {
                    self.release_if_unused(s);
                    return (Verdict::Duplicate, seen);
                }
                if self.len == Self::CAP {
                    // Pin the slot so that evicting its own last record cannot free it.
                    self.slots[s].refs += 1;
                    self.pop_front(true);
                    self.slots[s].refs -= 1;
                }
                self.record(s, side, at);
                seen
            }
            Err(_) => {
                // No slot, no late record either (late records keep their slot).
                if self.len == Self::CAP {
                    self.pop_front(true);
                }
                self.make_room();
                let s = self.insert(hi, lo, hash);
                self.record(s, side, at);
                None
            }
        };
        self.stats.delivered += 1;
        if seen.is_some() {
            self.stats.slipped += 1;
        }
        (Verdict::Deliver, seen)
    }

    /// A frame arrived on a port that is not trusted to deliver (failed or recovering, or
    /// lagging beyond the maximum): it may only be a twin. Consumes a matching record of the
    /// other port if there is one (a late one too, if the port may match late copies); never
    /// records. Returns true if it was a twin.
    pub fn match_only(&mut self, now: Instant, port: usize, frame: &Frame) -> bool {
        self.match_measured(now, port, frame).is_some()
    }

    /// As [`Merger::match_only`], reporting the twin it matched.
    pub fn match_measured(&mut self, now: Instant, port: usize, frame: &Frame) -> Option<Twin> {
        self.expire(now);
        if port > 1 {
            return None;
        }
        let (hi, lo) = key(frame);
        let hash = hash(hi, lo);
        let at = now.as_micros();
        let s = self.find(hi, lo, hash).ok()?;
        if let Some(twin) = self.consume::<true>(s, port as u8, at) {
            return Some(twin);
        }
        if !self.late_match[port] {
            return None;
        }
        self.take_late(s, port as u8, at)
    }

    /// Live records of `frame`'s key, with the port holding them.
    pub fn unmatched(&self, frame: &Frame) -> Option<(usize, u16)> {
        let (hi, lo) = key(frame);
        let s = self.find(hi, lo, hash(hi, lo)).ok()?;
        let slot = &self.slots[s];
        (slot.unmatched > 0).then_some((slot.side() as usize, slot.unmatched))
    }

    /// Consumes the oldest live record of slot `s` held by the port other than `side`.
    #[inline]
    fn consume<const MEASURE: bool>(&mut self, s: usize, side: u8, at: u64) -> Option<Twin> {
        let slot = &mut self.slots[s];
        if slot.unmatched == 0 || slot.side() == side {
            return None;
        }
        // With one live record it is the newest, in the ring: its age is exact.
        let lag = (MEASURE && slot.unmatched == 1).then(|| {
            let newest = self.ring[slot.last_pos as usize].at;
            Duration::from_micros(at.saturating_sub(newest))
        });
        slot.unmatched -= 1;
        self.stats.duplicates += 1;
        Some(Twin { lag, late: false })
    }

    fn record(&mut self, s: usize, side: u8, at: u64) {
        let tail = (self.head + self.len) & Self::MASK;
        let slot = &mut self.slots[s];
        if slot.unmatched == 0 {
            slot.flags = (slot.flags & !1) | side;
        }
        let seq = slot.recorded;
        slot.recorded = seq.wrapping_add(1);
        slot.unmatched += 1;
        // Counted before the late record at the tail gives its reference back, which may be
        // this slot's.
        slot.refs += 1;
        slot.last_pos = tail as u16;
        self.drop_late(tail);
        self.ring[tail] = Record {
            at,
            seq,
            slot: s as u16,
            late: false,
        };
        self.len += 1;
        if self.len as u32 > self.stats.high_water {
            self.stats.high_water = self.len as u32;
        }
    }

    fn pop_front(&mut self, evicting: bool) {
        let pos = self.head;
        let r = self.ring[pos];
        self.head = (self.head + 1) & Self::MASK;
        self.len -= 1;
        let s = r.slot as usize;
        let slot = &mut self.slots[s];
        // Live iff among the `unmatched` newest records of the key.
        if slot.recorded.wrapping_sub(r.seq) <= slot.unmatched {
            slot.unmatched -= 1;
            if evicting {
                self.stats.evicted += 1;
            } else {
                self.stats.expired += 1;
            }
            let side = slot.side();
            if self.hold_late(pos, s, side) {
                // It keeps its reference.
                return;
            }
        }
        self.release(s);
    }

    /// One reference to slot `s` less; the slot is freed at zero.
    #[inline]
    fn release(&mut self, s: usize) {
        let slot = &mut self.slots[s];
        slot.refs -= 1;
        if slot.refs == 0 {
            self.remove(s);
        }
    }

    /// Frees slot `s` if nothing refers to it (after a pin was taken off).
    fn release_if_unused(&mut self, s: usize) {
        if self.slots[s].refs == 0 {
            self.remove(s);
        }
    }

    #[inline]
    fn home(hash: u32) -> usize {
        // Multiplicative hashing: the top bits are the best mixed.
        ((hash as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> Self::SHIFT) as usize
    }

    /// `Ok(slot)` if present, else `Err(empty index position)`.
    #[inline]
    fn find(&self, hi: u64, lo: u64, hash: u32) -> Result<usize, usize> {
        let mut i = Self::home(hash);
        loop {
            let e = self.index[i];
            if e == 0 {
                return Err(i);
            }
            let s = (e - 1) as usize;
            let slot = &self.slots[s];
            if slot.hash == hash && slot.lo == lo && slot.hi == hi {
                return Ok(s);
            }
            i = (i + 1) & Self::MASK;
        }
    }

    fn insert(&mut self, hi: u64, lo: u64, hash: u32) -> usize {
        // Cannot be empty: slots in use ≤ records held < CAP < SLOTS.
        self.free_len -= 1;
        let s = self.free[self.free_len] as usize;
        self.slots[s] = Slot {
            hi,
            lo,
            hash,
            ..Slot::EMPTY
        };
        let mut i = Self::home(hash);
        while self.index[i] != 0 {
            i = (i + 1) & Self::MASK;
        }
        self.index[i] = s as u16 + 1;
        s
    }

    /// Removes slot `s` from the index (backward-shift deletion) and frees it.
    fn remove(&mut self, s: usize) {
        let mut i = Self::home(self.slots[s].hash);
        while self.index[i] as usize != s + 1 {
            i = (i + 1) & Self::MASK;
        }
        let mut j = i;
        loop {
            j = (j + 1) & Self::MASK;
            let e = self.index[j];
            if e == 0 {
                break;
            }
            let k = Self::home(self.slots[(e - 1) as usize].hash);
            // Move e back to the hole unless its home lies cyclically in (i, j].
            let stays = if i <= j {
                i < k && k <= j
            } else {
                i < k || k <= j
            };
            if !stays {
                self.index[i] = e;
                i = j;
            }
        }
        self.index[i] = 0;
        self.free[self.free_len] = s as u16;
        self.free_len += 1;
    }
}

impl<const SLOTS: usize> core::fmt::Debug for Merger<SLOTS> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Merger")
            .field("window", &self.window())
            .field("records", &self.len)
            .field("keys", &self.keys())
            .field("stats", &self.stats)
            .finish()
    }
}

/// The merge key: (identifier, format, RTR, DLC) and the data bytes. Frame padding is zero, so
/// equal frames give equal keys.
#[inline]
fn key(f: &Frame) -> (u64, u64) {
    let id = f.id();
    let hi = id.raw() as u64
        | (id.is_extended() as u64) << 32
        | (f.is_remote() as u64) << 33
        | (f.dlc() as u64) << 34;
    let data = f.data();
    let mut d = [0u8; 8];
    d[..data.len()].copy_from_slice(data);
    (hi, u64::from_le_bytes(d))
}

#[inline]
fn hash(hi: u64, lo: u64) -> u32 {
    let x = (lo ^ hi.rotate_left(29)).wrapping_mul(0xD6E8_FEB8_6659_FD93);
    (x ^ (x >> 32)) as u32
}

#[cfg(test)]
mod tests;
