//! The receive merger: every frame *occurrence* sent on both buses is delivered exactly once.
//!
//! # The rule
//!
//! Frames carry no sequence number and identical frames legitimately repeat (heartbeats, SYNC,
//! cyclic PDOs whose values do not change), so "drop a frame equal to one seen recently" loses
//! data, and matching copies by content alone pairs a copy with the wrong repeat as soon as one
//! bus runs a period behind. What tells a frame's two copies apart is *when they were on the
//! wire*: each copy comes with its **receive timestamp** (taken where it arrived: the
//! controller, the kernel's socket, the simulator's wire; see
//! [`Device::handle_rx_at`](duocan_core::Device::handle_rx_at)), and the two copies of one
//! occurrence were on their buses within the skew window of each other, however late a port's
//! reader hands them over.
//!
//! Per key (identifier, RTR, DLC, data) the merger keeps the *unmatched* copies of one port,
//! oldest first, with their stamps. A copy stamped `s` on port `q`:
//!
//! - skips (and forgets) the other port's unmatched copies stamped before `s − window`: their
//!   twins would have come before this copy on `q`, which keeps its order, so they never came
//!   (that bus missed them);
//! - is the **twin** of the oldest remaining one, if that is stamped within the window of `s`:
//!   it consumes it and is dropped ([`Verdict::Duplicate`]); repeats that follow each other
//!   faster than the skew between the buses are so matched in the order each bus kept;
//! - otherwise is a new occurrence, **delivered** ([`Verdict::Deliver`]), and recorded as
//!   unmatched unless the other port has already received frames stamped a window or more
//!   after `s` (its copy would have come before those: it missed this one, no twin is to come).
//!
//! So the window must exceed the skew between the buses (the stamps of a frame's two copies),
//! and a repeat that follows a copy one bus missed within the window may be paired one
//! occurrence off: the count stays right while both buses work; if the other bus then dies
//! before the repeats pause for a window, one occurrence is taken for a twin. With stamps the
//! skew is that of the wires (the buses arbitrate alike), well below the 5 ms default.
//!
//! # How long a copy is kept
//!
//! Not for a fixed window of processing time: a port whose reader runs behind (a scheduling
//! stall, a gateway queue) hands its copies over late, with their old stamps. An unmatched copy
//! is kept for the **horizon** of processing time after it was *handed over* (memory is
//! bounded), unless a copy of the other port skips it first (see above) or the other port has
//! passed it; and beyond the horizon for as long as the other port's reader, running behind,
//! has not shown its copies up to this one's twin: until the present, less how far behind that
//! reader ran at its newest copy, passes the copy's stamp by a window. So a port whose receive
//! path runs behind the other port's, by up to the horizon or by any amount while it keeps
//! handing copies over, still finds every twin (memory allowing: see *Overflow*), however late
//! the two hand their copies over: a receiver held up as a whole (a loaded machine that starves
//! both its reader threads) hands over copies older than the horizon, and they still meet.
//! Kept from its stamp instead, such a copy would be forgotten the moment it arrived, and its
//! twin left to the memory of forgotten keys below, which is not exact: a key whose line
//! another key took meanwhile is delivered twice, and a repeat that follows a forgotten copy
//! within the window is taken for its twin.
//!
//! A reader that stops handing copies over altogether (a thread not scheduled, frozen) cannot
//! be told from a bus that stopped carrying frames, until it hands over again: the copies of
//! the other port are kept the horizon past how far behind it ran before it stopped. A copy
//! that comes later than that may find its twin forgotten. The merger remembers, per
//! key, the newest stamp of a copy forgotten with its twin still possible; a copy of the other
//! port with the same content stamped no later than that (plus the window) is dropped
//! ([`Verdict::Late`]): it is that copy's twin, or an older one's. Frames of other contents are
//! not touched (one bus flooded while the other carries the traffic forgets the flood, not the
//! traffic). How long that is remembered: see the `recent` table below.
//!
//! # A port not trusted yet
//!
//! A bus that comes back (repaired, re-initialised) may first carry frames that were queued
//! before the fault, older than any twin; the layer says which port is not trusted yet
//! ([`Trust::Unproven`]). Such a copy is judged like any other while its stamp is recent
//! enough that every record of the other port it could match is still held (less than the
//! horizon minus a window ago; a record is kept at least the horizon after its stamp, since it
//! was handed over no earlier): no twin among them proves the other bus never carried it (a
//! node cut from that bus, say), however late this port's reader hands it over. An older copy
//! that finds no twin is delivered only if the other port has not yet received anything
//! stamped as late as it ([`Verdict::Unproven`] otherwise): when the other bus fails at the
//! very moment this one returns, its frames are delivered from their first one, and while the
//! other bus works, what it has already passed is not taken from the returning one.
//!
//! # Lag
//!
//! Stamps taken where a frame arrived make a late reader harmless. A bus whose frames are *on
//! the wire* later (a bridge in its path), or a port whose driver has no timestamps (its stamps
//! are the hand-over times), shows a lag between twins: the layer measures it
//! ([`crate::link::lag`]) and gives the merger stamps corrected by it. The merger reports the
//! samples it can stand behind ([`Sample`]): only from a **fresh** occurrence, and only when it
//! was the one unmatched copy of its key, so a repeat paired one period off is never a sample;
//! a twin beyond the window only when this port received frames stamped after the other's copy
//! before it (a port back from an outage has nothing in between: what it missed was lost, not
//! late), and when the other port holds nothing back (its reader ran at most a window behind at
//! its newest copy) or has handed over its copies up to a window before this one. Fresh means
//! its content was not seen on either port within the horizon before the older of its stamp and
//! how far the other port has handed over its copies, nor stamped after it (what came before a
//! copy stamped earlier than the newest one seen is not known: it may be a repeat, as a node on
//! one bus only sends one beside the twin of another node's identical frame). How far a port has handed over: its
//! newest stamp, or, quiet since, the present less how far behind its reader ran at its newest
//! copy. A reader running behind has not shown its latest copies yet: they may be repeats of
//! the same content (a frame one bus missed while its sender's port on it was not back, whose
//! repeats the other bus carried), which make the copy no fresh occurrence, nor the one
//! unmatched copy of its key.
//!
//! # CAN FD frames
//!
//! With the feature `fd`, CAN FD frames go through the same merger
//! ([`Merger::arrive_fd_at`]): the same rule, the same records in the same ring, the same
//! per-port stamps and frontiers, so a bus's classic and FD frames together show how far it has
//! handed over, and one twin search serves both. What identifies an FD frame's occurrence:
//!
//! - its **identifier and format** (base or extended), its **length** (DLC) and **every data
//!   byte**, up to 64 (not the first eight only: two FD frames that differ in their last byte,
//!   a counter say, are two occurrences);
//! - that it is an **FD frame**: a classic frame and an FD frame with the same identifier and
//!   bytes are different frames, never each other's twin (a sender that sends both sends two
//!   frames; a bus does not turn one into the other);
//! - **not BRS and not ESI.** They are link-level flags: ESI is the error state of the sender's
//!   controller *on that bus* (error passive on one bus, active on the other is the very fault
//!   a second bus is for), and BRS how that controller sent the data phase, which a gateway or
//!   a bus configured without a data bit rate changes. The two copies of one occurrence may
//!   differ in them, so a merge keyed by them would deliver such an occurrence twice. The copy
//!   delivered is the first, with its own flags.
//!
//! The property tests over mixed classic and FD streams (`tests/link/merge_fd_properties.rs`)
//! check the statements of *Order* and *Memory* below for them.
//!
//! # Memory
//!
//! Records live in one ring in arrival order, keys in a fixed arena found through an
//! open-addressing index; a key's unmatched records are chained oldest first, so a twin is found
//! without a search of the ring, and a record is consumed, skipped or expired only from the
//! oldest end of its key's chain: O(1) per arrival, plus one step per record it skips. A
//! `Merger<SLOTS>` holds at most [`Merger::capacity`] = ¾·SLOTS records (16 bytes each). With
//! the feature `fd`, each key slot has a line for an FD frame's bytes 8 to 63 (56 bytes per
//! slot, 56 KiB for the default 1,024 slots): an FD frame takes one record and one key like a
//! classic frame, so a ring of FD frames holds as many as one of classic frames, and the
//! classic path never reads the lines (a slot's line is only written when an FD key takes it).
//! Records leave the ring from its front once matched, once the other port has passed them, or
//! the horizon after they were handed over (later behind a reader running behind, see above):
//! with one bus dead, the occupancy is the live bus's rate × horizon, ~320 records at 4,000
//! frames/s and the default 80 ms; behind a reader running late, its rate × how late. (They are kept even
//! once port health calls that bus failed: a failed port may still receive, a babbled one for
//! instance, and the first copies of a port coming back must find their twins.)
//!
//! # Overflow
//!
//! When the ring is full, the oldest record is evicted (counted in [`MergeStats::evicted`]); if
//! it was unmatched, it counts as forgotten (see above). A delivery is never refused for lack
//! of room.
//!
//! # Order
//!
//! Each occurrence is delivered at its first arrival, so when both buses deliver everything
//! the per-sender order is the order sent (each bus keeps it, and the earlier of two ordered
//! arrival pairs is ordered). When one bus drops a frame while it is ahead, the sender's next
//! frame on it may come before the dropped frame arrives on the other bus: delivered first. A
//! dead bus, or two complete buses, keep every sender's order exactly. The property tests
//! (`tests/link/merge_properties.rs`) check these statements.
//!
//! ```
//! use duocan_core::{Duration, Frame, Id, Instant};
//! use duocan_redundancy_core::link::merge::{Merger, Trust, Verdict};
//!
//! let mut m: Merger<64> = Merger::new(Duration::from_millis(10));
//! let t = Instant::from_millis;
//! let sync = Frame::from_array(Id::Standard(0x080), []);
//! // SYNC every 10 ms on both buses; port 1's reader runs 35 ms behind. Each copy it hands
//! // over finds the twin on the wire at its own time, not the SYNC port 0 heard last.
//! for k in 0..10 {
//!     assert_eq!(m.arrive_at(t(10 * k), t(10 * k), 0, &sync, Trust::Trusted).0, Verdict::Deliver);
//!     if k >= 4 {
//!         let late = k - 4; // its copy stamped 10·(k−4) ms, handed over at 10·k − 5 ms
//!         let (v, _) = m.arrive_at(t(10 * k + 5), t(10 * late), 1, &sync, Trust::Trusted);
//!         assert_eq!(v, Verdict::Duplicate);
//!     }
//! }
//! assert_eq!(m.stats().delivered, 10);
//! ```

