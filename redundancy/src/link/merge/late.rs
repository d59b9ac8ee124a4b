//! Late records: unmatched copies that left the window, kept recognisable behind the ring until
//! the horizon so that the copy of a lagging bus is still recognised (seen and measured, and
//! matched once that bus is known to lag).
//!
//! They need no memory of their own. The ring holds at most ¾ of its positions; the rest, just
//! behind its head, are the records that left it most recently, in order, until new arrivals
//! overwrite them. A record that leaves the window unmatched is marked late and keeps its
//! reference to its key's slot, which counts its late records (all of one port). An arrival
//! whose key has late records of the other port searches for the oldest of them behind the head,
//! newest first, down to the horizon; keys without late records cost one comparison. Since late
//! records keep slots, a new key that would fill the table beyond ¾ first gives back the oldest
//! late records.

use super::{Merger, Twin, LATE_SIDE};
use duocan::{Duration, Instant};

impl<const SLOTS: usize> Merger<SLOTS> {
    /// Whether copies that arrive on `port` from `now` on and leave the window unmatched are kept
    /// as late records (the default) or not, because the other port cannot deliver their twins
    /// (it is failed or recovering: its copies are lost, not late). Turning it off forgets the
    /// late records of `port`; turning it on applies to copies arriving from `now`. Either way a
    /// copy the other port lost is not taken for the twin of a later repeat that comes first on
    /// that port once it works again.
    pub fn keep_late(&mut self, port: usize, keep: bool, now: Instant) {
        let Some(k) = self.keep_late.get_mut(port) else {
            return;
        };
        if k.is_some() == keep {
            return;
        }
        *k = keep.then_some(now.as_micros());
        if !keep {
            self.drop_late_of(port as u8);
        }
    }

    /// Whether `port`'s unmatched copies are kept as late records (see [`Merger::keep_late`]).
    pub fn keeps_late(&self, port: usize) -> bool {
        self.keep_late.get(port).is_some_and(Option::is_some)
    }

    /// Forgets every unmatched copy `port` holds, in the window and late: once `port` is known
    /// to lag, the copies it delivered before (each seen as late, see `MergeStats::slipped`)
    /// were twins, and no copy of the other port is to come for them.
    pub fn forget(&mut self, port: usize) {
        if port > 1 {
            return;
        }
        for slot in self.slots.iter_mut() {
            if slot.side() as usize == port {
                slot.unmatched = 0;
            }
        }
        self.drop_late_of(port as u8);
    }

    /// Late records held now (behind the ring; those past the horizon count until overwritten).
    pub fn late_records(&self) -> usize {
        self.late
    }

    /// The record at `pos` (of slot `s`, copy of `side`) just left the ring unmatched: keeps it
    /// as a late record if it is wanted; returns whether it was.
    pub(super) fn hold_late(&mut self, pos: usize, s: usize, side: u8) -> bool {
        let at = self.ring[pos].at;
        if self.horizon == 0 || self.keep_late[side as usize].is_none_or(|since| at < since) {
            return false;
        }
        if self.slots[s].late > 0 && self.slots[s].late_side() != side {
            // Both ports hold unmatched copies of this key (one missed the other's, or lost
            // them while it was not trusted): the newer is the one whose twin may still come.
            self.drop_late_of_slot(s);
        }
        let slot = &mut self.slots[s];
        slot.flags = (slot.flags & !LATE_SIDE) | side << 1;
        slot.late += 1;
        self.ring[pos].late = true;
        self.late += 1;
        true
    }

    /// The record at `pos` is about to be overwritten: if it is late, it is given up.
    #[inline]
    pub(super) fn drop_late(&mut self, pos: usize) {
        if self.ring[pos].late {
            self.give_up(pos);
        }
    }

    /// Unmarks the late record at `pos` and gives its reference back.
    fn give_up(&mut self, pos: usize) {
        let r = &mut self.ring[pos];
        r.late = false;
        let s = r.slot as usize;
        self.slots[s].late -= 1;
        self.late -= 1;
        self.release(s);
    }

    fn drop_late_of(&mut self, side: u8) {
        if self.late == 0 {
            return;
        }
        for pos in 0..SLOTS {
            let r = &self.ring[pos];
            if r.late && self.slots[r.slot as usize].late_side() == side {
                self.give_up(pos);
            }
        }
    }

    /// Gives up the late records of slot `s` (which holds a reference of its own meanwhile).
    fn drop_late_of_slot(&mut self, s: usize) {
        let mask = SLOTS - 1;
        let mut pos = self.head;
        for _ in 0..SLOTS - self.len {
            if self.slots[s].late == 0 {
                break;
            }
            pos = (pos + mask) & mask;
            if self.ring[pos].late && self.ring[pos].slot as usize == s {
                self.give_up(pos);
            }
        }
    }

    /// Gives back the oldest late records until a new key leaves the table at most ¾ full.
    #[inline]
    pub(super) fn make_room(&mut self) {
        if self.late > 0 && self.keys() >= Self::CAP {
            self.give_back_room();
        }
    }

    #[cold]
    fn give_back_room(&mut self) {
        let mask = SLOTS - 1;
        // Behind the ring, oldest first: from the position after its tail.
        let mut pos = (self.head + self.len) & mask;
        while self.keys() >= Self::CAP && self.late > 0 && pos != self.head {
            if self.ring[pos].late {
                self.give_up(pos);
            }
            pos = (pos + 1) & mask;
        }
    }

    /// An arrival on `side` found no live twin in slot `s`: takes the oldest late record of the
    /// other port that is younger than the horizon, if any (matched or only seen, it is then no
    /// longer a late record: one copy answers for one record). The caller pins the slot.
    #[inline]
    pub(super) fn take_late(&mut self, s: usize, side: u8, at: u64) -> Option<Twin> {
        let slot = &self.slots[s];
        if slot.late == 0 || slot.late_side() == side {
            return None;
        }
        self.search_late(s, side, at)
    }

    #[cold]
    fn search_late(&mut self, s: usize, side: u8, at: u64) -> Option<Twin> {
        let mask = SLOTS - 1;
        let mut pos = self.head;
        let mut found = None;
        // Behind the head, newest first: arrival times fall, so the search ends at the horizon;
        // the last match is the oldest copy, the twin (each port keeps its order).
        for _ in 0..SLOTS - self.len {
            pos = (pos + mask) & mask;
            let r = &self.ring[pos];
            if at.saturating_sub(r.at) >= self.horizon {
                break;
            }
            if r.late && r.slot as usize == s {
                found = Some(pos);
            }
        }
        let pos = found?;
        let lag = Duration::from_micros(at.saturating_sub(self.ring[pos].at));
        self.give_up(pos);
        if self.late_match[side as usize] {
            self.stats.duplicates += 1;
            self.stats.late += 1;
        }
        Some(Twin {
            lag: Some(lag),
            late: true,
        })
    }
}
