//! The objects: the object lists, each object's section and its sub-objects' sections.

use super::Importer;
use crate::eds::error::{EdsError, EdsErrorKind};
use crate::eds::ini::{Pair, Section, SectionId};
use crate::eds::model::{AccessType, Object, ObjectCode, SubObject};
use crate::eds::number::{self, NumError};
use crate::eds::value::{self, type_name, Fit, Value};
use crate::eds::{MAX_CAPACITY, MAX_NAME_BYTES};
use crate::od::DataType;
use alloc::collections::BTreeMap;
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

/// The object lists, in the order CiA 306 gives them.
const LISTS: [&str; 3] = ["mandatoryobjects", "optionalobjects", "manufacturerobjects"];

/// What a sub-object takes from elsewhere than its own section.
#[derive(Default)]
pub(super) struct Overrides<'t> {
    /// The name (a `CompactSubObj` entry: the object's name and the sub-index, or
    /// `[xxxxName]`).
    pub name: Option<String>,
    /// `[xxxxValue]`'s `ParameterValue`.
    pub value: Option<Pair<'t>>,
    /// `[xxxxDenotation]`'s denotation.
    pub denotation: Option<String>,
    /// The data type when the section has none, and whether that is a warning: UNSIGNED8
    /// for sub-index 0 of an array or record (a warning), DOMAIN for a DOMAIN object (none).
    pub default_type: Option<(DataType, bool)>,
}

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

    /// One entry from its section (or from its object's section: a VAR, a compact array).
    pub(super) fn entry(
        &mut self,
        index: u16,
        sub: u8,
        s: &Section<'t>,
        over: Overrides<'t>,
    ) -> Result<SubObject, EdsError> {
        self.count_entry(s.line, s.name)?;
        let name = match (over.name, s.get("ParameterName").copied()) {
            (Some(n), _) => n,
            (None, Some(p)) => self.name(s, &p)?,
            (None, None) => {
                let n = format!("{index:04X}sub{sub:X}");
                self.missing(s, "ParameterName", format_args!("ParameterName={n}"))?;
                n
            }
        };
        let t = self.data_type(s, over.default_type)?;
        let access = self.access(s, t)?;
        let mut e = SubObject {
            index,
            sub,
            name,
            denotation: over
                .denotation
                .or_else(|| s.get("Denotation").map(|p| p.value.into())),
            data_type: t,
            access,
            pdo_mapping: self.flag(Some(s), "PDOMapping")?,
            default: self.value(s, s.get("DefaultValue").copied(), t, Fit::Wrap)?,
            low: None,
            high: None,
            value: None,
            upload_file: s.get("UploadFile").map(|p| p.value.into()),
            download_file: s.get("DownloadFile").map(|p| p.value.into()),
            obj_flags: self
                .number(Some(s), "ObjFlags", u32::MAX as u64)?
                .unwrap_or(0) as u32,
            max_length: None,
            line: s.line,
        };
        let value_pair = over.value.or_else(|| s.get("ParameterValue").copied());
        e.value = self.value(s, value_pair, t, Fit::Wrap)?;
        let limits = [s.get("LowLimit").copied(), s.get("HighLimit").copied()];
        let max_length = s.get("MaxLength").copied();
        if value::is_number(t) {
            e.low = self.value(s, limits[0], t, Fit::Clamp)?;
            e.high = self.value(s, limits[1], t, Fit::Clamp)?;
            self.check_limits(s, &e)?;
            if let Some(p) = max_length {
                let kind = EdsErrorKind::Misplaced {
                    why: "MaxLength on a fixed-size type",
                };
                self.problem(s, Some(&p), kind, "the key ignored")?;
            }
        } else {
            for p in limits.into_iter().flatten() {
                let kind = EdsErrorKind::Misplaced {
                    why: "a limit on a string or domain",
                };
                self.problem(s, Some(&p), kind, "the limit ignored")?;
            }
            e.max_length = self
                .number(Some(s), "MaxLength", MAX_CAPACITY as u64)?
                .map(|v| v as u32);
        }
        if t != DataType::Domain {
            for key in ["UploadFile", "DownloadFile"] {
                if let Some(p) = s.get(key).copied() {
                    let kind = EdsErrorKind::Misplaced {
                        why: "a file name on an entry that is not a DOMAIN",
                    };
                    self.problem(s, Some(&p), kind, "the file name kept")?;
                }
            }
        }
        self.hold(&e)?;
        Ok(e)
    }

    fn data_type(
        &mut self,
        s: &Section<'_>,
        fallback: Option<(DataType, bool)>,
    ) -> Result<DataType, EdsError> {
        let Some(p) = s.get("DataType").copied() else {
            let t = match fallback {
                // A DOMAIN object needs no DataType.
                Some((t, false)) => return Ok(t),
                Some((t, true)) => t,
                None => DataType::Domain,
            };
            self.missing(s, "DataType", format_args!("DataType={}", type_name(t)))?;
            return Ok(t);
        };
        let code = match number::literal(number::strip_comment(p.value)) {
            Ok(l) => l.value,
            Err(NumError::OctalDigits(v)) => {
                let kind = EdsErrorKind::OctalDigits {
                    value: p.value.into(),
                };
                self.problem(s, Some(&p), kind, format_args!("{v} (decimal)"))?;
                v
            }
            Err(_) => {
                // A type's name instead of its number.
                let named = DataType::ALL
                    .into_iter()
                    .find(|t| type_name(*t).eq_ignore_ascii_case(p.value.trim()));
                let kind = EdsErrorKind::BadValue {
                    value: p.value.into(),
                    expected: "a data type index",
                };
                let t = named.unwrap_or(DataType::Domain);
                self.problem(s, Some(&p), kind, type_name(t))?;
                return Ok(t);
            }
        };
        match u16::try_from(code).ok().and_then(DataType::from_code) {
            Some(t) => Ok(t),
            None => {
                let kind = EdsErrorKind::UnknownDataType {
                    code: code.clamp(0, u32::MAX as i128) as u32,
                };
                self.problem(s, Some(&p), kind, "DOMAIN")?;
                Ok(DataType::Domain)
            }
        }
    }

    fn access(&mut self, s: &Section<'_>, t: DataType) -> Result<AccessType, EdsError> {
        let Some(p) = s.get("AccessType").copied() else {
            let a = if t == DataType::Domain {
                AccessType::Rw
            } else {
                AccessType::Ro
            };
            self.missing(s, "AccessType", format_args!("AccessType={}", a.as_str()))?;
            return Ok(a);
        };
        if let Some(a) = AccessType::parse(p.value) {
            return Ok(a);
        }
        // Spellings seen in files written by hand or by other tools.
        let a = match p.value.trim().to_ascii_lowercase().as_str() {
            "w" | "write" | "writeonly" | "write-only" => AccessType::Wo,
            "readwrite" | "read-write" | "r/w" => AccessType::Rw,
            _ => AccessType::Ro,
        };
        let kind = EdsErrorKind::UnknownAccessType {
            value: p.value.into(),
        };
        self.problem(s, Some(&p), kind, a.as_str())?;
        Ok(a)
    }

    /// A value key of type `t`; `None` when absent or empty. A value that cannot be read is a
    /// problem (lenient: no value).
    pub(super) fn value(
        &mut self,
        s: &Section<'_>,
        p: Option<Pair<'_>>,
        t: DataType,
        fit: Fit,
    ) -> Result<Option<Value>, EdsError> {
        let Some(p) = p else { return Ok(None) };
        if p.value.is_empty() {
            // An empty string is a value; an empty number is none.
            return Ok((!value::is_number(t)).then(|| Value::Bytes(Vec::new())));
        }
        match value::read(p.value, t, fit) {
            Ok(r) => {
                if let Some((kind, taken)) = r.note {
                    self.problem(s, Some(&p), kind, taken)?;
                }
                Ok(Some(r.value))
            }
            Err(kind) => {
                self.problem(s, Some(&p), kind, "no value")?;
                Ok(None)
            }
        }
    }

    /// Limits the right way round, and the default and the parameter value within them
    /// (node-relative ones checked on node 1).
    fn check_limits(&mut self, s: &Section<'_>, e: &SubObject) -> Result<(), EdsError> {
        let t = e.data_type;
        let n = |v: &Option<Value>| v.as_ref().and_then(|v| v.to_limit(t, 1)).map(limit_f);
        let (low, high) = (n(&e.low), n(&e.high));
        if let (Some(l), Some(h)) = (low, high) {
            if l > h {
                let p = s.get("LowLimit").copied();
                let kind = EdsErrorKind::OutsideLimits {
                    value: p.map(|p| p.value).unwrap_or_default().into(),
                };
                self.problem(s, p.as_ref(), kind, "the limits as they are")?;
                return Ok(());
            }
        }
        for key in ["DefaultValue", "ParameterValue"] {
            let v = if key == "DefaultValue" {
                &e.default
            } else {
                &e.value
            };
            let Some(x) = n(v) else { continue };
            if low.is_some_and(|l| x < l) || high.is_some_and(|h| x > h) {
                let p = s.get(key).copied();
                let kind = EdsErrorKind::OutsideLimits {
                    value: p.map(|p| p.value).unwrap_or_default().into(),
                };
                self.problem(s, p.as_ref(), kind, "the value as it is")?;
            }
        }
        Ok(())
    }
}