use duocan_core::{Duration, Instant};

mod arrive;
#[cfg(feature = "fd")]
mod fd;
mod recent;
mod ring;
mod table;

use recent::Recent;
use table::{Table, MAX_SLOTS};

/// What to do with an arrival.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// First copy of an occurrence: deliver it upward.
    Deliver,
    /// Twin of an occurrence already delivered: drop it.
    Duplicate,
    /// Older than what the merger still remembers of the other port, which was receiving then
    /// and delivered that time's occurrences: dropped.
    Late,
    /// From a port not trusted yet, at a time the other port has already passed without it:
    /// dropped (a frame a repaired bus carried from before its fault).
    Unproven,
}

/// Whether the layer trusts a port to deliver (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trust {
    /// Working: its first copies are delivered.
    Trusted,
    /// Back from a fault and not proven yet, while the other port works.
    Unproven,
}

/// A lag measured from a twin: how much later (in µs; negative: earlier) this port's copy was
/// stamped than the other port's. Only from a fresh occurrence that was the one unmatched copy
/// of its key (see the module documentation); a twin beyond the window either way is a *late*
/// sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sample {
    /// This copy's stamp minus its twin's.
    pub skew: i64,
    /// The twin was beyond the window (before or after this copy): this copy was delivered,
    /// the lag is not known yet.
    pub late: bool,
}

