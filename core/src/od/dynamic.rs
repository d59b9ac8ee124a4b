//! The dynamic dictionary (`alloc`): entries inserted and removed at run time. A master starts
//! with its own ~1,300 entries and adds a handful per slave as slaves join.

use super::def::{key, ObjectDef};
use super::parameters::StorageError;
use super::{miss, value, BuildError, Entry, KeyHasher, ObjectDictionary};
use crate::od::abort::AbortCode;
use alloc::boxed::Box;
use alloc::vec::Vec;
use core::hash::BuildHasherDefault;
use core::ops::RangeInclusive;

struct DynEntry {
    def: ObjectDef,
    data: Vec<u8>,
    /// The value at the last capture when it differs from the default (most entries keep
    /// their default, and cost nothing here).
    power_on: Option<Box<[u8]>>,
    /// Name and default held here rather than in the definition (entries built at run time,
    /// from a device description); `None` for entries from `'static` tables.
    owned: Option<Box<Owned>>,
}

struct Owned {
    name: Box<str>,
    default: Option<Box<[u8]>>,
}

impl DynEntry {
    fn new(def: ObjectDef, node_id: u8, owned: Option<Box<Owned>>) -> DynEntry {
        let mut e = DynEntry {
            def,
            data: Vec::new(),
            power_on: None,
            owned,
        };
        e.data = e.default_bytes(node_id);
        e
    }

    fn owned_default(&self) -> Option<&[u8]> {
        self.owned.as_ref().and_then(|o| o.default.as_deref())
    }

    fn default_bytes(&self, node_id: u8) -> Vec<u8> {
        match self.owned_default() {
            Some(d) => d.to_vec(),
            None => value::default_vec(&self.def, node_id),
        }
    }

    fn is_default(&self, node_id: u8) -> bool {
        match self.owned_default() {
            Some(d) => self.data == d,
            None => value::is_default(&self.def, node_id, &self.data),
        }
    }

    #[inline]
    fn entry(&self) -> Entry<'_> {
        match &self.owned {
            None => Entry::of(&self.def, &self.data),
            Some(o) => Entry {
                def: &self.def,
                data: &self.data,
                name: &o.name,
                default_bytes: o.default.as_deref(),
            },
        }
    }
}

/// A heap-backed dictionary whose entries can be inserted and removed while running.
#[derive(Default)]
pub struct DynamicDictionary {
    map: hashbrown::HashMap<u32, DynEntry, BuildHasherDefault<KeyHasher>>,
    node_id: u8,
}

impl DynamicDictionary {
    /// An empty dictionary for `node_id` (used by `$NODEID`-relative defaults).
    #[must_use]
    pub fn new(node_id: u8) -> Self {
        DynamicDictionary {
            map: Default::default(),
            node_id,
        }
    }

    /// A dictionary filled from definition tables.
    pub fn from_tables(node_id: u8, tables: &[&[ObjectDef]]) -> Result<Self, BuildError> {
        let mut od = Self::new(node_id);
        for t in tables {
            od.insert_all(t)?;
        }
        Ok(od)
    }

    /// Inserts one entry with its default value. A key that exists is an error.
    pub fn insert(&mut self, def: ObjectDef) -> Result<(), BuildError> {
        let k = def.key();
        if self.map.contains_key(&k) {
            return Err(BuildError::Duplicate {
                index: def.index,
                sub: def.sub,
            });
        }
        self.map.insert(k, DynEntry::new(def, self.node_id, None));
        Ok(())
    }

    /// Inserts one entry whose name (and, for strings and domains, default value) are not
    /// `'static`: an entry built at run time, from a device description. The dictionary keeps
    /// them; [`Entry::name`] and [`Entry::default_bytes`] give them back, and the default is
    /// the value after reset. `default` longer than the entry's capacity is
    /// [`BuildError::OutOfStorage`]; a key that exists is an error.
    pub fn insert_owned(
        &mut self,
        def: ObjectDef,
        name: &str,
        default: Option<&[u8]>,
    ) -> Result<(), BuildError> {
        let k = def.key();
        if self.map.contains_key(&k) {
            return Err(BuildError::Duplicate {
                index: def.index,
                sub: def.sub,
            });
        }
        if let Some(d) = default {
            if d.len() > def.storage_size() {
                return Err(BuildError::OutOfStorage {
                    index: def.index,
                    sub: def.sub,
                    capacity: def.storage_size(),
                });
            }
        }
        let owned = Owned {
            name: name.into(),
            default: default.map(Into::into),
        };
        self.map
            .insert(k, DynEntry::new(def, self.node_id, Some(Box::new(owned))));
        Ok(())
    }

