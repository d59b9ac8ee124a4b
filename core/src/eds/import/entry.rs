//! One entry (sub-object): its name, data type, access, values and limits, each read and
//! checked.

use super::Importer;
use crate::eds::error::{EdsError, EdsErrorKind};
use crate::eds::ini::{Pair, Section};
use crate::eds::model::{AccessType, SubObject};
use crate::eds::number::{self, NumError};
use crate::eds::value::{self, type_name, Fit, Value};
use crate::eds::MAX_CAPACITY;
use crate::od::DataType;
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

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
        // An empty ParameterValue on a string whose default is not empty: the empty string
        // (what the configuration holds, and what an export of an empty string writes), where
        // lely reads "not configured" and keeps the default. Not a fault of the file, so not a
        // warning strict mode refuses: a `tracing` warning says which reading was taken.
        let default_set = matches!(&e.default, Some(Value::Bytes(b)) if !b.is_empty());
        if let Some(p) = value_pair.filter(|p| p.value.is_empty() && default_set) {
            let at = self.at(s, Some(&p));
            tracing::warn!(
                target: "duocan::eds",
                "{at}: empty over a non-empty default: read as the empty string (lely keeps \
                 the default)"
            );
        }
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
            // An empty limit is none, on a string as on a number.
            for p in limits.into_iter().flatten().filter(|p| !p.value.is_empty()) {
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
        // Spellings seen in files written by hand or by other tools; a trailing `;` (a
        // comment, in the INI files other tools write) is not part of it.
        let t = number::strip_comment(p.value).trim().to_ascii_lowercase();
        let a = AccessType::parse(&t).unwrap_or(match t.as_str() {
            "w" | "write" | "writeonly" | "write-only" => AccessType::Wo,
            "readwrite" | "read-write" | "r/w" => AccessType::Rw,
            _ => AccessType::Ro,
        });
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
