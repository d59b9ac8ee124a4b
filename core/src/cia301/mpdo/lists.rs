//! The object scanner list (0x1FA0–0x1FCF) and the object dispatcher list (0x1FD0–0x1FFF):
//! their entries, and the look-ups a producer and a consumer make in the dictionary.

use crate::cia301::pdo::mapping::le_u64;
use crate::od::ObjectDictionary;
use core::ops::RangeInclusive;

/// Indices of the object scanner list: what a node may send as source-address MPDO.
pub const SCANNER: RangeInclusive<u16> = 0x1FA0..=0x1FCF;
/// Indices of the object dispatcher list: where a received source-address MPDO goes.
pub const DISPATCHER: RangeInclusive<u16> = 0x1FD0..=0x1FFF;

/// One scanner list entry (UNSIGNED32): bits 0–7 sub-index, 8–23 index, 24–31 block size.
///
/// The entry covers `block` consecutive sub-indices from `sub`. A block size of 0 covers
/// nothing (an unused entry).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ScannerEntry {
    /// Object index.
    pub index: u16,
    /// First sub-index.
    pub sub: u8,
    /// Number of consecutive sub-indices.
    pub block: u8,
}

impl ScannerEntry {
    /// Decodes the dictionary value.
    #[must_use]
    pub const fn from_raw(raw: u32) -> ScannerEntry {
        ScannerEntry {
            sub: raw as u8,
            index: (raw >> 8) as u16,
            block: (raw >> 24) as u8,
        }
    }
    /// The dictionary value.
    #[must_use]
    pub const fn raw(self) -> u32 {
        self.sub as u32 | (self.index as u32) << 8 | (self.block as u32) << 24
    }
    /// Whether (`index`, `sub`) is in the entry's block.
    #[must_use]
    pub const fn covers(self, index: u16, sub: u8) -> bool {
        index == self.index && sub >= self.sub && ((sub - self.sub) as u16) < self.block as u16
    }
}

/// One dispatcher list entry (UNSIGNED64): bits 0–7 the producer's node-ID, 8–15 its
/// sub-index, 16–31 its index, 32–39 the local sub-index, 40–55 the local index, 56–63 the
/// block size.
///
/// Sub-index `producer_sub + k` of the producer goes to `local_sub + k` for `k < block`
/// (a block size of 0 covers nothing).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct DispatcherEntry {
    /// The producer's node-ID.
    pub producer: u8,
    /// The producer's index.
    pub producer_index: u16,
    /// The producer's first sub-index.
    pub producer_sub: u8,
    /// The local index written.
    pub local_index: u16,
    /// The local first sub-index.
    pub local_sub: u8,
    /// Number of consecutive sub-indices.
    pub block: u8,
}

impl DispatcherEntry {
    /// Decodes the dictionary value.
    #[must_use]
    pub const fn from_raw(raw: u64) -> DispatcherEntry {
        DispatcherEntry {
            producer: raw as u8,
            producer_sub: (raw >> 8) as u8,
            producer_index: (raw >> 16) as u16,
            local_sub: (raw >> 32) as u8,
            local_index: (raw >> 40) as u16,
            block: (raw >> 56) as u8,
        }
    }
    /// The dictionary value.
    #[must_use]
    pub const fn raw(self) -> u64 {
        self.producer as u64
            | (self.producer_sub as u64) << 8
            | (self.producer_index as u64) << 16
            | (self.local_sub as u64) << 32
            | (self.local_index as u64) << 40
            | (self.block as u64) << 56
    }
    /// The local object a producer's (`index`, `sub`) goes to, if the entry covers it. A local
    /// sub-index past 255 is not covered.
    #[must_use]
    pub const fn map(self, producer: u8, index: u16, sub: u8) -> Option<(u16, u8)> {
        if producer != self.producer || index != self.producer_index || sub < self.producer_sub {
            return None;
        }
        let k = sub - self.producer_sub;
        if k >= self.block {
            return None;
        }
        match self.local_sub.checked_add(k) {
            Some(s) => Some((self.local_index, s)),
            None => None,
        }
    }
}

/// The entries of the list objects in `range`: sub 1 up to sub 0 of each index present.
fn entries<D: ObjectDictionary + ?Sized>(
    od: &D,
    range: RangeInclusive<u16>,
) -> impl Iterator<Item = u64> + '_ {
    range.flat_map(move |i| {
        let n = od.get_u32(i, 0).map_or(0, |n| n.min(254) as u8);
        (1..=n).filter_map(move |s| od.get(i, s).ok().map(|e| le_u64(e.data)))
    })
}

/// Whether the scanner list lets this node send (`index`, `sub`) as source-address MPDO.
pub fn scanned<D: ObjectDictionary + ?Sized>(od: &D, index: u16, sub: u8) -> bool {
    entries(od, SCANNER).any(|raw| ScannerEntry::from_raw(raw as u32).covers(index, sub))
}

/// The local object the dispatcher list gives a source-address MPDO of `producer`'s
/// (`index`, `sub`): the first entry that covers it, in list order.
pub fn dispatch<D: ObjectDictionary + ?Sized>(
    od: &D,
    producer: u8,
    index: u16,
    sub: u8,
) -> Option<(u16, u8)> {
    entries(od, DISPATCHER).find_map(|raw| DispatcherEntry::from_raw(raw).map(producer, index, sub))
}
