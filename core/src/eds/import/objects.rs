//! The objects: the object lists, each object's section and its sub-objects' sections (each
//! entry in [`super::entry`]).

use super::entry::{implied, Overrides};
use super::Importer;
use crate::eds::error::{EdsError, EdsErrorKind};
use crate::eds::ini::{Pair, Section, SectionId};
use crate::eds::model::{AccessType, Object, ObjectCode};
use crate::eds::number;
use crate::eds::value::Value;
use crate::eds::MAX_NAME_BYTES;
use crate::od::DataType;
use alloc::collections::BTreeMap;
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

/// The object lists, in the order CiA 306 gives them.
const LISTS: [&str; 3] = ["mandatoryobjects", "optionalobjects", "manufacturerobjects"];

impl<'t> Importer<'_, 't> {
    /// Every object the lists name or a section describes.
    pub(super) fn objects(&mut self) -> Result<BTreeMap<u16, Object>, EdsError> {
        let ini = self.ini;
        // Index → where it is listed.
        let mut listed: BTreeMap<u16, (&str, Pair<'t>)> = BTreeMap::new();
        let mut any_list = false;
        for name in LISTS {
            let Some(s) = ini.named(name) else { continue };
            any_list = true;
            let stated = self.number(Some(s), "SupportedObjects", 0xFFFF)?;
            let mut found = 0u32;
            for p in &s.pairs {
                if p.key.eq_ignore_ascii_case("SupportedObjects") {
                    continue;
                }
                found += 1;
                match number::literal(number::strip_comment(p.value)) {
                    Ok(l) if (0..=0xFFFF).contains(&l.value) => {
                        listed.insert(l.value as u16, (s.name, *p));
                    }
                    _ => {
                        let kind = EdsErrorKind::BadValue {
                            value: p.value.into(),
                            expected: "an object index",
                        };
                        self.problem(s, Some(p), kind, "the line ignored")?;
                    }
                }
            }
            if stated != Some(found as u64) {
                let p = s.get("SupportedObjects").copied();
                let kind = EdsErrorKind::CountMismatch {
                    stated: stated.unwrap_or(0) as u32,
                    found,
                };
                self.problem(s, p.as_ref(), kind, format_args!("the {found} listed"))?;
            }
        }
        if !any_list {
            let at = self.rep.at(0, Some("MandatoryObjects"), None);
            self.rep.problem(
                at,
                EdsErrorKind::MissingSection,
                "no object list ([MandatoryObjects], [OptionalObjects], [ManufacturerObjects]): every object section",
            )?;
        }
        // Sub-object sections by index, in one pass.
        let mut subs: BTreeMap<u16, Vec<(u8, &Section<'t>)>> = BTreeMap::new();
        for s in &ini.sections {
            if let SectionId::Sub(i, sub) = s.id {
                subs.entry(i).or_default().push((sub, s));
            }
        }
        let mut objects = BTreeMap::new();
        for s in &ini.sections {
            let SectionId::Object(index) = s.id else {
                continue;
            };
            if any_list && listed.remove(&index).is_none() {
                let kind = EdsErrorKind::ObjectList {
                    index,
                    what: "has a section but no object list names it",
                };
                self.problem(s, None, kind, "the object as its section describes it")?;
            }
            let o = self.object(index, s, subs.remove(&index).unwrap_or_default())?;
            objects.insert(index, o);
        }
        for (index, (list, p)) in listed {
            let at = self.rep.at(p.line, Some(list), Some(p.key));
            let kind = EdsErrorKind::ObjectList {
                index,
                what: "is listed but has no section",
            };
            self.rep.problem(at, kind, "no such object")?;
        }
        for (_, orphans) in subs {
            for (_, s) in orphans {
                self.problem(s, None, EdsErrorKind::Orphan, "the section ignored")?;
            }
        }
        Ok(objects)
    }

    /// A name without control characters, cut to [`MAX_NAME_BYTES`] (each a warning).
    pub(super) fn name(&mut self, sec: &Section<'_>, p: &Pair<'_>) -> Result<String, EdsError> {
        let mut v: String = p.value.into();
        if v.chars().any(|c| c.is_control() && c != '\t') {
            v = v
                .chars()
                .filter(|c| !c.is_control() || *c == '\t')
                .collect::<String>()
                .trim()
                .into();
            let kind = EdsErrorKind::BadValue {
                value: p.value.into(),
                expected: "a name without control characters",
            };
            self.problem(sec, Some(p), kind, format_args!("{v:?}"))?;
        }
        if v.len() <= MAX_NAME_BYTES {
            return Ok(v);
        }
        let v = cut_name(v);
        self.problem(
            sec,
            Some(p),
            EdsErrorKind::NameTooLong,
            format_args!("{v:?}"),
        )?;
        Ok(v)
    }

    fn object(
        &mut self,
        index: u16,
        s: &Section<'t>,
        mut subs: Vec<(u8, &Section<'t>)>,
    ) -> Result<Object, EdsError> {
        let name = match s.get("ParameterName").copied() {
            Some(p) => self.name(s, &p)?,
            None => {
                let n = format!("{index:04X}");
                self.missing(s, "ParameterName", format_args!("ParameterName={n}"))?;
                n
            }
        };
        let denotation = s.get("Denotation").map(|p| String::from(p.value));
        let compact = self.number(Some(s), "CompactSubObj", 254)?.unwrap_or(0) as u8;
        let sub_number = self.number(Some(s), "SubNumber", 255)?;
        let code = match self.number(Some(s), "ObjectType", 255)? {
            None => ObjectCode::Var,
            Some(c) => match ObjectCode::from_code(c as u32) {
                Some(code) => code,
                None => {
                    let taken = if compact > 0 {
                        ObjectCode::Array
                    } else if sub_number.is_some() {
                        ObjectCode::Record
                    } else {
                        ObjectCode::Var
                    };
                    let p = s.get("ObjectType").copied();
                    let kind = EdsErrorKind::UnknownObjectType { code: c as u32 };
                    self.problem(s, p.as_ref(), kind, format_args!("{taken:?}"))?;
                    taken
                }
            },
        };
        let mut o = Object {
            index,
            name,
            denotation,
            code,
            subs: BTreeMap::new(),
            links: Vec::new(),
            compact: false,
            implicit: false,
            line: s.line,
        };
        if code == ObjectCode::Null {
            return Ok(o);
        }
        if !code.has_subs() {
            for (_, sub) in &subs {
                let kind = EdsErrorKind::Misplaced {
                    why: "a sub-object section of a VAR",
                };
                self.problem(sub, None, kind, "the section ignored")?;
            }
            let over = Overrides {
                name: Some(o.name.clone()),
                denotation: o.denotation.clone(),
                default_type: (code == ObjectCode::Domain).then_some((DataType::Domain, false)),
                ..Overrides::default()
            };
            let e = self.entry(index, 0, s, over)?;
            o.subs.insert(0, e);
            return Ok(o);
        }
        if compact > 0 && !subs.is_empty() {
            let kind = EdsErrorKind::Misplaced {
                why: "CompactSubObj and sub-object sections",
            };
            self.problem(s, None, kind, "the sub-object sections")?;
        } else if compact > 0 {
            if sub_number.is_some() {
                let kind = EdsErrorKind::Misplaced {
                    why: "both SubNumber and CompactSubObj",
                };
                self.problem(s, None, kind, "CompactSubObj")?;
            }
            self.compact_array(&mut o, s, compact)?;
            return Ok(o);
        }
        subs.sort_by_key(|(sub, _)| *sub);
        let found = subs.len() as u64;
        let taken = format!("the {found} sub-objects described");
        match sub_number {
            None => self.missing(s, "SubNumber", &taken)?,
            Some(n) if n != found => {
                let p = s.get("SubNumber").copied();
                let kind = EdsErrorKind::CountMismatch {
                    stated: n as u32,
                    found: found as u32,
                };
                self.problem(s, p.as_ref(), kind, &taken)?;
            }
            Some(_) => {}
        }
        for (sub, sec) in subs {
            let over = Overrides {
                default_type: (sub == 0).then_some((DataType::Unsigned8, true)),
                ..Overrides::default()
            };
            let e = self.entry(index, sub, sec, over)?;
            o.subs.insert(sub, e);
        }
        self.sub_zero(&mut o, s)?;
        Ok(o)
    }

    /// An array or record without sub-index 0 gets one (UNSIGNED8, const, the highest
    /// sub-index), with a warning.
    pub(super) fn sub_zero(&mut self, o: &mut Object, s: &Section<'_>) -> Result<(), EdsError> {
        if o.subs.contains_key(&0) {
            return Ok(());
        }
        let highest = o.subs.keys().next_back().copied().unwrap_or(0);
        self.problem(
            s,
            None,
            EdsErrorKind::NoSubZero,
            format_args!("sub-index 0, UNSIGNED8 const {highest}"),
        )?;
        self.count_entry(s.line, s.name)?;
        o.subs.insert(
            0,
            implied(
                o.index,
                0,
                "Highest sub-index supported",
                DataType::Unsigned8,
            )
            .with(AccessType::Const, Some(Value::Unsigned(highest as u64))),
        );
        Ok(())
    }
}

/// `name` cut to [`MAX_NAME_BYTES`] at a character boundary, without trailing spaces.
pub(super) fn cut_name(mut name: String) -> String {
    if name.len() > MAX_NAME_BYTES {
        let mut end = MAX_NAME_BYTES;
        while !name.is_char_boundary(end) {
            end -= 1;
        }
        name.truncate(end);
        let trimmed = name.trim_end().len();
        name.truncate(trimmed);
    }
    name
}
