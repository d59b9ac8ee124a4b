//! Data types and values: how `DefaultValue`, `ParameterValue`, `LowLimit` and `HighLimit` are
//! read for each CiA 301 type, and written back.
//!
//! - BOOLEAN, the integers, TIME_OF_DAY and TIME_DIFFERENCE (a 48-bit number): numbers, a
//!   `$NODEID` expression for the integers. A signed type written in hex or octal is the bit
//!   pattern (`0xFFFF` is −1 for INTEGER16), in decimal the value.
//! - REAL32/REAL64: decimal floating point, or `0x` and the IEEE 754 bits.
//! - VISIBLE_STRING and UNICODE_STRING: the text itself (UNICODE_STRING travels as UTF-16LE).
//! - OCTET_STRING and DOMAIN: hex digits, two per byte, spaces between bytes allowed.

mod write;

pub use write::canonical_limit;
pub(crate) use write::{unsigned_text, write, write_limit};

use super::error::EdsErrorKind;
use super::number::{self, Literal, NumError};
use crate::od::{DataType, Limit};
use alloc::format;
use alloc::string::String;
use alloc::vec::Vec;

/// A value as a device description states it, before it is tied to a node.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// BOOLEAN, the unsigned integers, TIME_OF_DAY, TIME_DIFFERENCE.
    Unsigned(u64),
    /// The signed integers.
    Signed(i64),
    /// REAL32 (exactly an `f32`'s value) and REAL64.
    Real(f64),
    /// `$NODEID + offset`: an integer that depends on the node-ID.
    NodeIdPlus(u32),
    /// Strings and domains: the bytes on the bus (UNICODE_STRING: UTF-16LE).
    Bytes(Vec<u8>),
}

impl Value {
    /// The bytes on the bus for an entry of type `t` on node `node_id`.
    #[must_use]
    pub fn to_bytes(&self, t: DataType, node_id: u8) -> Vec<u8> {
        let size = t.fixed_size().unwrap_or(8);
        let int = |v: u64| v.to_le_bytes()[..size].to_vec();
        match self {
            Value::Unsigned(v) => int(*v),
            Value::Signed(v) => int(*v as u64),
            Value::NodeIdPlus(v) => int(*v as u64 + node_id as u64),
            Value::Real(v) if t == DataType::Real32 => (*v as f32).to_le_bytes().to_vec(),
            Value::Real(v) => v.to_le_bytes().to_vec(),
            Value::Bytes(b) => b.clone(),
        }
    }

    /// The value as a dictionary limit of type `t` on node `node_id`; `None` for strings.
    #[must_use]
    pub fn to_limit(&self, t: DataType, node_id: u8) -> Option<Limit> {
        Some(match self {
            Value::Unsigned(v) => Limit::Unsigned(*v),
            Value::Signed(v) => Limit::Signed(*v),
            Value::Real(v) => Limit::Real(*v),
            Value::NodeIdPlus(v) if t.is_signed() => Limit::Signed(*v as i64 + node_id as i64),
            Value::NodeIdPlus(v) => Limit::Unsigned(*v as u64 + node_id as u64),
            Value::Bytes(_) => return None,
        })
    }
}

/// The CiA 301 name of a data type (`UNSIGNED8`).
#[must_use]
pub const fn type_name(t: DataType) -> &'static str {
    use DataType::*;
    match t {
        Boolean => "BOOLEAN",
        Integer8 => "INTEGER8",
        Integer16 => "INTEGER16",
        Integer24 => "INTEGER24",
        Integer32 => "INTEGER32",
        Integer40 => "INTEGER40",
        Integer48 => "INTEGER48",
        Integer56 => "INTEGER56",
        Integer64 => "INTEGER64",
        Unsigned8 => "UNSIGNED8",
        Unsigned16 => "UNSIGNED16",
        Unsigned24 => "UNSIGNED24",
        Unsigned32 => "UNSIGNED32",
        Unsigned40 => "UNSIGNED40",
        Unsigned48 => "UNSIGNED48",
        Unsigned56 => "UNSIGNED56",
        Unsigned64 => "UNSIGNED64",
        Real32 => "REAL32",
        Real64 => "REAL64",
        VisibleString => "VISIBLE_STRING",
        OctetString => "OCTET_STRING",
        UnicodeString => "UNICODE_STRING",
        Domain => "DOMAIN",
        TimeOfDay => "TIME_OF_DAY",
        TimeDifference => "TIME_DIFFERENCE",
    }
}