/// What a merger has done since it was created.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MergeStats {
    /// Arrivals delivered.
    pub delivered: u64,
    /// Arrivals dropped as twins.
    pub duplicates: u64,
    /// Arrivals dropped as older than what the merger remembers ([`Verdict::Late`]).
    pub late: u64,
    /// Arrivals of a port not trusted yet dropped ([`Verdict::Unproven`]).
    pub unproven: u64,
    /// Arrivals delivered although an unmatched copy of the same content, beyond the window,
    /// was pending on the other port: a twin lagging more than the window before its lag was
    /// known (delivered a second time), or a repeat of a frame the other port missed.
    pub slipped: u64,
    /// Unmatched records whose twin never came: the other port passed them (skipped by a later
    /// copy of the same content, or received beyond them by the horizon).
    pub expired: u64,
    /// Unmatched records forgotten at the horizon, their twin still possible.
    pub forgotten: u64,
    /// Records evicted because the ring was full.
    pub evicted: u64,
    /// Arrivals on a port other than 0 and 1 (delivered, not recorded).
    pub bad_port: u64,
    /// Most records held at once.
    pub high_water: u32,
}

/// What the search for a twin found.
enum Twin {
    /// The twin, consumed, and the lag it measured, if any.
    Found(Option<Sample>),
    /// None: whether an older unmatched copy of the same content was skipped (beyond the
    /// window), and the late sample it gave, if any.
    None { skipped: bool, seen: Option<Sample> },
}

