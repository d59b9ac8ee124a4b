//! The engine's lookup tables: PDOs by identifier (sorted pairs, a range per identifier) and,
//! for event-driven TPDOs, the dictionary entries they map (so that a write finds its TPDOs
//! without scanning them all).

use super::dictionary::map_index;
use super::mapping::{Dir, CACHED};
use super::tpdo::Tpdo;
use crate::frame::storage::{Storage, Table};
use crate::frame::Id;
use crate::od::{key, ObjectDictionary};

/// Identifier as a sortable key: 11-bit below 29-bit.
pub(super) fn id_key(id: Id) -> u32 {
    match id {
        Id::Standard(r) => r as u32,
        Id::Extended(r) => r | 1 << 31,
    }
}

/// Sorted (key, slot) pairs: the range of slots whose key is `k`.
pub(super) fn equal_range(v: &[(u32, u16)], k: u32) -> (usize, usize) {
    let lo = v.partition_point(|x| x.0 < k);
    let hi = lo + v[lo..].partition_point(|x| x.0 == k);
    (lo, hi)
}

/// Sorts (key, slot) pairs in place, ascending: what `sort_unstable` gives (equal pairs are
/// indistinguishable), by a Shell sort (Knuth's gaps: about `n^1.5` steps at worst) written
/// out for this one type, a small fraction of the generic sort's code (tables are rebuilt at
/// boot and on a PDO's reconfiguration only).
pub(super) fn sort_pairs(v: &mut [(u32, u16)]) {
    let n = v.len();
    let mut gap = 1;
    while gap < n / 3 {
        gap = 3 * gap + 1;
    }
    while gap > 0 {
        for i in gap..n {
            let mut j = i;
            while j >= gap && v[j - gap] > v[j] {
                v.swap(j - gap, j);
                j -= gap;
            }
        }
        gap /= 3;
    }
}

/// Entry → event-capable TPDOs that map it, sorted by entry key. Holds 8 mappings per TPDO on
/// average; beyond that (long bit-granular mappings) lookups fall back to scanning the TPDOs.
pub(super) struct Reverse<S: Storage, const T: usize> {
    slots: Table<[(u32, u16); CACHED], T, S>,
    len: usize,
    pub(super) overflow: bool,
}

impl<S: Storage, const T: usize> Reverse<S, T> {
    pub(super) fn new(tpdos: usize) -> Self {
        Reverse {
            slots: Table::new(tpdos, || [(0, 0); CACHED]),
            len: 0,
            overflow: false,
        }
    }

    pub(super) fn is_empty(&self) -> bool {
        self.len == 0 && !self.overflow
    }

    pub(super) fn pairs(&self) -> &[(u32, u16)] {
        &self.slots.as_flattened()[..self.len]
    }

    pub(super) fn rebuild<D: ObjectDictionary + ?Sized>(&mut self, tpdos: &[Tpdo], od: &D) {
        self.len = 0;
        self.overflow = false;
        let flat = self.slots.as_flattened_mut();
        'all: for (k, t) in tpdos.iter().enumerate() {
            if !(t.p.active() && t.p.event_capable()) {
                continue;
            }
            for j in 0..t.p.mapping.count() {
                let e = t.p.mapping.entry(od, map_index(Dir::Transmit, k as u16), j);
                if e.is_dummy() {
                    continue;
                }
                let Some(slot) = flat.get_mut(self.len) else {
                    self.overflow = true;
                    break 'all;
                };
                *slot = (key(e.index, e.sub), k as u16);
                self.len += 1;
            }
        }
        let v = &mut flat[..self.len];
        sort_pairs(v);
        // A TPDO mapping one entry twice is triggered once.
        let mut w = 0;
        for r in 0..v.len() {
            if w == 0 || v[w - 1] != v[r] {
                v[w] = v[r];
                w += 1;
            }
        }
        self.len = w;
    }
}

#[cfg(test)]
mod tests {
    use super::sort_pairs;

    #[test]
    fn sort_pairs_sorts_as_the_library_sort_does() {
        let mut rng = fastrand::Rng::with_seed(7);
        // Small tables, and large ones (the gaps of the Shell sort up to 3280).
        for n in (0..70).chain([1_000, 4_096, 10_000]) {
            for _ in 0..20 {
                // Few distinct keys: duplicates of key and of whole pairs are the common case.
                let mut v: Vec<(u32, u16)> = (0..n)
                    .map(|_| (rng.u32(0..8) << 29 | rng.u32(0..4), rng.u16(0..4)))
                    .collect();
                let mut want = v.clone();
                want.sort_unstable();
                sort_pairs(&mut v);
                assert_eq!(v, want);
            }
        }
    }
}
