//! Definition tables of the scanner and dispatcher list objects, `const` like
//! [`crate::pdo::params`], so a no_std node keeps them in flash:
//!
//! ```
//! use duocan_core::mpdo::{dispatcher_list, scanner_list, DispatcherEntry, ScannerEntry};
//! use duocan_core::od::ObjectDef;
//! // This node may send 0x6000/1..=4 as source-address MPDO.
//! static SCAN: [ObjectDef; 3] = scanner_list(0, &[ScannerEntry { index: 0x6000, sub: 1, block: 4 }.raw()]);
//! // Node 7's 0x6000/1..=4 land in 0x2100/1..=4 here.
//! static DISPATCH: [ObjectDef; 2] = dispatcher_list(0, &[DispatcherEntry {
//!     producer: 7, producer_index: 0x6000, producer_sub: 1,
//!     local_index: 0x2100, local_sub: 1, block: 4,
//! }.raw()]);
//! assert_eq!(SCAN[0].index, 0x1FA0);
//! assert_eq!(DISPATCH[1].index, 0x1FD0);
//! ```

use crate::od::{Access, DataType, DefaultValue, ObjectDef, ObjectType};

/// Lists of each kind CiA 301 can address (0x1FA0–0x1FCF, 0x1FD0–0x1FFF).
pub const LISTS: u16 = 48;

const fn entry(index: u16, sub: u8, t: DataType, v: u64, name: &'static str) -> ObjectDef {
    ObjectDef::new(index, sub, t)
        .access(Access::Rw)
        .default(DefaultValue::Unsigned(v))
        .object_type(ObjectType::Array)
        .named(name)
}

const fn head(index: u16, n: usize, name: &'static str) -> ObjectDef {
    ObjectDef::u8(index, 0, Access::Const, n as u8)
        .object_type(ObjectType::Array)
        .named(name)
}

/// The entries a list is given: a scanner list's are 32-bit, a dispatcher list's 64-bit. One
/// builder serves both kinds, so that they cannot drift apart in layout.
#[derive(Clone, Copy)]
enum Entries<'a> {
    U32(&'a [u32]),
    U64(&'a [u64]),
}

impl Entries<'_> {
    const fn len(self) -> usize {
        match self {
            Entries::U32(e) => e.len(),
            Entries::U64(e) => e.len(),
        }
    }

    /// Entry `k` (from 0) as its sub-index's value; past the given ones 0 (unused).
    const fn value(self, k: usize) -> u64 {
        match self {
            Entries::U32(e) if k < e.len() => e[k] as u64,
            Entries::U64(e) if k < e.len() => e[k],
            _ => 0,
        }
    }

    const fn data_type(self) -> DataType {
        match self {
            Entries::U32(_) => DataType::Unsigned32,
            Entries::U64(_) => DataType::Unsigned64,
        }
    }
}

/// List object `index` named `name` with `M − 1` entries, the first ones set to `entries`,
/// the rest 0 (unused); sub 0 is `M − 1`.
const fn list<const M: usize>(index: u16, name: &'static str, entries: Entries) -> [ObjectDef; M] {
    assert!(M >= 2 && M <= 255 && entries.len() < M, "1..=254 entries");
    let mut out = [head(index, M - 1, name); M];
    let mut k = 1;
    while k < M {
        out[k] = entry(
            index,
            k as u8,
            entries.data_type(),
            entries.value(k - 1),
            name,
        );
        k += 1;
    }
    out
}

/// Object scanner list `list` (0–47: 0x1FA0 + `list`) with `M − 1` entries, the first ones
/// set to `entries` ([`super::ScannerEntry::raw`]), the rest 0 (unused); sub 0 is `M − 1`.
///
/// Panics (at compile time in a const context) if `list` is above 47, `M` not 2–255 or
/// `entries` longer than `M − 1`.
pub const fn scanner_list<const M: usize>(list: u16, entries: &[u32]) -> [ObjectDef; M] {
    assert!(list < LISTS, "scanner lists are 0..=47 (0x1FA0..=0x1FCF)");
    self::list(0x1FA0 + list, "Object scanner list", Entries::U32(entries))
}

/// Object dispatcher list `list` (0–47: 0x1FD0 + `list`) with `M − 1` entries, the first ones
/// set to `entries` ([`super::DispatcherEntry::raw`]), the rest 0 (unused); sub 0 is `M − 1`.
///
/// Panics (at compile time in a const context) if `list` is above 47, `M` not 2–255 or
/// `entries` longer than `M − 1`.
pub const fn dispatcher_list<const M: usize>(list: u16, entries: &[u64]) -> [ObjectDef; M] {
    assert!(
        list < LISTS,
        "dispatcher lists are 0..=47 (0x1FD0..=0x1FFF)"
    );
    self::list(
        0x1FD0 + list,
        "Object dispatcher list",
        Entries::U64(entries),
    )
}