/// One arrival in the ring.
#[derive(Clone, Copy)]
struct Record {
    /// Its stamp (µs).
    at: u64,
    /// How late it was handed over after its stamp, in whole milliseconds rounded up
    /// (saturating at 65 s): it is kept at least the horizon after it was handed over. Kept in
    /// what the record's alignment left free, so a record stays 16 bytes.
    late_ms: u16,
    slot: u16,
    /// Ring position of the key's next record (valid while this one is unmatched and not the
    /// newest).
    next: u16,
    /// No copy of its key arrived within the horizon before it.
    fresh: bool,
}

impl Record {
    /// When it was handed over (µs), as far as it is kept (up to a millisecond later).
    fn handed(&self) -> u64 {
        self.at.saturating_add(u64::from(self.late_ms) * 1_000)
    }

    /// How late a copy stamped `at` and handed over at `handed` (µs) was, as a record keeps it.
    fn late_ms(at: u64, handed: u64) -> u16 {
        // In 32 bits: a 64-bit division would bring the general division routine (almost
        // 1 KB) into a 32-bit device's image. Clamped where the result saturates anyway.
        let us = handed.saturating_sub(at).min(u64::from(u16::MAX) * 1_000) as u32;
        us.div_ceil(1_000) as u16
    }

    const EMPTY: Record = Record {
        at: 0,
        late_ms: 0,
        slot: 0,
        next: 0,
        fresh: false,
    };
}

/// The active-active receive merger for two ports (0 and 1), with `SLOTS` slots.
///
/// ```
/// use duocan_core::{Duration, Frame, Id, Instant};
/// use duocan_redundancy_core::link::merge::{Merger, Verdict};
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
    horizon: u64,
    ring: [Record; SLOTS],
    head: usize,
    len: usize,
    table: Table<SLOTS>,
    /// Per port: the newest stamp it received (µs).
    frontier: [u64; 2],
    /// Per port: the stamp (µs) of the last of its copies that met a fresh twin within the
    /// window: up to there it was on time. A time on the common time line: a change of the
    /// port's correction leaves it as it is. Builds with `alloc` only: in a bare-metal image
    /// (the safety gateway's) every byte of the link moves code, and its flash has no room.
    #[cfg(feature = "alloc")]
    on_time: [u64; 2],
    /// Per port: how long after its stamp its newest copy was handed over (µs): how far behind
    /// its reader runs (see [`Merger::shown`]), and the correction its stamps get (µs, the sum
    /// of [`Merger::shift`]).
    behind: [u64; 2],
    corrected: [u64; 2],
    /// The newest `now` an arrival was handled at, and per port the `now` its correction last
    /// changed ([`Merger::shift`], µs): its records handed over before that are stamped with
    /// the correction before it, and give no lag sample (see [`crate::link::lag`]).
    now: u64,
    shifted: [u64; 2],
    /// Per port: its stamps are receive timestamps (see [`Merger::set_stamped`]).
    stamped: [bool; 2],
    recent: Recent<SLOTS>,
    stats: MergeStats,
}

impl<const SLOTS: usize> Merger<SLOTS> {
    const CHECK: () = assert!(
        SLOTS.is_power_of_two() && SLOTS >= 4 && SLOTS <= MAX_SLOTS,
        "merger slots must be a power of two between 4 and 32768"
    );
    const CAP: usize = SLOTS - SLOTS / 4;
    const MASK: usize = SLOTS - 1;
    /// No next record.
    const NONE: u16 = u16::MAX;

    /// An empty merger matching twins stamped up to `window` apart, keeping unmatched copies
    /// up to eight windows.
    #[must_use]
    pub fn new(window: Duration) -> Self {
        Self::with_horizon(window, window.saturating_mul(8))
    }

