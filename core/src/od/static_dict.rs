//! The static dictionary: definitions in `'static` tables (flash), values in a fixed byte arena,
//! index a perfect hash built when the tables are loaded (one probe per lookup, whatever the
//! key), the power-on image in a fixed record area. No heap; sized by three const parameters.

use super::def::{key, ObjectDef};
use super::parameters::{self, StorageError};
use super::perfect_index::PerfectIndex;
use super::{miss, value, BuildError, Entry, ObjectDictionary};
use crate::od::abort::AbortCode;
use core::ops::RangeInclusive;

#[derive(Clone, Copy)]
struct Slot {
    def: &'static ObjectDef,
    offset: u32,
    len: u32,
}

/// Bytes a [`StaticDictionary`] keeps for its power-on image unless told otherwise: room for
/// about twenty entries the application configures before boot (a producer time, a few
/// consumers, PDO parameters).
pub const POWER_ON_BYTES: usize = 256;

/// Bytes a power-on record spends besides the value: index, sub-index, length.
const RECORD_HEADER: usize = 5;

/// A dictionary over compile-time definition tables, with room for `N` entries (a power of two,
/// as the hash map requires), `BYTES` bytes of values and `POWER_ON` bytes of power-on image.
///
/// The power-on image ([`ObjectDictionary::capture_power_on`]) holds only the entries whose
/// value differs from their compile-time default, 5 bytes plus the value each: what the
/// application configured before boot. The defaults themselves live in flash, in the tables.
///
/// ```
/// use duocan_core::od::{Access, ObjectDef, ObjectDictionary, StaticDictionary};
/// static APP: [ObjectDef; 1] = [ObjectDef::u16(0x2000, 0, Access::Rw, 7)];
/// // Room for 16 entries and 64 bytes of values, named where the dictionary is declared.
/// type AppDictionary = StaticDictionary<16, 64>;
/// let mut od = AppDictionary::new();
/// od.load(5, &[&APP]).unwrap();
/// assert_eq!(od.get_value::<u16>(0x2000, 0), Ok(7));
/// ```
pub struct StaticDictionary<
    const N: usize,
    const BYTES: usize,
    const POWER_ON: usize = POWER_ON_BYTES,
> {
    map: PerfectIndex<Slot, N>,
    arena: [u8; BYTES],
    used: usize,
    node_id: u8,
    /// Power-on records: index u16 LE, sub-index, length u16 LE, value.
    power_on: [u8; POWER_ON],
    power_on_used: usize,
}

