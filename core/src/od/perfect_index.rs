//! The static dictionary's index: a perfect hash over the keys it holds, built when the tables
//! are loaded, so that a lookup is one multiplication, two array reads and one comparison, the
//! same for every key (no probing, no chain, no branch that depends on the key).
//!
//! The scheme is hash-and-displace: a key's hash picks a bucket (half as many buckets as
//! slots) and a base slot; the bucket's displacement, chosen when the index is built, is XORed
//! into the base. Buckets are placed largest first, each with the first displacement that puts
//! all its keys on free slots. A build that finds no displacement for some bucket starts again
//! with another salt; after [`SALTS`] salts (never seen with a table up to three quarters full)
//! the index falls back to a scan, which is slow but correct. Tables of fewer than
//! [`SMALL`] slots are always scanned: a handful of comparisons beats any hash.
//!
//! Everything lives in fixed arrays sized by the capacity `N` (a power of two): the entries at
//! their slots, each beside its key (one read finds both), the displacements and the build's
//! scratch. No heap, `no_std`. Iteration goes in slot order (a dictionary's `for_each` promises
//! no order).

/// Marks a slot without an entry: zero, so that an empty index is all zeros (the `static` of
/// an empty dictionary goes in .bss: no start-up code, no image in flash).
const EMPTY: u32 = 0;
/// Set in every key the index holds (keys are `index << 8 | sub`: 24 bits), so that no key is
/// [`EMPTY`], not even 0x0000sub0.
const PRESENT: u32 = 1 << 24;
/// Marks a slot taken while a bucket is being placed (above any key's bits).
const TAKEN: u32 = 1 << 31;
/// Salts a build tries before it falls back to scanning.
const SALTS: u32 = 32;
/// Below this capacity the index scans.
const SMALL: usize = 16;
/// Keys one bucket may hold (a salt that puts more in one is passed over).
const BUCKET_MAX: usize = 16;

/// The key's 64-bit hash for `salt`: one multiplication by an odd multiplier the salt picks. The
/// bucket is taken from the top bits of the product and the base slot from the bits below the
/// middle, both of which every key bit reaches.
#[inline(always)]
fn hash(key: u32, salt: u32) -> u64 {
    let m = 0x9E37_79B9_7F4A_7C15u64 ^ (u64::from(salt).wrapping_mul(0xD6E8_FEB8_6659_FD93) << 1);
    u64::from(key).wrapping_mul(m | 1)
}

/// A key and its entry, side by side: a lookup reads one place.
#[derive(Clone, Copy)]
struct Cell<T> {
    key: u32,
    entry: Option<T>,
}

/// A perfect-hash index of at most `N` entries of type `T`.
pub(crate) struct PerfectIndex<T: Copy, const N: usize> {
    cells: [Cell<T>; N],
    /// The first `N / 2` are the buckets' displacements; the rest is scratch while building.
    disp: [u16; N],
    /// While building: the entries' slots grouped by bucket.
    scratch: [u16; N],
    len: usize,
    salt: u32,
    perfect: bool,
}

impl<T: Copy, const N: usize> PerfectIndex<T, N> {
    /// An empty index.
    pub const fn new() -> Self {
        PerfectIndex {
            cells: [Cell {
                key: EMPTY,
                entry: None,
            }; N],
            disp: [0; N],
            scratch: [0; N],
            len: 0,
            salt: 0,
            perfect: false,
        }
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.len
    }

    const MASK: usize = N.saturating_sub(1);
    /// Bits of the bucket number: half as many buckets as slots (rounded down to a power of
    /// two).
    const BUCKET_BITS: u32 = if N >= 4 { (N / 2).ilog2() } else { 0 };
    const BUCKETS: usize = 1 << Self::BUCKET_BITS;

    /// The bucket and base slot of `key` under `salt`.
    #[inline(always)]
    fn place(key: u32, salt: u32) -> (usize, usize) {
        let h = hash(key, salt);
        let bucket = (h >> (63 - Self::BUCKET_BITS) >> 1) as usize;
        (bucket, (h >> 24) as usize & Self::MASK)
    }

    /// The slot of `key`, if it is in the index.
    #[inline(always)]
    fn find(&self, key: u32) -> Option<usize> {
        let key = key | PRESENT;
        if self.perfect {
            let (b, base) = Self::place(key, self.salt);
            let slot = (base ^ self.disp[b] as usize) & Self::MASK;
            return (self.cells[slot].key == key).then_some(slot);
        }
        self.cells.iter().position(|c| c.key == key)
    }

