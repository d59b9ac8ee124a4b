//! The merger's key table: a fixed arena of slots, one per key with records in the ring,
//! found through an open-addressing index (linear probing, backward-shift deletion), and the
//! merge key itself: a classic frame's fits in the slot; a CAN FD frame's bytes beyond the
//! eighth are kept in the slot's payload line (feature `fd`).

#[cfg(feature = "fd")]
use duocan_core::frame::FdFrame;
use duocan_core::Frame;

/// A key with records in the ring.
#[derive(Clone, Copy)]
pub(super) struct Slot {
    pub(super) hi: u64,
    pub(super) lo: u64,
    pub(super) hash: u32,
    /// Unmatched records: the newest `unmatched` of the key's records, all of port `side`.
    pub(super) unmatched: u16,
    /// Records in the ring pointing here; the slot is freed at zero.
    pub(super) refs: u16,
    /// Ring position of the oldest unmatched record (valid while `unmatched > 0`).
    pub(super) first: u16,
    /// Ring position of the newest record (valid while `unmatched > 0`).
    pub(super) last: u16,
    /// The port holding the unmatched records.
    pub(super) side: u8,
}

impl Slot {
    const EMPTY: Slot = Slot {
        hi: 0,
        lo: 0,
        hash: 0,
        unmatched: 0,
        refs: 0,
        first: 0,
        last: 0,
        side: 0,
    };
}

/// Arena slot numbers are stored as `u16 + 1` in the index.
pub(super) const MAX_SLOTS: usize = 1 << 15;

/// `SLOTS` key slots and their index.
pub(super) struct Table<const SLOTS: usize> {
    pub(super) slots: [Slot; SLOTS],
    /// Per slot, an FD key's bytes 8 to 63 (zero beyond its length); a classic key's line is
    /// not read. One line per slot, not per FD key: no bookkeeping on the classic path, where
    /// the line of a slot freed and taken again is simply left stale.
    #[cfg(feature = "fd")]
    tails: [Tail; SLOTS],
    free: [u16; SLOTS],
    free_len: usize,
    /// 0 = empty, else arena slot + 1.
    index: [u16; SLOTS],
}

impl<const SLOTS: usize> Table<SLOTS> {
    const MASK: usize = SLOTS - 1;
    const SHIFT: u32 = 64 - SLOTS.trailing_zeros();

    pub(super) fn new() -> Self {
        let mut free = [0u16; SLOTS];
        // Hand out low slots first (the free list is a stack).
        for (i, f) in free.iter_mut().enumerate() {
            *f = (SLOTS - 1 - i) as u16;
        }
        Table {
            slots: [Slot::EMPTY; SLOTS],
            #[cfg(feature = "fd")]
            tails: [[0; TAIL]; SLOTS],
            free,
            free_len: SLOTS,
            index: [0; SLOTS],
        }
    }

    /// Keys held.
    pub(super) fn keys(&self) -> usize {
        SLOTS - self.free_len
    }

