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
        v.sort_unstable();
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