/// True for the types whose values are numbers (not strings or domains).
pub(crate) const fn is_number(t: DataType) -> bool {
    t.fixed_size().is_some()
}

/// What to do with an integer outside the type: a value wraps as a C cast would; a limit is
/// clamped, which keeps its meaning (a high limit above the type's range is no limit).
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Fit {
    Wrap,
    Clamp,
}

/// A value read, and what a lenient reader should say it took when the text was not quite
/// right.
pub(crate) struct Read {
    pub value: Value,
    pub note: Option<(EdsErrorKind, String)>,
}

impl Read {
    fn ok(value: Value) -> Read {
        Read { value, note: None }
    }
    fn noted(value: Value, kind: EdsErrorKind, taken: String) -> Read {
        Read {
            value,
            note: Some((kind, taken)),
        }
    }
}

/// Reads `text` as a value of type `t`. `Err` when nothing can be taken.
pub(crate) fn read(text: &str, t: DataType, fit: Fit) -> Result<Read, EdsErrorKind> {
    use DataType::*;
    match t {
        VisibleString => Ok(text_value(text, |s| s.as_bytes().to_vec())),
        UnicodeString => Ok(text_value(text, |s| {
            s.encode_utf16().flat_map(u16::to_le_bytes).collect()
        })),
        OctetString | Domain => hex_bytes(text),
        Real32 | Real64 => real(text, t, fit),
        _ => integer(text, t, fit),
    }
}

fn bad(text: &str, expected: &'static str) -> EdsErrorKind {
    EdsErrorKind::BadValue {
        value: text.into(),
        expected,
    }
}

/// Text values lose control characters (tab excepted): no file can carry them.
fn text_value(text: &str, encode: impl Fn(&str) -> Vec<u8>) -> Read {
    if text.chars().any(|c| c.is_control() && c != '\t') {
        let clean: String = text
            .chars()
            .filter(|c| !c.is_control() || *c == '\t')
            .collect();
        // What the control characters hid is trimmed like any value.
        let clean = clean.trim();
        let v = Value::Bytes(encode(clean));
        return Read::noted(
            v,
            bad(text, "text without control characters"),
            format!("{clean:?}"),
        );
    }
    Read::ok(Value::Bytes(encode(text)))
}

fn hex_bytes(text: &str) -> Result<Read, EdsErrorKind> {
    let mut note = None;
    let mut digits: String = text.chars().filter(|c| !c.is_whitespace()).collect();
    if let Some(rest) = digits
        .strip_prefix("0x")
        .or_else(|| digits.strip_prefix("0X"))
    {
        digits = rest.into();
        note = Some("the digits after 0x");
    }
    if !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(bad(text, "hex digits, two per byte"));
    }
    if digits.len() % 2 == 1 {
        digits.insert(0, '0');
        note = Some("the digits with a leading 0");
    }
    let bytes: Vec<u8> = digits
        .as_bytes()
        .chunks(2)
        .map(|p| {
            let h = |b: u8| (b as char).to_digit(16).unwrap_or(0) as u8;
            h(p[0]) << 4 | h(p[1])
        })
        .collect();
    Ok(match note {
        None => Read::ok(Value::Bytes(bytes)),
        Some(n) => Read::noted(
            Value::Bytes(bytes),
            bad(text, "hex digits, two per byte"),
            n.into(),
        ),
    })
}

fn real(text: &str, t: DataType, fit: Fit) -> Result<Read, EdsErrorKind> {
    let s = number::strip_comment(text.trim());
    let expected = "a floating-point number";
    if let Some(h) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        let bits = u64::from_str_radix(h, 16).map_err(|_| bad(text, expected))?;
        return match t {
            DataType::Real32 => {
                let b = u32::try_from(bits).map_err(|_| EdsErrorKind::OutOfRange {
                    value: text.into(),
                    range: "the 32 bits of a REAL32".into(),
                })?;
                Ok(Read::ok(Value::Real(f32::from_bits(b) as f64)))
            }
            _ => Ok(Read::ok(Value::Real(f64::from_bits(bits)))),
        };
    }
    // A value of a REAL32 is read as an f32 so that it is exactly the number written; a limit
    // keeps the f64 the dictionary compares with.
    let parse = |s: &str| -> Option<f64> {
        if t == DataType::Real32 && fit == Fit::Wrap {
            s.parse::<f32>().ok().map(|v| v as f64)
        } else {
            s.parse::<f64>().ok()
        }
    };
    if let Some(v) = parse(s) {
        return Ok(Read::ok(Value::Real(v)));
    }
    // A decimal comma, as some localized tools write it.
    let dotted = s.replacen(',', ".", 1);
    match parse(&dotted) {
        Some(v) if s.contains(',') => Ok(Read::noted(
            Value::Real(v),
            bad(text, expected),
            format!("{v}"),
        )),
        _ => Err(bad(text, expected)),
    }
}