    #[inline]
    fn home(hash: u32) -> usize {
        // Multiplicative hashing: the top bits are the best mixed.
        ((hash as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> Self::SHIFT) as usize
    }

    /// The slot of a key, if held.
    #[inline]
    pub(super) fn find(&self, hi: u64, lo: u64, hash: u32) -> Option<usize> {
        let mut i = Self::home(hash);
        loop {
            let e = self.index[i];
            if e == 0 {
                return None;
            }
            let s = (e - 1) as usize;
            let slot = &self.slots[s];
            if slot.hash == hash && slot.lo == lo && slot.hi == hi {
                return Some(s);
            }
            i = (i + 1) & Self::MASK;
        }
    }

    /// A new slot for a key that is not held. The caller keeps the number of keys below
    /// `SLOTS` (each key has a record in the ring, which holds fewer than `SLOTS`).
    pub(super) fn insert(&mut self, hi: u64, lo: u64, hash: u32) -> usize {
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

    /// The slot of an FD key, if held: as [`Table::find`], its payload line compared too.
    #[cfg(feature = "fd")]
    pub(super) fn find_fd(&self, hi: u64, lo: u64, hash: u32, tail: &Tail) -> Option<usize> {
        let mut i = Self::home(hash);
        loop {
            let e = self.index[i];
            if e == 0 {
                return None;
            }
            let s = (e - 1) as usize;
            let slot = &self.slots[s];
            if slot.hash == hash && slot.lo == lo && slot.hi == hi && self.tails[s] == *tail {
                return Some(s);
            }
            i = (i + 1) & Self::MASK;
        }
    }

    /// A new slot for an FD key that is not held, its payload line written.
    #[cfg(feature = "fd")]
    pub(super) fn insert_fd(&mut self, hi: u64, lo: u64, hash: u32, tail: &Tail) -> usize {
        let s = self.insert(hi, lo, hash);
        self.tails[s] = *tail;
        s
    }

    /// One reference to slot `s` less; the slot is freed at zero.
    #[inline]
    pub(super) fn release(&mut self, s: usize) {
        let slot = &mut self.slots[s];
        slot.refs -= 1;
        if slot.refs == 0 {
            self.remove(s);
        }
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

/// A frame the merger keys: how its key is made, found and added. A classic frame's key is
/// its two words; an FD frame's has its payload line besides (feature `fd`). Generic, so that
/// the classic path is compiled as it was before FD frames.
pub(super) trait MergeFrame {
    /// The words a slot keeps: (identifier, format, RTR, DLC, FDF) and data bytes 0 to 7.
    fn key(&self) -> (u64, u64);
    /// The key's hash (over every byte).
    fn hash(&self, hi: u64, lo: u64) -> u32;
    /// Its slot, if held.
    fn find<const SLOTS: usize>(&self, t: &Table<SLOTS>, hi: u64, lo: u64, h: u32)
        -> Option<usize>;
    /// A new slot for its key (not held).
    fn insert<const SLOTS: usize>(&self, t: &mut Table<SLOTS>, hi: u64, lo: u64, h: u32) -> usize;
}

// Always inlined: the classic path calls the table itself, as before FD frames (a wrapper
// left out of line would move code in a bare-metal image whose flash has no room).
impl MergeFrame for Frame {
    #[inline(always)]
    fn key(&self) -> (u64, u64) {
        key(self)
    }
    #[inline(always)]
    fn hash(&self, hi: u64, lo: u64) -> u32 {
        hash(hi, lo)
    }
    #[inline(always)]
    fn find<const SLOTS: usize>(
        &self,
        t: &Table<SLOTS>,
        hi: u64,
        lo: u64,
        h: u32,
    ) -> Option<usize> {
        t.find(hi, lo, h)
    }
    #[inline(always)]
    fn insert<const SLOTS: usize>(&self, t: &mut Table<SLOTS>, hi: u64, lo: u64, h: u32) -> usize {
        t.insert(hi, lo, h)
    }
}

/// Bytes 8 to 63 of an FD frame.
#[cfg(feature = "fd")]
pub(super) const TAIL: usize = duocan_core::frame::fd::FD_MAX_LEN - 8;
#[cfg(feature = "fd")]
pub(super) type Tail = [u8; TAIL];

/// The FDF bit of the key's first word: an FD frame is never the key of a classic one, whatever
/// its bytes (a classic frame's first word has bits 0 to 37 only).
#[cfg(feature = "fd")]
const FDF: u64 = 1 << 38;

/// An FD frame's bytes 8 to 63 (zero beyond its length).
#[cfg(feature = "fd")]
fn tail(f: &FdFrame) -> Tail {
    let mut t = [0u8; TAIL];
    if let Some(rest) = f.data().get(8..) {
        t[..rest.len()].copy_from_slice(rest);
    }
    t
}

/// An FD frame's key: (identifier, format, DLC, FDF), every data byte. Not BRS or ESI: they
/// say how a copy was carried on its bus, not what was sent (see the module documentation).
#[cfg(feature = "fd")]
impl MergeFrame for FdFrame {
    fn key(&self) -> (u64, u64) {
        let id = self.id();
        let hi =
            id.raw() as u64 | (id.is_extended() as u64) << 32 | (self.dlc() as u64) << 34 | FDF;
        let data = self.data();
        let mut d = [0u8; 8];
        let n = data.len().min(8);
        d[..n].copy_from_slice(&data[..n]);
        (hi, u64::from_le_bytes(d))
    }
    fn hash(&self, hi: u64, lo: u64) -> u32 {
        // Every byte counts: FD frames that differ only beyond the eighth byte (a counter at
        // the end of a PDO) spread over the index as classic ones do.
        let mut folded = lo;
        for w in tail(self).chunks_exact(8) {
            let mut b = [0u8; 8];
            b.copy_from_slice(w);
            folded = (folded ^ u64::from_le_bytes(b))
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .rotate_left(27);
        }
        hash(hi, folded)
    }
    fn find<const SLOTS: usize>(
        &self,
        t: &Table<SLOTS>,
        hi: u64,
        lo: u64,
        h: u32,
    ) -> Option<usize> {
        t.find_fd(hi, lo, h, &tail(self))
    }
    fn insert<const SLOTS: usize>(&self, t: &mut Table<SLOTS>, hi: u64, lo: u64, h: u32) -> usize {
        t.insert_fd(hi, lo, h, &tail(self))
    }
}

/// The merge key: (identifier, format, RTR, DLC) and the data bytes. Frame padding is zero, so
/// equal frames give equal keys.
#[inline]
pub(super) fn key(f: &Frame) -> (u64, u64) {
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
pub(super) fn hash(hi: u64, lo: u64) -> u32 {
    let x = (lo ^ hi.rotate_left(29)).wrapping_mul(0xD6E8_FEB8_6659_FD93);
    (x ^ (x >> 32)) as u32
}
