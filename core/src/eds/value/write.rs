//! Writing values back: the text each type's bytes are written as, so that they read back the
//! same, and limits as the dictionary compares them.

use super::sign_extend;
use crate::od::{DataType, Limit};
use alloc::format;
use alloc::string::String;

/// Why a value cannot be written so that it reads back the same.
pub(crate) type Unwritable = &'static str;

/// Writes the bytes of a value of type `t` as the file carries it.
pub(crate) fn write(t: DataType, bytes: &[u8]) -> Result<String, Unwritable> {
    use DataType::*;
    match t {
        VisibleString => {
            let s = core::str::from_utf8(bytes).map_err(|_| "the string is not UTF-8")?;
            text_ok(s)?;
            Ok(s.into())
        }
        UnicodeString => {
            if bytes.len() % 2 == 1 {
                return Err("the UNICODE_STRING has an odd number of bytes");
            }
            let units = bytes.chunks(2).map(|c| u16::from_le_bytes([c[0], c[1]]));
            let s: String = char::decode_utf16(units)
                .collect::<Result<_, _>>()
                .map_err(|_| "the UNICODE_STRING is not valid UTF-16")?;
            text_ok(&s)?;
            Ok(s)
        }
        OctetString | Domain => {
            let mut s = String::with_capacity(bytes.len() * 2);
            for b in bytes {
                s.push_str(&format!("{b:02X}"));
            }
            Ok(s)
        }
        _ => {
            let size = t.fixed_size().unwrap_or(8);
            if bytes.len() != size {
                return Err("the value's length is not its type's size");
            }
            let mut buf = [0u8; 8];
            buf[..size].copy_from_slice(bytes);
            let raw = u64::from_le_bytes(buf);
            Ok(match t {
                // A NaN other than the one "NaN" reads as keeps its bits.
                Real32
                    if f32::from_bits(raw as u32).is_nan() && raw as u32 != f32::NAN.to_bits() =>
                {
                    format!("0x{:08X}", raw as u32)
                }
                Real64 if f64::from_bits(raw).is_nan() && raw != f64::NAN.to_bits() => {
                    format!("0x{raw:016X}")
                }
                Real32 => format!("{:?}", f32::from_bits(raw as u32)),
                Real64 => format!("{:?}", f64::from_bits(raw)),
                _ if t.is_signed() => format!("{}", sign_extend(raw as i128, size as u32 * 8)),
                _ => unsigned_text(raw),
            })
        }
    }
}

/// An unsigned number: decimal below 10, else hex.
pub(crate) fn unsigned_text(v: u64) -> String {
    if v < 10 {
        format!("{v}")
    } else {
        format!("{v:#X}").replacen("0X", "0x", 1)
    }
}

fn text_ok(s: &str) -> Result<(), Unwritable> {
    if s.chars().any(|c| c.is_control() && c != '\t') {
        return Err("the string holds a control character");
    }
    if s.trim() != s {
        return Err("the string starts or ends with white space");
    }
    Ok(())
}

/// Writes a dictionary limit of type `t`, clamped to the type's range (so that it reads back
/// as the same check).
pub(crate) fn write_limit(t: DataType, l: Limit) -> Option<String> {
    Some(match canonical_limit(t, l)? {
        Limit::Real(x) => format!("{x:?}"),
        Limit::Signed(x) => format!("{x}"),
        Limit::Unsigned(x) => unsigned_text(x),
    })
}

/// A limit as the type compares it (the conversions of the dictionary's check), clamped to the
/// type's range: two limits with the same canonical form accept the same values.
#[must_use]
pub fn canonical_limit(t: DataType, l: Limit) -> Option<Limit> {
    let size = t.fixed_size()?;
    let bits = if t == DataType::Boolean {
        1
    } else {
        size as u32 * 8
    };
    Some(if t.is_real() {
        Limit::Real(match l {
            Limit::Real(x) => x,
            Limit::Signed(x) => x as f64,
            Limit::Unsigned(x) => x as f64,
        })
    } else if t.is_signed() {
        let v = match l {
            Limit::Signed(x) => x,
            Limit::Unsigned(x) => i64::try_from(x).unwrap_or(i64::MAX),
            Limit::Real(x) => x as i64,
        } as i128;
        let (min, max) = (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1);
        Limit::Signed(v.clamp(min, max) as i64)
    } else {
        let v = match l {
            Limit::Unsigned(x) => x,
            Limit::Signed(x) => u64::try_from(x).unwrap_or(0),
            Limit::Real(x) => x as u64,
        } as i128;
        Limit::Unsigned(v.clamp(0, (1i128 << bits) - 1) as u64)
    })
}
