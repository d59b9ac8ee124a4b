//! The data types of CiA 309-3 and their text: what `w[rite]` takes and `r[ead]` answers.
//!
//! | type | text |
//! |---|---|
//! | `b` | 0 or 1 |
//! | `i8`…`i64`, `u8`…`u64` (also the 24-, 40-, 48-, 56-bit ones) | decimal; written also as `0x` hex |
//! | `x8`, `x16`, `x32`, `x64` | `0x` and upper-case hex digits, every byte shown |
//! | `r32`, `r64` | decimal, with a point and an exponent as needed |
//! | `vs` | in double quotes, a quote doubled (`"say ""hi"""`); one word may be written bare |
//! | `os`, `us`, `d` | base64 (RFC 4648 alphabet, padded: what RFC 2045 MIME uses, on one line) |
//! | `t`, `td` | two decimal numbers: days, then milliseconds (TIME_OF_DAY from 1984-01-01) |
//! | `hex` | bytes as pairs of hex digits, space between (CANopenNode's, not in the standard) |
//!
//! A value read that does not have the size of its type is the gateway's error
//! `0x06070010` (the SDO abort code for a length that does not match), never a guess.

use crate::args::{encode, parse_hex_bytes, parse_int, Type};

/// A CiA 309-3 data type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DataType {
    /// BOOLEAN (`b`).
    Bool,
    /// INTEGERn, n = 8 × the bytes (1–8).
    Int(u8),
    /// UNSIGNEDn (1–8 bytes).
    Uint(u8),
    /// UNSIGNEDn shown in hex (1, 2, 4 or 8 bytes).
    Hex(u8),
    /// REAL32.
    Real32,
    /// REAL64.
    Real64,
    /// VISIBLE_STRING (`vs`).
    Visible,
    /// OCTET_STRING (`os`), UNICODE_STRING (`us`) or DOMAIN (`d`): base64.
    Base64,
    /// TIME_OF_DAY (`t`) or TIME_DIFFERENCE (`td`).
    Time,
    /// Raw bytes in hex (`hex`).
    Bytes,
}

impl DataType {
    /// The type a 309-3 name stands for (case-insensitive), or `None`.
    pub fn parse(name: &str) -> Option<DataType> {
        let n = name.to_ascii_lowercase();
        let bits = |s: &str| match s {
            "8" => Some(1),
            "16" => Some(2),
            "24" => Some(3),
            "32" => Some(4),
            "40" => Some(5),
            "48" => Some(6),
            "56" => Some(7),
            "64" => Some(8),
            _ => None,
        };
        Some(match n.as_str() {
            "b" => DataType::Bool,
            "r32" => DataType::Real32,
            "r64" => DataType::Real64,
            "vs" => DataType::Visible,
            "os" | "us" | "d" => DataType::Base64,
            "t" | "td" => DataType::Time,
            "hex" => DataType::Bytes,
            _ => {
                let (kind, rest) = n.split_at_checked(1)?;
                let size = bits(rest)?;
                match kind {
                    "i" => DataType::Int(size),
                    "u" => DataType::Uint(size),
                    "x" if matches!(size, 1 | 2 | 4 | 8) => DataType::Hex(size),
                    _ => return None,
                }
            }
        })
    }

    /// The size of a value of this type, or `None` for the ones of any size.
    fn size(self) -> Option<usize> {
        match self {
            DataType::Bool => Some(1),
            DataType::Int(n) | DataType::Uint(n) | DataType::Hex(n) => Some(usize::from(n)),
            DataType::Real32 => Some(4),
            DataType::Real64 => Some(8),
            DataType::Time => Some(6),
            DataType::Visible | DataType::Base64 | DataType::Bytes => None,
        }
    }
}

/// What went wrong with a value: its text is not one of the type (a syntax error), or the
/// bytes read do not have the type's size.
#[derive(Debug, PartialEq, Eq)]
pub enum ValueError {
    /// The text is not a value of the type.
    Syntax,
    /// The bytes read are not the type's size.
    Length,
}

/// One word of a request: its text, and whether it was in double quotes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Word {
    /// The text (a quoted word without its quotes, a doubled quote made one).
    pub text: String,
    /// True if the word was in double quotes.
    pub quoted: bool,
}

/// The bytes to write for the words `words` as `ty`.
pub fn encode_value(ty: DataType, words: &[Word]) -> Result<Vec<u8>, ValueError> {
    fn bare(w: &Word) -> Option<&str> {
        (!w.quoted).then_some(w.text.as_str())
    }
    let one = || match words {
        [w] => bare(w).ok_or(ValueError::Syntax),
        _ => Err(ValueError::Syntax),
    };
    match ty {
        DataType::Bool => match one()? {
            "0" => Ok(vec![0]),
            "1" => Ok(vec![1]),
            _ => Err(ValueError::Syntax),
        },
        DataType::Int(n) => int_bytes(one()?, true, n),
        DataType::Uint(n) | DataType::Hex(n) => int_bytes(one()?, false, n),
        DataType::Real32 => encode(Type::F32, one()?).map_err(|_| ValueError::Syntax),
        DataType::Real64 => encode(Type::F64, one()?).map_err(|_| ValueError::Syntax),
        DataType::Visible => match words {
            [w] => Ok(w.text.as_bytes().to_vec()),
            _ => Err(ValueError::Syntax),
        },
        DataType::Base64 => base64_decode(one()?).ok_or(ValueError::Syntax),
        DataType::Time => match words {
            [days, ms] => {
                let days = parse_int(bare(days).ok_or(ValueError::Syntax)?, false)
                    .ok()
                    .and_then(|v| u16::try_from(v).ok())
                    .ok_or(ValueError::Syntax)?;
                // 28 bits of milliseconds; a day has fewer, but a time difference may not.
                let ms = parse_int(bare(ms).ok_or(ValueError::Syntax)?, false)
                    .ok()
                    .and_then(|v| u32::try_from(v).ok())
                    .filter(|v| *v < 1 << 28)
                    .ok_or(ValueError::Syntax)?;
                let mut b = ms.to_le_bytes().to_vec();
                b.extend_from_slice(&days.to_le_bytes());
                Ok(b)
            }
            _ => Err(ValueError::Syntax),
        },
        DataType::Bytes => {
            if words.is_empty() || words.iter().any(|w| w.quoted) {
                return Err(ValueError::Syntax);
            }
            let all: Vec<&str> = words.iter().map(|w| w.text.as_str()).collect();
            parse_hex_bytes(&all.join(" ")).map_err(|_| ValueError::Syntax)
        }
    }
}