    /// Whether `key` is in the index.
    #[inline]
    pub fn contains_key(&self, key: u32) -> bool {
        self.find(key).is_some()
    }

    /// The entry of `key`.
    #[inline(always)]
    pub fn get(&self, key: u32) -> Option<&T> {
        let key = key | PRESENT;
        if self.perfect {
            // The lookup proper, written out: one cell read for key and entry together.
            let (b, base) = Self::place(key, self.salt);
            let cell = &self.cells[(base ^ self.disp[b] as usize) & Self::MASK];
            return if cell.key == key {
                cell.entry.as_ref()
            } else {
                None
            };
        }
        self.find(key).and_then(|s| self.cells[s].entry.as_ref())
    }

    /// The entry of `key`, to change it.
    #[inline]
    pub fn get_mut(&mut self, key: u32) -> Option<&mut T> {
        self.find(key).and_then(|s| self.cells[s].entry.as_mut())
    }

    /// Adds `key` (not yet in the index: the caller checks) with `entry`; `Err` when full.
    /// Lookups scan until [`PerfectIndex::build`] runs.
    pub fn push(&mut self, key: u32, entry: T) -> Result<(), T> {
        let Some(slot) = self.cells.iter().position(|c| c.key == EMPTY) else {
            return Err(entry);
        };
        self.cells[slot] = Cell {
            key: key | PRESENT,
            entry: Some(entry),
        };
        self.len += 1;
        self.perfect = false;
        Ok(())
    }

