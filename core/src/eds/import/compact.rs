//! What the file implies rather than writes: `CompactSubObj` arrays (with their `[xxxxName]`,
//! `[xxxxValue]` and `[xxxxDenotation]` sections), the PDOs of `CompactPDO`, and
//! `[xxxxObjectLinks]`.

use super::entry::{implied, Overrides};
use super::objects::cut_name;
use super::Importer;
use crate::eds::error::{EdsError, EdsErrorKind};
use crate::eds::ini::{Pair, Section, SectionId};
use crate::eds::model::{AccessType, DeviceInfo, Object, ObjectCode};
use crate::eds::number;
use crate::eds::value::Value;
use crate::od::DataType;
use alloc::collections::btree_map::Entry;
use alloc::collections::BTreeMap;
use alloc::format;
use alloc::vec;
use alloc::vec::Vec;

impl<'t> Importer<'_, 't> {
    /// Sub-index 0 (`NrOfObjects`, UNSIGNED8 ro, the count) and entries 1..=`n`, each as the
    /// object's section describes it, named `<name><n>` unless `[xxxxName]` names it.
    pub(super) fn compact_array(
        &mut self,
        o: &mut Object,
        s: &Section<'t>,
        n: u8,
    ) -> Result<(), EdsError> {
        o.compact = true;
        let index = o.index;
        let names = self.numbered(SectionId::Names(index), n)?;
        let values = self.numbered(SectionId::Values(index), n)?;
        let denotations = self.numbered(SectionId::Denotations(index), n)?;
        self.count_entry(s.line, s.name)?;
        o.subs.insert(
            0,
            implied(index, 0, "NrOfObjects", DataType::Unsigned8)
                .with(AccessType::Ro, Some(Value::Unsigned(n as u64))),
        );
        for sub in 1..=n {
            let i = sub as usize;
            let over = Overrides {
                name: Some(match &names[i] {
                    Some(p) => self.name(self.ini.get(&SectionId::Names(index)).unwrap_or(s), p)?,
                    None => cut_name(format!("{}{sub}", o.name)),
                }),
                value: values[i],
                denotation: None,
                default_type: None,
            };
            let mut e = self.entry(index, sub, s, over)?;
            if let Some(p) = denotations[i] {
                e.denotation = Some(p.value.into());
                self.hold(&e)?;
            }
            o.subs.insert(sub, e);
        }
        Ok(())
    }

    /// The pairs `1=…` to `n=…` of a `NrOfEntries` section, by sub-index (`None` where absent).
    fn numbered(&mut self, id: SectionId, n: u8) -> Result<Vec<Option<Pair<'t>>>, EdsError> {
        let mut out = vec![None; n as usize + 1];
        let Some(s) = self.ini.get(&id) else {
            return Ok(out);
        };
        let stated = self.number(Some(s), "NrOfEntries", 255)?;
        let mut found = 0u32;
        for p in &s.pairs {
            if p.key.eq_ignore_ascii_case("NrOfEntries") {
                continue;
            }
            match p.key.parse::<u8>() {
                Ok(sub) if (1..=n).contains(&sub) => {
                    out[sub as usize] = Some(*p);
                    found += 1;
                }
                _ => {
                    let kind = EdsErrorKind::Misplaced {
                        why: "a key that is no sub-index of the compact array",
                    };
                    self.problem(s, Some(p), kind, "the key ignored")?;
                }
            }
        }
        if stated != Some(found as u64) {
            let p = s.get("NrOfEntries").copied();
            let kind = EdsErrorKind::CountMismatch {
                stated: stated.unwrap_or(0) as u32,
                found,
            };
            self.problem(
                s,
                p.as_ref(),
                kind,
                format_args!("the {found} entries given"),
            )?;
        }
        Ok(out)
    }

    /// The PDOs `CompactPDO` implies: `NrOfRXPDO`/`NrOfTXPDO` communication and mapping
    /// objects, counting the ones the file describes, the missing half of a described pair
    /// included.
    pub(super) fn compact_pdo(
        &mut self,
        di: &DeviceInfo,
        objects: &mut BTreeMap<u16, Object>,
    ) -> Result<(), EdsError> {
        let mask = di.compact_pdo & 0x3F;
        if mask == 0 {
            return Ok(());
        }
        for (tx, comm, map, count) in [
            (false, 0x1400u16, 0x1600u16, di.nr_of_rx_pdo),
            (true, 0x1800, 0x1A00, di.nr_of_tx_pdo),
        ] {
            let described = |i: u16, o: &BTreeMap<u16, Object>| {
                o.contains_key(&(comm + i)) || o.contains_key(&(map + i))
            };
            let existing = (0..512).filter(|&i| described(i, objects)).count() as u16;
            let mut to_add = count.saturating_sub(existing);
            for i in 0..512u16 {
                if !described(i, objects) {
                    if to_add == 0 {
                        continue;
                    }
                    to_add -= 1;
                }
                if let Entry::Vacant(v) = objects.entry(comm + i) {
                    v.insert(self.pdo_comm(comm + i, i, tx, mask)?);
                }
                if let Entry::Vacant(v) = objects.entry(map + i) {
                    v.insert(self.pdo_map(map + i, tx)?);
                }
            }
        }
        Ok(())
    }

    fn implied_object(&mut self, index: u16, name: &str) -> Object {
        Object {
            index,
            name: name.into(),
            denotation: None,
            code: ObjectCode::Record,
            subs: BTreeMap::new(),
            links: Vec::new(),
            compact: false,
            implicit: true,
            line: 0,
        }
    }

    fn pdo_comm(&mut self, index: u16, n: u16, tx: bool, mask: u8) -> Result<Object, EdsError> {
        let (name, cob_name, base) = if tx {
            ("TPDO communication parameter", "COB-ID used by TPDO", 0x180)
        } else {
            ("RPDO communication parameter", "COB-ID used by RPDO", 0x200)
        };
        let mut o = self.implied_object(index, name);
        let highest = 8 - mask.leading_zeros() as u8;
        let subs: [(u8, &str, DataType, Option<Value>); 6] = [
            (
                1,
                cob_name,
                DataType::Unsigned32,
                // The predefined connection set for the first four, invalid beyond.
                Some(if n < 4 {
                    Value::NodeIdPlus(base + 0x100 * n as u32)
                } else {
                    Value::Unsigned(0x8000_0000)
                }),
            ),
            (
                2,
                "Transmission type",
                DataType::Unsigned8,
                Some(Value::Unsigned(0xFF)),
            ),
            (3, "Inhibit time", DataType::Unsigned16, None),
            (
                4,
                if tx {
                    "Reserved"
                } else {
                    "Compatibility entry"
                },
                DataType::Unsigned8,
                None,
            ),
            (5, "Event timer", DataType::Unsigned16, None),
            (6, "SYNC start value", DataType::Unsigned8, None),
        ];
        self.count_entry(0, "DeviceInfo")?;
        o.subs.insert(
            0,
            implied(index, 0, "Highest sub-index supported", DataType::Unsigned8)
                .with(AccessType::Const, Some(Value::Unsigned(highest as u64))),
        );
        for (sub, name, t, default) in subs {
            if mask & (1 << (sub - 1)) == 0 {
                continue;
            }
            self.count_entry(0, "DeviceInfo")?;
            o.subs.insert(
                sub,
                implied(index, sub, name, t).with(AccessType::Rw, default),
            );
        }
        Ok(o)
    }

    fn pdo_map(&mut self, index: u16, tx: bool) -> Result<Object, EdsError> {
        let name = if tx {
            "TPDO mapping parameter"
        } else {
            "RPDO mapping parameter"
        };
        let mut o = self.implied_object(index, name);
        self.count_entry(0, "DeviceInfo")?;
        o.subs.insert(
            0,
            implied(
                index,
                0,
                "Number of mapped application objects in PDO",
                DataType::Unsigned8,
            ),
        );
        for sub in 1..=64u8 {
            self.count_entry(0, "DeviceInfo")?;
            let e = implied(
                index,
                sub,
                &format!("Application object {sub}"),
                DataType::Unsigned32,
            );
            o.subs.insert(sub, e);
        }
        Ok(o)
    }

    /// `[xxxxObjectLinks]`: `ObjectLinks=n`, then `1=0x…` to `n=0x…`.
    pub(super) fn links(&mut self, objects: &mut BTreeMap<u16, Object>) -> Result<(), EdsError> {
        let ini = self.ini;
        for s in &ini.sections {
            let SectionId::Links(index) = s.id else {
                continue;
            };
            if !objects.contains_key(&index) {
                self.problem(s, None, EdsErrorKind::Orphan, "the section ignored")?;
                continue;
            }
            let stated = self.number(Some(s), "ObjectLinks", 0xFFFF)?;
            let mut links = Vec::new();
            for p in &s.pairs {
                if p.key.eq_ignore_ascii_case("ObjectLinks") {
                    continue;
                }
                match number::literal(number::strip_comment(p.value)) {
                    Ok(l) if p.key.parse::<u16>().is_ok() && (0..=0xFFFF).contains(&l.value) => {
                        links.push(l.value as u16)
                    }
                    _ => {
                        let kind = EdsErrorKind::BadValue {
                            value: p.value.into(),
                            expected: "n=an object index",
                        };
                        self.problem(s, Some(p), kind, "the line ignored")?;
                    }
                }
            }
            let found = links.len() as u32;
            if stated != Some(found as u64) {
                let p = s.get("ObjectLinks").copied();
                let kind = EdsErrorKind::CountMismatch {
                    stated: stated.unwrap_or(0) as u32,
                    found,
                };
                self.problem(s, p.as_ref(), kind, format_args!("the {found} links given"))?;
            }
            if let Some(o) = objects.get_mut(&index) {
                o.links = links;
            }
        }
        Ok(())
    }
}