fn integer(text: &str, t: DataType, fit: Fit) -> Result<Read, EdsErrorKind> {
    let expected = if t == DataType::Boolean {
        "0 or 1"
    } else {
        "an integer or a $NODEID expression"
    };
    let (e, octal_note) = match number::expr(text) {
        Ok(e) => (e, None),
        Err(NumError::OctalDigits(v)) => (
            number::Expr {
                node_id: false,
                literal: Literal {
                    value: v,
                    radix: 10,
                    signed: v < 0,
                },
            },
            Some(EdsErrorKind::OctalDigits { value: text.into() }),
        ),
        Err(NumError::Overflow) => {
            return Err(EdsErrorKind::OutOfRange {
                value: text.into(),
                range: "64 bits".into(),
            })
        }
        Err(NumError::Bad) if t == DataType::Boolean => {
            let s = number::strip_comment(text.trim());
            let v = if s.eq_ignore_ascii_case("true") {
                1
            } else if s.eq_ignore_ascii_case("false") {
                0
            } else {
                return Err(bad(text, expected));
            };
            return Ok(Read::noted(
                Value::Unsigned(v),
                bad(text, expected),
                format!("{v}"),
            ));
        }
        Err(NumError::Bad) => return Err(bad(text, expected)),
    };
    if e.node_id {
        if t == DataType::Boolean {
            return Err(EdsErrorKind::Misplaced {
                why: "$NODEID in a BOOLEAN",
            });
        }
        let off = e.literal.value;
        return match u32::try_from(off) {
            Ok(o) => Ok(Read::ok(Value::NodeIdPlus(o))),
            Err(_) => Err(EdsErrorKind::OutOfRange {
                value: text.into(),
                range: "a 32-bit $NODEID offset".into(),
            }),
        };
    }
    let mut r = fit_integer(text, t, e.literal, fit);
    if let (Some(kind), None) = (octal_note, &r.note) {
        r.note = Some((kind, format!("{} (decimal)", e.literal.value)));
    }
    Ok(r)
}

/// Fits a literal into the type's bits.
fn fit_integer(text: &str, t: DataType, l: Literal, fit: Fit) -> Read {
    let bits = match t {
        DataType::Boolean => 1,
        _ => t.fixed_size().unwrap_or(8) as u32 * 8,
    };
    let v = l.value;
    let umax: i128 = (1i128 << bits) - 1;
    let out_of_range = |value: Value, taken: String| {
        Read::noted(
            value,
            EdsErrorKind::OutOfRange {
                value: text.into(),
                range: type_name(t).into(),
            },
            taken,
        )
    };
    if t.is_signed() {
        let (min, max) = (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1);
        // Hex and octal write the bit pattern.
        let pattern = l.radix != 10 && !l.signed && v >= 0 && v <= umax;
        if (min..=max).contains(&v) {
            return Read::ok(Value::Signed(v as i64));
        }
        if pattern {
            return Read::ok(Value::Signed(sign_extend(v, bits)));
        }
        let taken = match fit {
            Fit::Clamp => v.clamp(min, max) as i64,
            Fit::Wrap => sign_extend(v & umax, bits),
        };
        return out_of_range(Value::Signed(taken), format!("{taken}"));
    }
    if (0..=umax).contains(&v) {
        return Read::ok(Value::Unsigned(v as u64));
    }
    let taken = match (fit, t) {
        (_, DataType::Boolean) => (v != 0) as u64,
        (Fit::Clamp, _) => v.clamp(0, umax) as u64,
        (Fit::Wrap, _) => (v & umax) as u64,
    };
    out_of_range(Value::Unsigned(taken), unsigned_text(taken))
}

