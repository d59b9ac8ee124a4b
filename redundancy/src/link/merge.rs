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
//! # Memory
//!
//! Records live in one ring in arrival order (so expiry pops from the front and is O(1) per
//! record), keys in a fixed arena indexed by an open-addressing table. A record stores its key's
//! arena slot and the key's arrival sequence number; since records of a key are consumed and
//! expired oldest first, the live records of a key are always its `unmatched` newest ones, and a
//! record at the front of the ring is live exactly when its sequence number is among them. No
//! record is ever searched for or moved.
//!
//! A `Merger<SLOTS>` has `SLOTS` slots (a power of two) and holds at most [`Merger::capacity`] =
//! ¾·SLOTS records, keeping the table at most ¾ full. Two saturated 1 Mbit/s buses deliver at most
//! about 21,300 frames/s each, i.e. ~430 records in a 10 ms window, which the default
//! `SLOTS = 1024` holds with room to spare. With one bus dead every record expires unmatched after the window, so the
//! occupancy is bounded by the live bus's rate × window: memory is constant by construction.
//!
//! # Overflow
//!
//! When the ring is full, the oldest record is evicted before its window ends (counted in
//! [`MergeStats::evicted`] when it was still unmatched). A delivery is never refused: the only
//! possible harm is that the twin of the evicted arrival, arriving later, is delivered as a
//! duplicate (at most one per eviction). Losing a frame is worse than a counted duplicate.
//!
//! # Failed ports
//!
//! The merger itself treats both ports alike. The layer feeds it arrivals from a port that is
//! failed or recovering (while the other port is healthy) through [`Merger::match_only`]: such
//! an arrival may consume a pending twin but is never delivered or recorded, because a repaired
//! segment can first flush frames older than the window, which would otherwise come up a second
//! time (see [`crate::link::health`]). With both ports unhealthy, both deliver normally.
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
//! exactly. The property tests (`tests/merge_properties.rs`) check these statements.

use duocan::{Duration, Frame, Instant};

/// What to do with an arrival.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// First copy of an occurrence: deliver it upward.
    Deliver,
    /// Twin of an occurrence already delivered: drop it.
    Duplicate,
}

/// What a merger has done since it was created.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MergeStats {
    /// Arrivals delivered.
    pub delivered: u64,
    /// Arrivals dropped as twins.
    pub duplicates: u64,
    /// Unmatched records that expired (their twin never came: one bus missed the frame).
    pub expired: u64,
    /// Unmatched records evicted early because the table was full (each may cause one
    /// duplicate later).
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
    recorded: u32,
    /// Live (unmatched) records: the newest `unmatched` recorded ones.
    unmatched: u16,
    /// Records in the ring pointing here, live or not; the slot is freed at zero.
    refs: u16,
    /// Port holding the live records.
    side: u8,
}

impl Slot {
    const EMPTY: Slot = Slot {
        hi: 0,
        lo: 0,
        hash: 0,
        recorded: 0,
        unmatched: 0,
        refs: 0,
        side: 0,
    };
}

#[derive(Clone, Copy)]
struct Record {
    at: u64,
    seq: u32,
    slot: u16,
}

