//! Values typed by a device description: what a by-name read returns and a PDO's entries hold
//! when the Rust type is not known at compile time.

use crate::eds::type_name;
use crate::od::DataType;
use std::fmt;

/// A value whose type comes from a data type (a device description's, or a PDO mapping's)
/// rather than from the Rust type asked for: what [`RemoteSdo::read_value`] returns and what
/// each entry of a received PDO holds.
///
/// [`RemoteSdo::read_value`]: super::RemoteSdo::read_value
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum AnyValue {
    /// BOOLEAN.
    Bool(bool),
    /// The unsigned integers of any width (UNSIGNED8 … UNSIGNED64), and TIME_OF_DAY and
    /// TIME_DIFFERENCE as their 48-bit number; an entry of unknown type in a PDO.
    Unsigned(u64),
    /// The signed integers of any width (INTEGER8 … INTEGER64).
    Signed(i64),
    /// REAL32 (exactly the `f32`'s value) and REAL64.
    Real(f64),
    /// VISIBLE_STRING and UNICODE_STRING that are valid text (trailing NULs removed).
    Text(String),
    /// OCTET_STRING, DOMAIN, and strings that are not valid text.
    Bytes(Vec<u8>),
}

impl AnyValue {
    /// The value as an unsigned integer, if it is a non-negative integer or a boolean.
    #[must_use]
    pub fn as_u64(&self) -> Option<u64> {
        match *self {
            AnyValue::Unsigned(v) => Some(v),
            AnyValue::Signed(v) => u64::try_from(v).ok(),
            AnyValue::Bool(b) => Some(u64::from(b)),
            _ => None,
        }
    }
    /// The value as a signed integer, if it is an integer that fits or a boolean.
    #[must_use]
    pub fn as_i64(&self) -> Option<i64> {
        match *self {
            AnyValue::Signed(v) => Some(v),
            AnyValue::Unsigned(v) => i64::try_from(v).ok(),
            AnyValue::Bool(b) => Some(i64::from(b)),
            _ => None,
        }
    }
    /// The value as a floating-point number, if it is a number.
    #[must_use]
    pub fn as_f64(&self) -> Option<f64> {
        match *self {
            AnyValue::Real(v) => Some(v),
            AnyValue::Unsigned(v) => Some(v as f64),
            AnyValue::Signed(v) => Some(v as f64),
            _ => None,
        }
    }
    /// The text, if the value is text.
    #[must_use]
    pub fn as_str(&self) -> Option<&str> {
        match self {
            AnyValue::Text(s) => Some(s),
            _ => None,
        }
    }

    /// Decodes the bytes an SDO upload returned for an entry of type `t`; `None` if a
    /// fixed-size type gets another number of bytes.
    #[must_use]
    pub fn decode(t: DataType, bytes: &[u8]) -> Option<AnyValue> {
        match t.fixed_size() {
            Some(n) if bytes.len() != n => None,
            Some(_) => {
                let mut b = [0u8; 8];
                b[..bytes.len()].copy_from_slice(bytes);
                let bits = t.bit_size().unwrap_or(64);
                Some(Self::from_bits(Some(t), u64::from_le_bytes(b), bits))
            }
            None => Some(text_or_bytes(t, bytes.to_vec())),
        }
    }

    /// The value of `bits` bits (`raw`, least significant first, as a PDO carries it) of an
    /// entry of type `t` (`None`: unknown, read as unsigned).
    pub(crate) fn from_bits(t: Option<DataType>, raw: u64, bits: u32) -> AnyValue {
        let Some(t) = t else {
            return AnyValue::Unsigned(raw);
        };
        match t {
            DataType::Boolean => AnyValue::Bool(raw != 0),
            DataType::Real32 if bits == 32 => AnyValue::Real(f64::from(f32::from_bits(raw as u32))),
            DataType::Real64 if bits == 64 => AnyValue::Real(f64::from_bits(raw)),
            t if t.is_signed() && (1..64).contains(&bits) => {
                // Sign-extend from the entry's top bit.
                let shift = 64 - bits;
                AnyValue::Signed(((raw << shift) as i64) >> shift)
            }
            t if t.is_signed() => AnyValue::Signed(raw as i64),
            t if t.fixed_size().is_none() => {
                let n = (bits as usize).div_ceil(8).min(8);
                text_or_bytes(t, raw.to_le_bytes()[..n].to_vec())
            }
            _ => AnyValue::Unsigned(raw),
        }
    }