    /// Every entry (slot order).
    pub fn values(&self) -> impl Iterator<Item = &T> + '_ {
        self.cells.iter().filter_map(|c| c.entry.as_ref())
    }

    /// Every entry, to change it (slot order).
    pub fn values_mut(&mut self) -> impl Iterator<Item = &mut T> + '_ {
        self.cells.iter_mut().filter_map(|c| c.entry.as_mut())
    }

    /// Builds the perfect hash over the entries there are (call after adding them).
    pub fn build(&mut self) {
        self.perfect = false;
        if N < SMALL || self.len == 0 || N > u16::MAX as usize {
            return;
        }
        for attempt in 0..SALTS {
            let salt = self.salt.wrapping_add(attempt + 1);
            if self.try_salt(salt) {
                self.salt = salt;
                self.settle();
                self.perfect = true;
                return;
            }
        }
    }

    /// Tries to place every bucket under `salt`; on success the displacements are set.
    fn try_salt(&mut self, salt: u32) -> bool {
        let b = Self::BUCKETS;
        let (disp, ends) = self.disp.split_at_mut(b);
        // Group the entries' slots by bucket (a counting sort into `scratch`): `ends[k]` is
        // where bucket k's members end, and the previous bucket's end where they start.
        ends.iter_mut().for_each(|e| *e = 0);
        for c in self.cells.iter().filter(|c| c.key != EMPTY) {
            let (k, _) = Self::place(c.key, salt);
            ends[k] += 1;
        }
        let mut start = 0u16;
        let mut largest = 0;
        for e in ends.iter_mut() {
            largest = largest.max(*e as usize);
            let n = *e;
            *e = start;
            start += n;
        }
        for (s, c) in self
            .cells
            .iter()
            .enumerate()
            .filter(|(_, c)| c.key != EMPTY)
        {
            let (k, _) = Self::place(c.key, salt);
            self.scratch[ends[k] as usize] = s as u16;
            ends[k] += 1;
        }
        if largest > BUCKET_MAX {
            return false;
        }
        disp.iter_mut().for_each(|d| *d = 0);
        let mut ok = true;
        'sizes: for size in (1..=largest).rev() {
            for k in 0..b {
                let from = if k == 0 { 0 } else { ends[k - 1] as usize };
                if ends[k] as usize - from != size {
                    continue;
                }
                let mut bases = heapless::Vec::<usize, BUCKET_MAX>::new();
                for &s in &self.scratch[from..from + size] {
                    // (A key whose slot an earlier bucket claimed carries the mark.)
                    let base = Self::place(self.cells[s as usize].key & !TAKEN, salt).1;
                    // Two keys of a bucket on one base: no displacement separates them.
                    if bases.contains(&base) || bases.push(base).is_err() {
                        ok = false;
                        break 'sizes;
                    }
                }
                let cells = &self.cells;
                let free = |d: usize| {
                    bases
                        .iter()
                        .all(|base| cells[(base ^ d) & Self::MASK].key & TAKEN == 0)
                };
                let Some(d) = (0..N).find(|&d| free(d)) else {
                    ok = false;
                    break 'sizes;
                };
                disp[k] = d as u16;
                for base in &bases {
                    self.cells[(base ^ d) & Self::MASK].key |= TAKEN;
                }
            }
        }
        // The marks go whatever the outcome.
        for c in self.cells.iter_mut() {
            c.key &= !TAKEN;
        }
        ok
    }

    /// Moves every entry to its slot under the new hash (in place, one swap per misplaced
    /// entry).
    fn settle(&mut self) {
        let target = |key: u32, disp: &[u16]| {
            let (b, base) = Self::place(key, self.salt);
            (base ^ disp[b] as usize) & Self::MASK
        };
        for s in 0..N {
            while self.cells[s].key != EMPTY {
                let t = target(self.cells[s].key, &self.disp);
                if t == s {
                    break;
                }
                // Two distinct cells (`t != s`), swapped as such: `slice::swap` allows them
                // to be one and copies through the general overlapping copy.
                let (lo, hi) = self.cells.split_at_mut(s.max(t));
                core::mem::swap(&mut lo[s.min(t)], &mut hi[0]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(i: u32) -> u32 {
        // A dictionary-like spread: objects from 0x1000, a few sub-indices each.
        ((0x1000 + i / 5 * 3) << 8) | (i % 5)
    }

    #[test]
    fn every_key_is_found_and_no_other() {
        for n in [1usize, 10, 100, 700, 1024, 1500] {
            let mut ix = PerfectIndex::<u32, 2048>::new();
            for i in 0..n as u32 {
                ix.push(key(i), i).unwrap();
            }
            ix.build();
            assert!(ix.perfect, "{n} keys in 2048 slots");
            for i in 0..n as u32 {
                assert_eq!(ix.get(key(i)), Some(&i));
            }
            assert_eq!(ix.get(key(n as u32)), None);
            assert_eq!(ix.get(0x0000_1234), None);
            // Every entry once.
            let mut all: std::vec::Vec<u32> = ix.values().copied().collect();
            all.sort_unstable();
            assert!(all.into_iter().eq(0..n as u32));
        }
    }

    #[test]
    fn a_full_table_is_still_exact_and_small_tables_scan() {
        let mut ix = PerfectIndex::<u32, 64>::new();
        for i in 0..64 {
            ix.push(key(i), i).unwrap();
        }
        assert_eq!(ix.push(key(64), 64), Err(64));
        ix.build();
        // Perfect or scanning, every lookup is right.
        for i in 0..64 {
            assert_eq!(ix.get(key(i)), Some(&i));
        }
        assert_eq!(ix.get(key(64)), None);
        let mut small = PerfectIndex::<u32, 8>::new();
        small.push(key(3), 3).unwrap();
        small.build();
        assert!(!small.perfect);
        assert_eq!(small.get(key(3)), Some(&3));
        *small.get_mut(key(3)).unwrap() = 4;
        assert_eq!(
            small.values().copied().collect::<heapless::Vec<u32, 8>>(),
            [4]
        );
    }

    /// An empty slot is a zero key, so key 0 (index 0x0000, sub 0) must still be a key, found
    /// as any other, scanning and perfect.
    #[test]
    fn key_zero_is_a_key_like_any_other() {
        let mut ix = PerfectIndex::<u32, 64>::new();
        assert_eq!(ix.get(0), None);
        ix.push(0, 7).unwrap();
        assert_eq!(ix.get(0), Some(&7));
        for i in 1..40 {
            ix.push(key(i), i).unwrap();
        }
        ix.build();
        assert!(ix.perfect);
        assert_eq!(ix.get(0), Some(&7));
        assert!(ix.contains_key(0));
        assert_eq!(ix.len(), 40);
        assert_eq!(ix.values().count(), 40);
        let mut empty = PerfectIndex::<u32, 64>::new();
        empty.build();
        assert_eq!(empty.get(0), None);
    }

    #[test]
    fn adding_after_a_build_keeps_every_key() {
        let mut ix = PerfectIndex::<u32, 256>::new();
        for i in 0..100 {
            ix.push(key(i), i).unwrap();
        }
        ix.build();
        for i in 100..180 {
            assert!(!ix.contains_key(key(i)));
            ix.push(key(i), i).unwrap();
        }
        ix.build();
        for i in 0..180 {
            assert_eq!(ix.get(key(i)), Some(&i));
        }
        let mut all: std::vec::Vec<u32> = ix.values().copied().collect();
        all.sort_unstable();
        assert!(all.into_iter().eq(0..180));
    }
}