impl<const N: usize, const BYTES: usize, const POWER_ON: usize> Default
    for StaticDictionary<N, BYTES, POWER_ON>
{
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const BYTES: usize, const POWER_ON: usize>
    StaticDictionary<N, BYTES, POWER_ON>
{
    /// An empty dictionary; `const`, so it can be placed in a `static`.
    #[must_use]
    pub const fn new() -> Self {
        StaticDictionary {
            map: PerfectIndex::new(),
            arena: [0; BYTES],
            used: 0,
            node_id: 0,
            power_on: [0; POWER_ON],
            power_on_used: 0,
        }
    }

    /// Adds every definition of `tables` with its default value for `node_id`. Fails without
    /// partial effects on the failing entry if capacity runs out or a key repeats.
    pub fn load(&mut self, node_id: u8, tables: &[&'static [ObjectDef]]) -> Result<(), BuildError> {
        self.node_id = node_id;
        // Two loops, not `flat_map`: its iterator adapter cost the bare-metal images 250
        // bytes of flash.
        let mut added = Ok(());
        'tables: for t in tables {
            for def in t.iter() {
                added = self.add(def);
                if added.is_err() {
                    break 'tables;
                }
            }
        }
        // What was added, all of it on success, is indexed for lookups either way.
        self.map.build();
        added
    }

    fn add(&mut self, def: &'static ObjectDef) -> Result<(), BuildError> {
        let k = def.key();
        if self.map.contains_key(k) {
            return Err(BuildError::Duplicate {
                index: def.index,
                sub: def.sub,
            });
        }
        let size = def.storage_size();
        if self.used + size > BYTES {
            return Err(BuildError::OutOfStorage {
                index: def.index,
                sub: def.sub,
                capacity: BYTES,
            });
        }
        let offset = self.used;
        let len = value::encode_default(def, self.node_id, &mut self.arena[offset..offset + size]);
        let slot = Slot {
            def,
            offset: offset as u32,
            len: len as u32,
        };
        self.map
            .push(k, slot)
            .map_err(|_| BuildError::TooManyEntries { capacity: N })?;
        self.used += size;
        Ok(())
    }

    /// Bytes of value storage in use.
    pub fn storage_used(&self) -> usize {
        self.used
    }

    /// Bytes of the power-on image in use (of `POWER_ON`).
    pub fn power_on_used(&self) -> usize {
        self.power_on_used
    }

    /// Sets the node-ID used by `$NODEID` defaults; takes effect at the next reset of the range.
    /// The power-on image goes: it was taken for the old node-ID, so the next reset restores
    /// the defaults (capture again to keep a configuration).
    pub fn set_node_id(&mut self, node_id: u8) {
        self.node_id = node_id;
        self.power_on_used = 0;
    }
}

impl<const N: usize, const BYTES: usize, const POWER_ON: usize> ObjectDictionary
    for StaticDictionary<N, BYTES, POWER_ON>
{
    #[inline]
    fn get(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        match self.map.get(key(index, sub)) {
            Some(s) => {
                let start = s.offset as usize;
                Ok(Entry::of(s.def, &self.arena[start..start + s.len as usize]))
            }
            None => Err(miss(self.map.contains_key(key(index, 0)))),
        }
    }

    fn store(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let Some(s) = self.map.get_mut(key(index, sub)) else {
            return Err(miss(self.map.contains_key(key(index, 0))));
        };
        if data.len() > s.def.storage_size() {
            return Err(AbortCode::LENGTH_TOO_HIGH);
        }
        let start = s.offset as usize;
        self.arena[start..start + data.len()].copy_from_slice(data);
        s.len = data.len() as u32;
        Ok(())
    }

    fn reset_range(&mut self, range: RangeInclusive<u16>) {
        let node_id = self.node_id;
        for s in self.map.values_mut() {
            if range.contains(&s.def.index) {
                let start = s.offset as usize;
                let size = s.def.storage_size();
                s.len = value::encode_default(s.def, node_id, &mut self.arena[start..start + size])
                    as u32;
            }
        }
        // Then what the application configured before boot, over the defaults.
        let mut at = 0;
        while at + RECORD_HEADER <= self.power_on_used {
            let h = &self.power_on[at..at + RECORD_HEADER];
            let (index, sub) = (u16::from_le_bytes([h[0], h[1]]), h[2]);
            let len = u16::from_le_bytes([h[3], h[4]]) as usize;
            let value = at + RECORD_HEADER..at + RECORD_HEADER + len;
            at = value.end;
            if !range.contains(&index) {
                continue;
            }
            // Taken from the entry itself, so it fits; checked all the same.
            if let Some(s) = self
                .map
                .get_mut(key(index, sub))
                .filter(|s| len <= s.def.storage_size())
            {
                let start = s.offset as usize;
                self.arena[start..start + len].copy_from_slice(&self.power_on[value]);
                s.len = len as u32;
            }
        }
    }

    fn capture_power_on(&mut self) -> Result<(), StorageError> {
        let node_id = self.node_id;
        let changed = |s: &Slot| {
            let start = s.offset as usize;
            let data = &self.arena[start..start + s.len as usize];
            (!value::is_default(s.def, node_id, data)).then_some(data)
        };
        // Measure first: all or nothing.
        let needed: usize = self
            .map
            .values()
            .filter_map(changed)
            .map(|d| RECORD_HEADER + d.len())
            .sum();
        let too_long = self
            .map
            .values()
            .filter_map(changed)
            .any(|d| d.len() > u16::MAX as usize);
        if needed > POWER_ON || too_long {
            return Err(StorageError::TooLarge {
                needed: parameters::bytes(needed),
                capacity: parameters::bytes(POWER_ON),
            });
        }
        let mut at = 0;
        for s in self.map.values() {
            if let Some(data) = changed(s) {
                let r = &mut self.power_on[at..at + RECORD_HEADER + data.len()];
                r[..2].copy_from_slice(&s.def.index.to_le_bytes());
                r[2] = s.def.sub;
                r[3..5].copy_from_slice(&(data.len() as u16).to_le_bytes());
                r[RECORD_HEADER..].copy_from_slice(data);
                at += r.len();
            }
        }
        self.power_on_used = at;
        Ok(())
    }

    fn node_id(&self) -> u8 {
        self.node_id
    }

    fn for_each(&self, f: &mut dyn FnMut(Entry<'_>)) {
        for s in self.map.values() {
            let start = s.offset as usize;
            f(Entry::of(s.def, &self.arena[start..start + s.len as usize]));
        }
    }

    fn len(&self) -> usize {
        self.map.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::{Access, DataType, DefaultValue};

    static TABLE: [ObjectDef; 4] = [
        ObjectDef::u32(0x1014, 0, Access::Rw, 0).default(DefaultValue::NodeIdPlus(0x80)),
        ObjectDef::u8(0x2000, 0, Access::Rw, 2),
        ObjectDef::u8(0x2000, 1, Access::Ro, 9),
        ObjectDef::bytes(0x2001, 0, DataType::VisibleString, 8)
            .default(DefaultValue::Bytes(b"abc")),
    ];

    #[test]
    fn lookup_miss_distinguishes_object_and_sub_index() {
        let mut od = StaticDictionary::<8, 64>::new();
        od.load(3, &[&TABLE]).unwrap();
        assert_eq!(od.get(0x3000, 0).err(), Some(AbortCode::NO_OBJECT));
        assert_eq!(od.get(0x2000, 7).err(), Some(AbortCode::NO_SUB_INDEX));
        assert_eq!(od.get_value::<u32>(0x1014, 0), Ok(0x83));
        assert_eq!(od.read(0x2001, 0), Ok(&b"abc"[..]));
    }

    #[test]
    fn writes_are_checked_and_resets_restore_defaults() {
        let mut od = StaticDictionary::<8, 64>::new();
        od.load(3, &[&TABLE]).unwrap();
        assert_eq!(od.write(0x2000, 1, &[1]), Err(AbortCode::READ_ONLY));
        assert_eq!(
            od.write(0x2000, 0, &[1, 2]),
            Err(AbortCode::LENGTH_TOO_HIGH)
        );
        assert_eq!(
            od.write(0x2001, 0, b"123456789"),
            Err(AbortCode::LENGTH_TOO_HIGH)
        );
        od.write(0x2001, 0, b"hello").unwrap();
        od.write_local(0x2000, 1, &[5]).unwrap();
        assert_eq!(od.read(0x2001, 0), Ok(&b"hello"[..]));
        od.reset_range(0x2000..=0x2FFF);
        assert_eq!(od.read(0x2001, 0), Ok(&b"abc"[..]));
        assert_eq!(od.get_value::<u8>(0x2000, 1), Ok(9));
        assert_eq!(
            od.get_value::<u16>(0x2000, 1),
            Err(AbortCode::TYPE_MISMATCH)
        );
    }

    #[test]
    fn capacity_errors_are_reported() {
        let mut od = StaticDictionary::<2, 64>::new();
        assert_eq!(
            od.load(3, &[&TABLE]),
            Err(BuildError::TooManyEntries { capacity: 2 })
        );
        let mut od = StaticDictionary::<8, 6>::new();
        assert!(matches!(
            od.load(3, &[&TABLE]),
            Err(BuildError::OutOfStorage { index: 0x2001, .. })
        ));
        let mut od = StaticDictionary::<8, 64>::new();
        assert_eq!(
            od.load(3, &[&TABLE, &TABLE]),
            Err(BuildError::Duplicate {
                index: 0x1014,
                sub: 0
            })
        );
    }
}
