//! The merger's ring of records, oldest first: a record is added at the back, a matched one
//! leaves when it reaches the front, and when the ring is full the oldest goes, *forgotten*
//! (see `recent`) if its twin could still come. Each key's unmatched records are chained
//! through the ring from its slot in the table.

use super::table::MergeFrame;
use super::{Merger, Record};

impl<const SLOTS: usize> Merger<SLOTS> {
    /// Removes the oldest unmatched record of slot `s` from its chain (it stays in the ring,
    /// matched, until it reaches the front).
    #[inline]
    pub(super) fn unlink_first(&mut self, s: usize) {
        let slot = &mut self.table.slots[s];
        let first = slot.first as usize;
        slot.unmatched -= 1;
        slot.first = self.ring[first].next;
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn record<F: MergeFrame>(
        &mut self,
        found: Option<usize>,
        frame: &F,
        hi: u64,
        lo: u64,
        hash: u32,
        port: usize,
        at: u64,
        handed: u64,
        fresh: bool,
    ) {
        if self.len == Self::CAP {
            self.evict();
        }
        // Evicting may have freed the key's slot: look again if it had one.
        let s = match found {
            Some(_) => frame.find(&self.table, hi, lo, hash),
            None => None,
        }
        .unwrap_or_else(|| frame.insert(&mut self.table, hi, lo, hash));
        let tail = (self.head + self.len) & Self::MASK;
        let slot = &mut self.table.slots[s];
        if slot.unmatched > 0 && slot.side as usize != port {
            // The other port's records are all too new for this copy, so that port has passed
            // it: they stay, this copy has no twin to wait for. (Only a slot already held gets
            // here, never one just inserted.)
            return;
        }
        if slot.unmatched == 0 {
            slot.side = port as u8;
            slot.first = tail as u16;
        } else {
            let last = slot.last as usize;
            self.ring[last].next = tail as u16;
        }
        let slot = &mut self.table.slots[s];
        slot.unmatched += 1;
        slot.refs += 1;
        slot.last = tail as u16;
        self.ring[tail] = Record {
            at,
            late_ms: Record::late_ms(at, handed),
            slot: s as u16,
            next: Self::NONE,
            fresh,
        };
        self.len += 1;
        if self.len as u32 > self.stats.high_water {
            self.stats.high_water = self.len as u32;
        }
    }

    /// Makes room for one record: the oldest goes, forgotten if it was unmatched.
    #[cold]
    pub(super) fn evict(&mut self) {
        let pos = self.head;
        let r = self.ring[pos];
        let s = r.slot as usize;
        let slot = &self.table.slots[s];
        if slot.unmatched > 0 && slot.first as usize == pos {
            let side = slot.side as usize;
            self.unlink_first(s);
            self.stats.evicted += 1;
            if self.frontier[1 - side] < r.at.saturating_add(self.window) {
                self.forget(s, side, r.at);
            }
        }
        self.pop_front();
    }

    /// The unmatched copy of slot `s`'s key on `side`, stamped `at`, is forgotten while its
    /// twin could still come.
    pub(super) fn forget(&mut self, s: usize, side: usize, at: u64) {
        let hash = self.table.slots[s].hash;
        self.recent.forgot(hash, side, at);
    }

    pub(super) fn pop_front(&mut self) {
        let r = self.ring[self.head];
        self.head = (self.head + 1) & Self::MASK;
        self.len -= 1;
        self.table.release(r.slot as usize);
    }
}