    /// Inserts or replaces one entry (value reset to the default, which is also its power-on
    /// value).
    pub fn upsert(&mut self, def: ObjectDef) {
        self.map
            .insert(def.key(), DynEntry::new(def, self.node_id, None));
    }

    /// Inserts every definition of a table.
    pub fn insert_all(&mut self, defs: &[ObjectDef]) -> Result<(), BuildError> {
        self.map.reserve(defs.len());
        for d in defs {
            self.insert(*d)?;
        }
        Ok(())
    }

    /// Removes one entry; returns its definition if it existed.
    pub fn remove(&mut self, index: u16, sub: u8) -> Option<ObjectDef> {
        self.map.remove(&key(index, sub)).map(|e| e.def)
    }

    /// Removes every sub-index of an object; returns how many entries went.
    pub fn remove_object(&mut self, index: u16) -> usize {
        let before = self.map.len();
        self.map.retain(|_, e| e.def.index != index);
        before - self.map.len()
    }

    /// Sets the node-ID used by `$NODEID` defaults; takes effect at the next reset of the range.
    /// The power-on values go: they were taken for the old node-ID, so the next reset restores
    /// the defaults (capture again to keep a configuration).
    pub fn set_node_id(&mut self, node_id: u8) {
        self.node_id = node_id;
        for e in self.map.values_mut() {
            e.power_on = None;
        }
    }
}

impl ObjectDictionary for DynamicDictionary {
    #[inline(always)]
    fn get(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        match self.map.get(&key(index, sub)) {
            Some(e) => Ok(e.entry()),
            None => Err(miss(self.map.contains_key(&key(index, 0)))),
        }
    }

    fn store(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        let Some(e) = self.map.get_mut(&key(index, sub)) else {
            return Err(miss(self.map.contains_key(&key(index, 0))));
        };
        if data.len() > e.def.storage_size() {
            return Err(AbortCode::LENGTH_TOO_HIGH);
        }
        e.data.clear();
        e.data.extend_from_slice(data);
        Ok(())
    }

    fn reset_range(&mut self, range: RangeInclusive<u16>) {
        let node_id = self.node_id;
        for e in self.map.values_mut() {
            if range.contains(&e.def.index) {
                e.data = match &e.power_on {
                    Some(v) => v.to_vec(),
                    None => e.default_bytes(node_id),
                };
            }
        }
    }

    fn capture_power_on(&mut self) -> Result<(), StorageError> {
        let node_id = self.node_id;
        for e in self.map.values_mut() {
            e.power_on = (!e.is_default(node_id)).then(|| e.data.clone().into_boxed_slice());
        }
        Ok(())
    }

    fn node_id(&self) -> u8 {
        self.node_id
    }

    fn for_each(&self, f: &mut dyn FnMut(Entry<'_>)) {
        for e in self.map.values() {
            f(e.entry());
        }
    }

    fn len(&self) -> usize {
        self.map.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::{Access, DataType};

    #[test]
    fn entries_come_and_go_at_run_time() {
        let mut od = DynamicDictionary::new(1);
        od.insert(ObjectDef::u8(0x2100, 0, Access::Ro, 2)).unwrap();
        od.insert(ObjectDef::u32(0x2100, 1, Access::Rw, 7)).unwrap();
        od.insert(ObjectDef::u32(0x2100, 2, Access::Rw, 8)).unwrap();
        assert_eq!(
            od.insert(ObjectDef::u8(0x2100, 0, Access::Ro, 2)),
            Err(BuildError::Duplicate {
                index: 0x2100,
                sub: 0
            })
        );
        assert_eq!(od.get_value::<u32>(0x2100, 2), Ok(8));
        assert!(od.remove(0x2100, 2).is_some());
        assert_eq!(od.get(0x2100, 2).err(), Some(AbortCode::NO_SUB_INDEX));
        assert_eq!(od.remove_object(0x2100), 2);
        assert_eq!(od.get(0x2100, 1).err(), Some(AbortCode::NO_OBJECT));
        assert!(od.is_empty());
    }

    #[test]
    fn domain_capacity_is_enforced() {
        let mut od = DynamicDictionary::new(1);
        od.insert(ObjectDef::bytes(0x2200, 0, DataType::Domain, 1000))
            .unwrap();
        od.write(0x2200, 0, &[7; 1000]).unwrap();
        assert_eq!(od.read(0x2200, 0).map(<[u8]>::len), Ok(1000));
        assert_eq!(
            od.write(0x2200, 0, &[7; 1001]),
            Err(AbortCode::LENGTH_TOO_HIGH)
        );
    }
}