pub(crate) fn sign_extend(v: i128, bits: u32) -> i64 {
    let shift = 128 - bits;
    ((v << shift) >> shift) as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn val(text: &str, t: DataType) -> Value {
        let r = read(text, t, Fit::Wrap).unwrap();
        assert!(r.note.is_none(), "{text:?} as {t:?}: {:?}", r.note);
        r.value
    }

    #[test]
    fn every_type_reads_and_writes_back() {
        use DataType::*;
        for t in DataType::ALL {
            let text = match t {
                Boolean => "1",
                VisibleString => "hello world",
                UnicodeString => "grüße ☃",
                OctetString | Domain => "0102AB",
                Real32 | Real64 => "1.5",
                _ if t.is_signed() => "-3",
                _ => "0x12",
            };
            let bytes = val(text, t).to_bytes(t, 0);
            let back = write(t, &bytes).unwrap();
            assert_eq!(val(&back, t).to_bytes(t, 0), bytes, "{t:?}");
        }
    }

    #[test]
    fn signed_hex_is_the_bit_pattern_and_decimal_the_value() {
        assert_eq!(val("0xFFFF", DataType::Integer16), Value::Signed(-1));
        assert_eq!(
            val("0x800000", DataType::Integer24),
            Value::Signed(-0x800000)
        );
        assert_eq!(val("-32768", DataType::Integer16), Value::Signed(-32768));
        let r = read("40000", DataType::Integer16, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Signed(40000 - 65536));
        assert!(r.note.is_some());
        let r = read("40000", DataType::Integer16, Fit::Clamp).unwrap();
        assert_eq!(r.value, Value::Signed(32767));
    }

    #[test]
    fn out_of_range_unsigned_wraps_values_and_clamps_limits() {
        let r = read("0x1FF", DataType::Unsigned8, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Unsigned(0xFF));
        assert_eq!(r.note.unwrap().1, "0xFF");
        let r = read("-1", DataType::Unsigned16, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Unsigned(0xFFFF));
        let r = read("1000", DataType::Unsigned8, Fit::Clamp).unwrap();
        assert_eq!(r.value, Value::Unsigned(255));
        let r = read("0x1000000", DataType::Unsigned24, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Unsigned(0));
    }

    #[test]
    fn reals_take_bits_and_decimal_commas() {
        assert_eq!(val("0x3F800000", DataType::Real32), Value::Real(1.0));
        assert_eq!(val("0.1", DataType::Real32), Value::Real(0.1f32 as f64));
        assert_eq!(val("0.1", DataType::Real64), Value::Real(0.1));
        let r = read("2,5", DataType::Real64, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Real(2.5));
        assert!(r.note.is_some());
        assert!(read("abc", DataType::Real32, Fit::Wrap).is_err());
    }

    #[test]
    fn octet_strings_are_hex_and_strings_are_text() {
        assert_eq!(
            val("01 02 ff", DataType::OctetString),
            Value::Bytes(alloc::vec![1, 2, 0xFF])
        );
        let r = read("0x123", DataType::Domain, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Bytes(alloc::vec![0x01, 0x23]));
        assert!(read("xyz", DataType::Domain, Fit::Wrap).is_err());
        assert_eq!(
            val("a;b = c", DataType::VisibleString),
            Value::Bytes(b"a;b = c".to_vec())
        );
        assert_eq!(
            val("€", DataType::UnicodeString),
            Value::Bytes(alloc::vec![0xAC, 0x20])
        );
    }

    #[test]
    fn booleans_and_node_ids() {
        assert_eq!(
            val("$NODEID+0x180", DataType::Unsigned32),
            Value::NodeIdPlus(0x180)
        );
        assert_eq!(
            Value::NodeIdPlus(0x180).to_bytes(DataType::Unsigned32, 5),
            0x185u32.to_le_bytes()
        );
        assert!(read("$NODEID", DataType::Boolean, Fit::Wrap).is_err());
        let r = read("TRUE", DataType::Boolean, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Unsigned(1));
        let r = read("7", DataType::Boolean, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Unsigned(1));
        assert!(r.note.is_some());
    }

    #[test]
    fn control_characters_go_and_what_they_hid_is_trimmed() {
        let r = read("\0 a\u{1}b \0", DataType::VisibleString, Fit::Wrap).unwrap();
        assert_eq!(r.value, Value::Bytes(b"ab".to_vec()));
        assert!(r.note.is_some());
        assert!(write(DataType::VisibleString, b"ab").is_ok());
    }

    #[test]
    fn unwritable_values_are_refused() {
        assert!(write(DataType::VisibleString, b" padded").is_err());
        assert!(write(DataType::VisibleString, b"a\nb").is_err());
        assert!(write(DataType::VisibleString, &[0xE4]).is_err());
        assert!(write(DataType::UnicodeString, &[0x41]).is_err());
        assert!(write(DataType::Unsigned16, &[1]).is_err());
    }
}