impl Record {
    const EMPTY: Record = Record {
        at: 0,
        seq: 0,
        slot: 0,
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
/// ```
pub struct Merger<const SLOTS: usize> {
    window: u64,
    ring: [Record; SLOTS],
    head: usize,
    len: usize,
    slots: [Slot; SLOTS],
    free: [u16; SLOTS],
    free_len: usize,
    /// Open addressing, linear probing: 0 = empty, else arena slot + 1.
    index: [u16; SLOTS],
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
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        let mut free = [0u16; SLOTS];
        // Hand out low slots first (free list is a stack).
        for (i, f) in free.iter_mut().enumerate() {
            *f = (SLOTS - 1 - i) as u16;
        }
        Merger {
            window: window.as_micros(),
            ring: [Record::EMPTY; SLOTS],
            head: 0,
            len: 0,
            slots: [Slot::EMPTY; SLOTS],
            free,
            free_len: SLOTS,
            index: [0; SLOTS],
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
    /// Counters.
    pub fn stats(&self) -> MergeStats {
        self.stats
    }
    /// Forgets every record (counters are kept).
    pub fn clear(&mut self) {
        *self = Merger {
            stats: self.stats,
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

    /// A frame arrived on `port` (0 or 1) at `now`. Times must not go backwards; if they do,
    /// the merger stays consistent but may match across the jump.
    pub fn arrive(&mut self, now: Instant, port: usize, frame: &Frame) -> Verdict {
        self.expire(now);
        if port > 1 {
            self.stats.bad_port += 1;
            self.stats.delivered += 1;
            return Verdict::Deliver;
        }
        let side = port as u8;
        let (hi, lo) = key(frame);
        let hash = hash(hi, lo);
        let at = now.as_micros();
        match self.find(hi, lo, hash) {
            Ok(s) => {
                let slot = &mut self.slots[s];
                if slot.unmatched > 0 && slot.side != side {
                    slot.unmatched -= 1;
                    self.stats.duplicates += 1;
                    return Verdict::Duplicate;
                }
                if self.len == Self::CAP {
                    // Pin the slot so that evicting its own last record cannot free it.
                    self.slots[s].refs += 1;
                    self.pop_front(true);
                    self.slots[s].refs -= 1;
                }
                self.record(s, side, at);
            }
            Err(_) => {
                if self.len == Self::CAP {
                    self.pop_front(true);
                }
                let s = self.insert(hi, lo, hash);
                self.record(s, side, at);
            }
        }
        self.stats.delivered += 1;
        Verdict::Deliver
    }

    /// A frame arrived on a port that is not trusted to deliver (failed or recovering): it may
    /// only be a twin. Consumes a matching record of the other port if there is one; never
    /// records. Returns true if it was a twin.
    pub fn match_only(&mut self, now: Instant, port: usize, frame: &Frame) -> bool {
        self.expire(now);
        if port > 1 {
            return false;
        }
        let (hi, lo) = key(frame);
        if let Ok(s) = self.find(hi, lo, hash(hi, lo)) {
            let slot = &mut self.slots[s];
            if slot.unmatched > 0 && slot.side != port as u8 {
                slot.unmatched -= 1;
                self.stats.duplicates += 1;
                return true;
            }
        }
        false
    }

    /// Live records of `frame`'s key, with the port holding them.
    pub fn unmatched(&self, frame: &Frame) -> Option<(usize, u16)> {
        let (hi, lo) = key(frame);
        let s = self.find(hi, lo, hash(hi, lo)).ok()?;
        let slot = &self.slots[s];
        (slot.unmatched > 0).then_some((slot.side as usize, slot.unmatched))
    }

    fn record(&mut self, s: usize, side: u8, at: u64) {
        let slot = &mut self.slots[s];
        if slot.unmatched == 0 {
            slot.side = side;
        }
        let seq = slot.recorded;
        slot.recorded = seq.wrapping_add(1);
        slot.unmatched += 1;
        slot.refs += 1;
        let tail = (self.head + self.len) & Self::MASK;
        self.ring[tail] = Record {
            at,
            seq,
            slot: s as u16,
        };
        self.len += 1;
        if self.len as u32 > self.stats.high_water {
            self.stats.high_water = self.len as u32;
        }
    }

    fn pop_front(&mut self, evicting: bool) {
        let r = self.ring[self.head];
        self.head = (self.head + 1) & Self::MASK;
        self.len -= 1;
        let s = r.slot as usize;
        let slot = &mut self.slots[s];
        // Live iff among the `unmatched` newest records of the key.
        if slot.recorded.wrapping_sub(r.seq) <= slot.unmatched as u32 {
            slot.unmatched -= 1;
            if evicting {
                self.stats.evicted += 1;
            } else {
                self.stats.expired += 1;
            }
        }
        slot.refs -= 1;
        if slot.refs == 0 {
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
mod tests {
    use super::*;
    use duocan::Id;

    fn f(id: u16, d: u8) -> Frame {
        Frame::from_array(Id::Standard(id), [d])
    }
    fn t(us: u64) -> Instant {
        Instant::from_micros(us)
    }
    const W: Duration = Duration::from_millis(10);

    #[test]
    fn twin_within_window_is_dropped_and_late_twin_is_delivered() {
        let mut m: Merger<16> = Merger::new(W);
        assert_eq!(m.arrive(t(0), 0, &f(1, 1)), Verdict::Deliver);
        assert_eq!(m.arrive(t(9_999), 1, &f(1, 1)), Verdict::Duplicate);
        assert_eq!(m.arrive(t(20_000), 0, &f(1, 1)), Verdict::Deliver);
        // Exactly one window later the record has expired: a new occurrence.
        assert_eq!(m.arrive(t(30_000), 1, &f(1, 1)), Verdict::Deliver);
        assert_eq!(m.stats().expired, 1);
    }

    #[test]
    fn repeats_on_one_port_are_all_delivered_and_matched_one_for_one() {
        let mut m: Merger<16> = Merger::new(W);
        for i in 0..3 {
            assert_eq!(m.arrive(t(i), 0, &f(1, 1)), Verdict::Deliver);
        }
        assert_eq!(m.unmatched(&f(1, 1)), Some((0, 3)));
        for i in 0..3 {
            assert_eq!(m.arrive(t(5 + i), 1, &f(1, 1)), Verdict::Duplicate);
        }
        // A fourth copy on port 1 has no twin left: new occurrence, recorded for port 1.
        assert_eq!(m.arrive(t(9), 1, &f(1, 1)), Verdict::Deliver);
        assert_eq!(m.unmatched(&f(1, 1)), Some((1, 1)));
    }

    #[test]
    fn different_data_or_dlc_or_rtr_is_a_different_key() {
        let mut m: Merger<16> = Merger::new(W);
        let a = Frame::new(Id::Standard(5), &[0]).unwrap();
        let b = Frame::new(Id::Standard(5), &[]).unwrap();
        let r = Frame::remote(Id::Standard(5), 0).unwrap();
        let x = Frame::new(Id::Extended(5), &[]).unwrap();
        for fr in [a, b, r, x] {
            assert_eq!(m.arrive(t(0), 0, &fr), Verdict::Deliver);
        }
        assert_eq!(m.keys(), 4);
        for fr in [a, b, r, x] {
            assert_eq!(m.arrive(t(1), 1, &fr), Verdict::Duplicate);
        }
    }

    #[test]
    fn slots_are_freed_when_records_leave() {
        let mut m: Merger<16> = Merger::new(W);
        for i in 0..12u8 {
            m.arrive(t(0), 0, &f(0x100, i));
        }
        assert_eq!(m.keys(), 12);
        m.expire(t(10_000));
        assert_eq!((m.len(), m.keys()), (0, 0));
        // The index is empty again: everything can be re-inserted and found.
        for i in 0..12u8 {
            m.arrive(t(10_000), 0, &f(0x100, i));
        }
        for i in 0..12u8 {
            assert_eq!(m.arrive(t(10_001), 1, &f(0x100, i)), Verdict::Duplicate);
        }
    }

    #[test]
    fn overflow_evicts_the_oldest_and_never_refuses_a_delivery() {
        let mut m: Merger<16> = Merger::new(W);
        assert_eq!(m.capacity(), 12);
        for i in 0..20u8 {
            assert_eq!(m.arrive(t(i as u64), 0, &f(0x100, i)), Verdict::Deliver);
        }
        assert_eq!(m.len(), 12);
        assert_eq!(m.stats().evicted, 8);
        // The twins of the kept ones are matched; those of the evicted ones (0..8) come back
        // as duplicates: one per eviction, no more.
        for i in 8..20u8 {
            assert_eq!(m.arrive(t(100), 1, &f(0x100, i)), Verdict::Duplicate);
        }
        for i in 0..8u8 {
            assert_eq!(m.arrive(t(100), 1, &f(0x100, i)), Verdict::Deliver);
        }
        assert_eq!(m.stats().evicted, 8);
    }

    #[test]
    fn eviction_of_the_arrivals_own_key_keeps_the_slot() {
        let mut m: Merger<4> = Merger::new(W);
        assert_eq!(m.capacity(), 3);
        for i in 0..10 {
            assert_eq!(m.arrive(t(i), 0, &f(7, 7)), Verdict::Deliver);
        }
        assert_eq!(m.unmatched(&f(7, 7)), Some((0, 3)));
        assert_eq!(m.keys(), 1);
    }

    #[test]
    fn match_only_consumes_but_never_records() {
        let mut m: Merger<16> = Merger::new(W);
        assert!(!m.match_only(t(0), 1, &f(1, 1)));
        assert!(m.is_empty());
        m.arrive(t(1), 0, &f(1, 1));
        assert!(m.match_only(t(2), 1, &f(1, 1)));
        assert_eq!(m.unmatched(&f(1, 1)), None);
    }
}