    /// The `bits` bits an entry of type `t` (`None`: unknown) carries for this value, or why
    /// the value does not fit.
    pub(crate) fn to_bits(&self, t: Option<DataType>, bits: u32) -> Result<u64, String> {
        let bits = bits.min(64);
        let max = if bits >= 64 {
            u64::MAX
        } else {
            (1u64 << bits) - 1
        };
        let signed = t.is_some_and(DataType::is_signed);
        let what = t.map_or("an entry of unknown type", type_name);
        let too_big = |v: &dyn fmt::Display| format!("{v} does not fit {what} in {bits} bits");
        match (self, t) {
            (AnyValue::Real(v), Some(DataType::Real32)) if bits == 32 => {
                Ok(u64::from((*v as f32).to_bits()))
            }
            (AnyValue::Real(v), Some(DataType::Real64)) if bits == 64 => Ok(v.to_bits()),
            (AnyValue::Real(_), _) => Err(format!("a real number does not fit {what}")),
            (AnyValue::Bytes(_) | AnyValue::Text(_), Some(t)) if t.fixed_size().is_some() => {
                Err(format!("{what} is a number, not text or bytes"))
            }
            (AnyValue::Bytes(_) | AnyValue::Text(_), _) => {
                let b = self.to_bytes(t.unwrap_or(DataType::OctetString));
                if b.len() * 8 > bits as usize {
                    return Err(format!("{} byte(s) do not fit in {bits} bits", b.len()));
                }
                let mut buf = [0u8; 8];
                buf[..b.len()].copy_from_slice(&b);
                Ok(u64::from_le_bytes(buf))
            }
            (_, Some(t)) if t.is_real() => Err(format!("{what} is a real number: give a Real")),
            (AnyValue::Bool(b), _) => Ok(u64::from(*b)),
            (AnyValue::Unsigned(v), _) if signed => {
                let limit = max >> 1;
                if *v > limit {
                    return Err(too_big(v));
                }
                Ok(*v)
            }
            (AnyValue::Unsigned(v), _) => {
                if *v > max {
                    return Err(too_big(v));
                }
                Ok(*v)
            }
            (AnyValue::Signed(v), _) if !signed && t.is_some() => {
                if *v < 0 {
                    return Err(format!("{v} is negative and {what} is unsigned"));
                }
                AnyValue::Unsigned(*v as u64).to_bits(t, bits)
            }
            (AnyValue::Signed(v), _) => {
                let lo = if bits >= 64 {
                    i64::MIN
                } else {
                    -(1i64 << (bits - 1))
                };
                let hi = if bits >= 64 {
                    i64::MAX
                } else {
                    (1i64 << (bits - 1)) - 1
                };
                if *v < lo || *v > hi {
                    return Err(too_big(v));
                }
                Ok((*v as u64) & max)
            }
        }
    }

    /// The bytes an SDO download carries for an entry of type `t`, or why the value does not
    /// fit it.
    pub(crate) fn encode(&self, t: DataType) -> Result<Vec<u8>, String> {
        match t.fixed_size() {
            Some(n) => {
                let bits = t.bit_size().unwrap_or(64);
                let raw = self.to_bits(Some(t), bits)?;
                Ok(raw.to_le_bytes()[..n].to_vec())
            }
            None => match self {
                AnyValue::Text(_) | AnyValue::Bytes(_) => Ok(self.to_bytes(t)),
                _ => Err(format!(
                    "{} holds text or bytes, not a number",
                    type_name(t)
                )),
            },
        }
    }

    /// Text and bytes as an entry of type `t` carries them (UNICODE_STRING: UTF-16LE).
    fn to_bytes(&self, t: DataType) -> Vec<u8> {
        match self {
            AnyValue::Text(s) if t == DataType::UnicodeString => {
                s.encode_utf16().flat_map(u16::to_le_bytes).collect()
            }
            AnyValue::Text(s) => s.as_bytes().to_vec(),
            AnyValue::Bytes(b) => b.clone(),
            _ => Vec::new(),
        }
    }
}

/// A string type's bytes as text when they are text, else as bytes.
fn text_or_bytes(t: DataType, mut bytes: Vec<u8>) -> AnyValue {
    match t {
        DataType::VisibleString => {
            while bytes.last() == Some(&0) {
                bytes.pop();
            }
            match String::from_utf8(bytes) {
                Ok(s) => AnyValue::Text(s),
                Err(e) => AnyValue::Bytes(e.into_bytes()),
            }
        }
        DataType::UnicodeString if bytes.len().is_multiple_of(2) => {
            let units: Vec<u16> = bytes
                .chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]))
                .take_while(|u| *u != 0)
                .collect();
            match String::from_utf16(&units) {
                Ok(s) => AnyValue::Text(s),
                Err(_) => AnyValue::Bytes(bytes),
            }
        }
        _ => AnyValue::Bytes(bytes),
    }
}

impl fmt::Display for AnyValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AnyValue::Bool(b) => write!(f, "{b}"),
            AnyValue::Unsigned(v) => write!(f, "{v}"),
            AnyValue::Signed(v) => write!(f, "{v}"),
            AnyValue::Real(v) => write!(f, "{v}"),
            AnyValue::Text(s) => write!(f, "{s:?}"),
            AnyValue::Bytes(b) => {
                for (i, x) in b.iter().enumerate() {
                    if i > 0 {
                        f.write_str(" ")?;
                    }
                    write!(f, "{x:02X}")?;
                }
                Ok(())
            }
        }
    }
}