/// A limit as a number to compare (every integer of 64 bits fits an i128; reals as f64 bits
/// would not order, so they compare through `partial_cmp` via `Real`).
#[derive(Clone, Copy, PartialEq, PartialOrd)]
enum Num {
    Int(i128),
    Real(f64),
}

fn limit_f(l: crate::od::Limit) -> Num {
    match l {
        crate::od::Limit::Unsigned(v) => Num::Int(v as i128),
        crate::od::Limit::Signed(v) => Num::Int(v as i128),
        crate::od::Limit::Real(v) => Num::Real(v),
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

/// An entry the file implies without describing it (`CompactSubObj`, `CompactPDO`, a missing
/// sub-index 0): read-write, no default, not mappable.
pub(super) fn implied(index: u16, sub: u8, name: &str, t: DataType) -> SubObject {
    SubObject {
        index,
        sub,
        name: name.into(),
        denotation: None,
        data_type: t,
        access: AccessType::Rw,
        pdo_mapping: false,
        default: None,
        low: None,
        high: None,
        value: None,
        upload_file: None,
        download_file: None,
        obj_flags: 0,
        max_length: None,
        line: 0,
    }
}

impl SubObject {
    pub(super) fn with(mut self, access: AccessType, default: Option<Value>) -> SubObject {
        self.access = access;
        self.default = default;
        self
    }
}