    /// An empty merger matching twins stamped up to `window` apart, keeping an unmatched copy
    /// up to `horizon` after it was handed over (at least the window): how far behind the other
    /// port's a port's receive path may run.
    #[must_use]
    pub fn with_horizon(window: Duration, horizon: Duration) -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        let (window, horizon) = (window.as_micros(), horizon.as_micros());
        Merger {
            window,
            horizon: horizon.max(window),
            ring: [Record::EMPTY; SLOTS],
            head: 0,
            len: 0,
            table: Table::new(),
            frontier: [0; 2],
            #[cfg(feature = "alloc")]
            on_time: [0; 2],
            behind: [0; 2],
            corrected: [0; 2],
            now: 0,
            shifted: [0; 2],
            stamped: [true; 2],
            recent: Recent::new(),
            stats: MergeStats::default(),
        }
    }

    /// Records it can hold (¾ of the slots).
    pub const fn capacity(&self) -> usize {
        Self::CAP
    }
    /// Records held now (unmatched, or matched and not yet at the front of the ring).
    pub fn len(&self) -> usize {
        self.len
    }
    /// True when no record is held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Distinct keys held now.
    pub fn keys(&self) -> usize {
        self.table.keys()
    }
    /// The skew window.
    pub fn window(&self) -> Duration {
        Duration::from_micros(self.window)
    }
    /// Changes the skew window (applies to records already held, too).
    pub fn set_window(&mut self, window: Duration) {
        self.window = window.as_micros();
    }
    /// How long after it was handed over an unmatched copy is kept at most.
    pub fn horizon(&self) -> Duration {
        Duration::from_micros(self.horizon)
    }
    /// The newest stamp port `p` (0 or 1) has received, if any.
    pub fn frontier(&self, p: usize) -> Option<Instant> {
        let f = *self.frontier.get(p)?;
        (f > 0).then_some(Instant::from_micros(f))
    }
    /// Port `p`'s stamps are corrected by `by` µs more from now on (see [`crate::link::lag`]):
    /// its frontier moves with them, so that it has not passed what its next copies will show.
    pub fn shift(&mut self, p: usize, by: i64) {
        if let Some(f) = self.frontier.get_mut(p) {
            *f = f.saturating_add_signed(-by);
            self.corrected[p] = self.corrected[p].saturating_add_signed(by);
            if by != 0 {
                self.shifted[p] = self.now;
            }
        }
    }
    /// Counters.
    pub fn stats(&self) -> MergeStats {
        self.stats
    }
    /// Forgets every record and every stamp (counters are kept).
    pub fn clear(&mut self) {
        *self = Merger {
            stats: self.stats,
            corrected: self.corrected,
            ..Merger::with_horizon(self.window(), self.horizon())
        };
    }

    /// Drops the records that are done at `now`: matched ones at the front of the ring, and
    /// unmatched ones whose twin cannot come (the other port, stamping on arrival, has passed
    /// them) or that were handed over the horizon before `now` and the other port's reader,
    /// as far as the merger can tell, is not still behind them (see the module documentation):
    /// forgotten, unless the other port has passed them (then their twin was lost, not late).
    ///
    /// A port without receive timestamps stamps its copies when it hands them over, so its
    /// stamps run ahead of its copies until its lag is measured, and the measure needs the
    /// record: what only such a port has passed is kept to the horizon.
    pub fn expire(&mut self, now: Instant) {
        let now = now.as_micros();
        while self.len > 0 {
            let pos = self.head;
            let r = self.ring[pos];
            let s = r.slot as usize;
            let slot = &self.table.slots[s];
            if slot.unmatched > 0 && slot.first as usize == pos {
                let side = slot.side as usize;
                let due = r.at.saturating_add(self.window);
                let passed = self.frontier[1 - side] >= due;
                // Kept the horizon after it was handed over, and longer while the other port's
                // reader, running behind, has not shown its copies up to this one's twin.
                if !(passed && self.stamped[1 - side])
                    && (now.saturating_sub(r.handed()) < self.horizon
                        || self.shown(1 - side, now) < due)
                {
                    break;
                }
                self.unlink_first(s);
                if passed {
                    self.stats.expired += 1;
                } else {
                    self.stats.forgotten += 1;
                    self.forget(s, side, r.at);
                }
            }
            self.pop_front();
        }
    }

    /// Whether port `p`'s stamps are receive timestamps, taken where its frames arrived (the
    /// default), or the times its driver handed them over: then what it seems to have passed
    /// is kept (see [`Merger::expire`]).
    pub fn set_stamped(&mut self, p: usize, stamped: bool) {
        if let Some(s) = self.stamped.get_mut(p) {
            *s = stamped;
        }
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): every
    /// stamp held moves back with it, and the time each record was handed over, so that a
    /// record keeps the time it still has to run. A
    /// stamp older than the new time line's origin lands on the origin. Runs through the whole
    /// ring: rare, not on the frame path.
    #[cold]
    pub fn step_back(&mut self, by: Duration) {
        let by = by.as_micros();
        for r in self.ring.iter_mut() {
            // Its hand-over moves back too: a stamp that lands on the origin must not carry the
            // old distance to it (the record would be kept longer than it has left).
            let handed = r.handed().saturating_sub(by);
            r.at = r.at.saturating_sub(by);
            r.late_ms = Record::late_ms(r.at, handed);
        }
        for f in &mut self.frontier {
            *f = f.saturating_sub(by);
        }
        #[cfg(feature = "alloc")]
        for f in &mut self.on_time {
            *f = f.saturating_sub(by);
        }
        self.now = self.now.saturating_sub(by);
        for s in &mut self.shifted {
            *s = s.saturating_sub(by);
        }
        self.recent.step_back(by);
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

#[cfg(test)]
mod tests;