macro_rules! from_int {
    ($variant:ident, $wide:ty: $($t:ty),*) => {$(
        impl From<$t> for AnyValue {
            fn from(v: $t) -> Self {
                AnyValue::$variant(<$wide>::from(v))
            }
        }
    )*};
}
from_int!(Unsigned, u64: u8, u16, u32, u64);
from_int!(Signed, i64: i8, i16, i32, i64);
from_int!(Real, f64: f32, f64);

impl From<bool> for AnyValue {
    fn from(v: bool) -> Self {
        AnyValue::Bool(v)
    }
}
impl From<&str> for AnyValue {
    fn from(v: &str) -> Self {
        AnyValue::Text(v.into())
    }
}
impl From<String> for AnyValue {
    fn from(v: String) -> Self {
        AnyValue::Text(v)
    }
}
impl From<Vec<u8>> for AnyValue {
    fn from(v: Vec<u8>) -> Self {
        AnyValue::Bytes(v)
    }
}

/// The Rust type (or the call) that reads an entry of type `t`: for error messages.
pub(crate) fn rust_type(t: DataType) -> &'static str {
    match t {
        DataType::Boolean => "bool",
        DataType::Unsigned8 => "u8",
        DataType::Unsigned16 => "u16",
        DataType::Unsigned32 => "u32",
        DataType::Unsigned64 => "u64",
        DataType::Integer8 => "i8",
        DataType::Integer16 => "i16",
        DataType::Integer32 => "i32",
        DataType::Integer64 => "i64",
        DataType::Real32 => "f32",
        DataType::Real64 => "f64",
        DataType::VisibleString | DataType::UnicodeString => "a string (read_value)",
        _ => "read_value",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A value decoded as its fixed-size type encodes back to the same bytes (BOOLEAN
        /// reads any non-zero byte as true; a REAL32 NaN may come back quieted).
        #[test]
        fn fixed_size_values_round_trip(code in 1u16..0x20, bytes in proptest::collection::vec(any::<u8>(), 0..9)) {
            let Some(t) = DataType::from_code(code) else { return Ok(()) };
            let Some(v) = AnyValue::decode(t, &bytes) else {
                prop_assert!(t.fixed_size().is_some_and(|n| n != bytes.len()));
                return Ok(());
            };
            if t == DataType::Boolean || matches!(v, AnyValue::Real(r) if r.is_nan()) {
                return Ok(());
            }
            if t.fixed_size().is_some() {
                prop_assert_eq!(v.encode(t), Ok(bytes));
            }
        }
    }

    #[test]
    fn bits_round_trip_and_range() {
        let v = AnyValue::Signed(-3);
        let raw = v.to_bits(Some(DataType::Integer16), 12).unwrap();
        assert_eq!(raw, 0xFFD);
        assert_eq!(AnyValue::from_bits(Some(DataType::Integer16), raw, 12), v);
        assert!(AnyValue::Signed(2048)
            .to_bits(Some(DataType::Integer16), 12)
            .is_err());
        assert!(AnyValue::Unsigned(256)
            .to_bits(Some(DataType::Unsigned8), 8)
            .is_err());
        assert!(AnyValue::Signed(-1)
            .to_bits(Some(DataType::Unsigned8), 8)
            .is_err());
        assert!(AnyValue::Text("x".into())
            .to_bits(Some(DataType::Unsigned8), 8)
            .is_err());
        let r = AnyValue::Real(1.5);
        let raw = r.to_bits(Some(DataType::Real32), 32).unwrap();
        assert_eq!(AnyValue::from_bits(Some(DataType::Real32), raw, 32), r);
    }

    #[test]
    fn decode_by_type() {
        assert_eq!(
            AnyValue::decode(DataType::Unsigned16, &[0x34, 0x12]),
            Some(AnyValue::Unsigned(0x1234))
        );
        assert_eq!(AnyValue::decode(DataType::Unsigned16, &[1]), None);
        assert_eq!(
            AnyValue::decode(DataType::Integer8, &[0xFF]),
            Some(AnyValue::Signed(-1))
        );
        assert_eq!(
            AnyValue::decode(DataType::VisibleString, b"ab\0"),
            Some(AnyValue::Text("ab".into()))
        );
        assert_eq!(
            AnyValue::Text("é".into()).encode(DataType::UnicodeString),
            Ok(vec![0xE9, 0])
        );
        assert_eq!(
            AnyValue::Unsigned(7).encode(DataType::Unsigned24),
            Ok(vec![7, 0, 0])
        );
    }
}
