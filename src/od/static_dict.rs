//! The static dictionary: definitions in `'static` tables (flash), values in a fixed byte arena,
//! index in a fixed-capacity hash map. No heap; sized by two const parameters.

use super::def::{key, ObjectDef};
use super::{miss, value, BuildError, Entry, KeyHasher, ObjectDictionary};
use crate::od::abort::AbortCode;
use core::ops::RangeInclusive;
use hash32::BuildHasherDefault;
use heapless::index_map::IndexMap;

#[derive(Clone, Copy)]
struct Slot {
    def: &'static ObjectDef,
    offset: u32,
    len: u32,
}

/// A dictionary over compile-time definition tables, with room for `N` entries (a power of two,
/// as the hash map requires) and `BYTES` bytes of values.
///
/// ```
/// use duocan::od::{Access, ObjectDef, ObjectDictionary, StaticDictionary};
/// static APP: [ObjectDef; 1] = [ObjectDef::u16(0x2000, 0, Access::Rw, 7)];
/// // Room for 16 entries and 64 bytes of values, named where the dictionary is declared.
/// type AppDictionary = StaticDictionary<16, 64>;
/// let mut od = AppDictionary::new();
/// od.load(5, &[&APP]).unwrap();
/// assert_eq!(od.get_value::<u16>(0x2000, 0), Ok(7));
/// ```
pub struct StaticDictionary<const N: usize, const BYTES: usize> {
    map: IndexMap<u32, Slot, BuildHasherDefault<KeyHasher>, N>,
    arena: [u8; BYTES],
    used: usize,
    node_id: u8,
}

impl<const N: usize, const BYTES: usize> Default for StaticDictionary<N, BYTES> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize, const BYTES: usize> StaticDictionary<N, BYTES> {
    /// An empty dictionary; `const`, so it can be placed in a `static`.
    #[must_use]
    pub const fn new() -> Self {
        StaticDictionary {
            map: IndexMap::new(),
            arena: [0; BYTES],
            used: 0,
            node_id: 0,
        }
    }

    /// Adds every definition of `tables` with its default value for `node_id`. Fails without
    /// partial effects on the failing entry if capacity runs out or a key repeats.
    pub fn load(&mut self, node_id: u8, tables: &[&'static [ObjectDef]]) -> Result<(), BuildError> {
        self.node_id = node_id;
        for table in tables {
            for def in table.iter() {
                self.add(def)?;
            }
        }
        Ok(())
    }

    fn add(&mut self, def: &'static ObjectDef) -> Result<(), BuildError> {
        let k = def.key();
        if self.map.contains_key(&k) {
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
            .insert(k, slot)
            .map_err(|_| BuildError::TooManyEntries { capacity: N })?;
        self.used += size;
        Ok(())
    }

    /// Bytes of value storage in use.
    pub fn storage_used(&self) -> usize {
        self.used
    }

    /// Sets the node-ID used by `$NODEID` defaults; takes effect at the next reset of the range.
    pub fn set_node_id(&mut self, node_id: u8) {
        self.node_id = node_id;
    }
}

impl<const N: usize, const BYTES: usize> ObjectDictionary for StaticDictionary<N, BYTES> {
    #[inline]
    fn get(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        match self.map.get(&key(index, sub)) {
            Some(s) => {
                let start = s.offset as usize;
                Ok(Entry {
                    def: s.def,
                    data: &self.arena[start..start + s.len as usize],
                })
            }
            None => Err(miss(self.map.contains_key(&key(index, 0)))),
        }
    }

    fn store(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let Some(s) = self.map.get_mut(&key(index, sub)) else {
            return Err(miss(self.map.contains_key(&key(index, 0))));
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
        for (_, s) in self.map.iter_mut() {
            if range.contains(&s.def.index) {
                let start = s.offset as usize;
                let size = s.def.storage_size();
                s.len = value::encode_default(s.def, node_id, &mut self.arena[start..start + size])
                    as u32;
            }
        }
    }

    fn node_id(&self) -> u8 {
        self.node_id
    }

    fn for_each(&self, f: &mut dyn FnMut(Entry<'_>)) {
        for (_, s) in self.map.iter() {
            let start = s.offset as usize;
            f(Entry {
                def: s.def,
                data: &self.arena[start..start + s.len as usize],
            });
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