/// `text` as an integer of `n` bytes, little-endian.
fn int_bytes(text: &str, signed: bool, n: u8) -> Result<Vec<u8>, ValueError> {
    let v = parse_int(text, signed).map_err(|_| ValueError::Syntax)?;
    let bits = 8 * u32::from(n);
    let (lo, hi) = if signed {
        (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
    } else {
        (0, (1i128 << bits) - 1)
    };
    if v < lo || v > hi {
        return Err(ValueError::Syntax);
    }
    Ok(v.to_le_bytes()[..usize::from(n)].to_vec())
}

/// The text of the bytes `data` read as `ty`.
pub fn show_value(ty: DataType, data: &[u8]) -> Result<String, ValueError> {
    if ty.size().is_some_and(|n| n != data.len()) {
        return Err(ValueError::Length);
    }
    let unsigned = || {
        let mut b = [0u8; 16];
        b[..data.len()].copy_from_slice(data);
        u128::from_le_bytes(b)
    };
    Ok(match ty {
        DataType::Bool | DataType::Uint(_) => unsigned().to_string(),
        DataType::Int(n) => {
            let shift = 128 - 8 * u32::from(n);
            (((unsigned() << shift) as i128) >> shift).to_string()
        }
        DataType::Hex(n) => format!("0x{:0w$X}", unsigned(), w = 2 * usize::from(n)),
        DataType::Real32 => {
            let b: [u8; 4] = data.try_into().map_err(|_| ValueError::Length)?;
            f32::from_le_bytes(b).to_string()
        }
        DataType::Real64 => {
            let b: [u8; 8] = data.try_into().map_err(|_| ValueError::Length)?;
            f64::from_le_bytes(b).to_string()
        }
        DataType::Visible => quote(data),
        DataType::Base64 => base64_encode(data),
        DataType::Time => {
            let v = unsigned();
            format!("{} {}", v >> 32, v & 0x0FFF_FFFF)
        }
        DataType::Bytes => data
            .iter()
            .map(|b| format!("{b:02X}"))
            .collect::<Vec<_>>()
            .join(" "),
    })
}

/// A visible string in double quotes, a quote doubled. Trailing NULs (padding some nodes
/// send) are dropped; a byte that is not text, and any control character, shows as U+FFFD:
/// a response is one line, whatever the node holds.
fn quote(data: &[u8]) -> String {
    let end = data.iter().rposition(|b| *b != 0).map_or(0, |i| i + 1);
    let text = String::from_utf8_lossy(&data[..end]);
    let mut s = String::with_capacity(text.len() + 2);
    s.push('"');
    for c in text.chars() {
        match c {
            '"' => s.push_str("\"\""),
            c if c.is_control() => s.push('\u{FFFD}'),
            c => s.push(c),
        }
    }
    s.push('"');
    s
}

const B64: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/// Base64 with padding.
pub fn base64_encode(data: &[u8]) -> String {
    let mut s = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let mut b = [0u8; 3];
        b[..chunk.len()].copy_from_slice(chunk);
        let n = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
        for i in 0..4 {
            if i <= chunk.len() {
                s.push(char::from(B64[(n >> (18 - 6 * i) & 0x3F) as usize]));
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Base64 with padding, strictly: whole groups of four, `=` only at the end, no bits left
/// over in the last character (so that every value has exactly one text).
pub fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let b = text.as_bytes();
    if !b.len().is_multiple_of(4) {
        return None;
    }
    let sextet = |c: u8| B64.iter().position(|x| *x == c).map(|p| p as u32);
    let mut out = Vec::with_capacity(b.len() / 4 * 3);
    let groups = b.len() / 4;
    for (g, q) in b.chunks(4).enumerate() {
        let pad = q.iter().rev().take_while(|c| **c == b'=').count();
        if pad > 2 || (pad > 0 && g + 1 != groups) {
            return None;
        }
        let mut n = 0u32;
        for &c in &q[..4 - pad] {
            n = n << 6 | sextet(c)?;
        }
        n <<= 6 * pad as u32;
        let bytes = [(n >> 16) as u8, (n >> 8) as u8, n as u8];
        let keep = 3 - pad;
        // The bits the padding stands for must be zero.
        if bytes[keep..].iter().any(|b| *b != 0) {
            return None;
        }
        out.extend_from_slice(&bytes[..keep]);
    }
    Some(out)
}
