//! The data types of CiA 309-3 and their text: what `w[rite]` takes and `r[ead]` answers.
//!
//! | type | text |
//! |---|---|
//! | `b` | a number, one byte (CiA 301 has 0 and 1; the node judges the value, as for `u8`) |
//! | `i8`…`i64`, `u8`…`u64` (also the 24-, 40-, 48-, 56-bit ones) | decimal; written also as `0x` hex |
//! | `x8`, `x16`, `x32`, `x64` | `0x` and upper-case hex digits, every byte shown |
//! | `r32`, `r64` | written: decimal, with a point and an exponent as needed; read: six significant digits, an exponent below 1e-4 and from 1e6 (C's `%g`, as CANopenNode prints them) |
//! | `vs` | in double quotes, a quote doubled (`"say ""hi"""`); one word may be written bare |
//! | `os`, `us`, `d` | base64 (RFC 4648 alphabet, padded: what RFC 2045 MIME uses, on one line) |
//! | `t`, `td` | two decimal numbers: days, then milliseconds (TIME_OF_DAY from 1984-01-01) |
//! | `hex` | bytes as pairs of hex digits, space between (CANopenNode's, not in the standard) |
//!
//! A value read whose size is not its type's is answered as its bytes in hex (as `hex`), as
//! CANopenNode's gateway does: `r 0x1017 0 u32` of a 16-bit object shows `E8 03`, the bytes the
//! node sent, never a number guessed from them.

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
    pub(crate) fn size(self) -> Option<usize> {
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

/// Why a value's text is not one of its type: said in the error's `#` comment.
pub type ValueError = String;

/// One word of a request: its text, and whether it was in double quotes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Word {
    /// The text (a quoted word without its quotes, a doubled quote made one).
    pub text: String,
    /// True if the word was in double quotes.
    pub quoted: bool,
}

/// The bytes to write for the words `words` as `ty`, or what is wrong with them.
pub fn encode_value(ty: DataType, words: &[Word]) -> Result<Vec<u8>, ValueError> {
    fn bare(w: &Word) -> Result<&str, ValueError> {
        if w.quoted {
            Err(format!("\"{}\": only a vs value is quoted", w.text))
        } else {
            Ok(w.text.as_str())
        }
    }
    let one = || match words {
        [w] => bare(w),
        [] => Err("no value".to_string()),
        _ => Err(format!("{} words where one value goes", words.len())),
    };
    match ty {
        // A BOOLEAN is one byte, written as a number (`1`, `0x1`, `01`) like CANopenNode's
        // gateway takes it; what the byte may hold (0 and 1 in CiA 301) the node's dictionary
        // judges, as it does for a u8, so a script gets the node's answer, not the gateway's.
        DataType::Bool => int_bytes(one()?, false, 1),
        DataType::Int(n) => int_bytes(one()?, true, n),
        DataType::Uint(n) | DataType::Hex(n) => int_bytes(one()?, false, n),
        DataType::Real32 => encode(Type::F32, one()?),
        DataType::Real64 => encode(Type::F64, one()?),
        DataType::Visible => match words {
            [w] => Ok(w.text.as_bytes().to_vec()),
            _ => Err("a string of several words goes in double quotes".to_string()),
        },
        DataType::Base64 => {
            let text = one()?;
            base64_decode(text).ok_or_else(|| format!("{text}: not base64 (RFC 4648, padded)"))
        }
        DataType::Time => match words {
            [days, ms] => {
                let days = parse_int(bare(days)?, false)
                    .ok()
                    .and_then(|v| u16::try_from(v).ok())
                    .ok_or_else(|| format!("{}: days are 0 to 65535", days.text))?;
                // 28 bits of milliseconds; a day has fewer, but a time difference may not.
                let ms = parse_int(bare(ms)?, false)
                    .ok()
                    .and_then(|v| u32::try_from(v).ok())
                    .filter(|v| *v < 1 << 28)
                    .ok_or_else(|| format!("{}: milliseconds are 0 to 268435455", ms.text))?;
                let mut b = ms.to_le_bytes().to_vec();
                b.extend_from_slice(&days.to_le_bytes());
                Ok(b)
            }
            _ => Err("a time is two numbers: days, then milliseconds".to_string()),
        },
        DataType::Bytes => {
            if words.is_empty() {
                return Err("no bytes".to_string());
            }
            let all = words.iter().map(bare).collect::<Result<Vec<_>, _>>()?;
            parse_hex_bytes(&all.join(" "))
        }
    }
}

/// `text` as an integer of `n` bytes, little-endian.
fn int_bytes(text: &str, signed: bool, n: u8) -> Result<Vec<u8>, ValueError> {
    let bits = 8 * u32::from(n);
    let (lo, hi) = if signed {
        (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
    } else {
        (0, (1i128 << bits) - 1)
    };
    let kind = if signed { "an i" } else { "a u" };
    match parse_int(text, signed) {
        Ok(v) if (lo..=hi).contains(&v) => Ok(v.to_le_bytes()[..usize::from(n)].to_vec()),
        _ => Err(format!("{text}: not {kind}{bits} ({lo} to {hi})")),
    }
}

/// The text of the bytes `data` read as `ty`; bytes that are not the type's size show as `hex`.
pub fn show_value(ty: DataType, data: &[u8]) -> String {
    if ty.size().is_some_and(|n| n != data.len()) {
        return show_value(DataType::Bytes, data);
    }
    let unsigned = || {
        let mut b = [0u8; 16];
        b[..data.len()].copy_from_slice(data);
        u128::from_le_bytes(b)
    };
    match ty {
        DataType::Bool | DataType::Uint(_) => unsigned().to_string(),
        DataType::Int(n) => {
            let shift = 128 - 8 * u32::from(n);
            (((unsigned() << shift) as i128) >> shift).to_string()
        }
        DataType::Hex(n) => format!("0x{:0w$X}", unsigned(), w = 2 * usize::from(n)),
        // The size was checked above: four and eight bytes.
        DataType::Real32 => c_g(f64::from(f32::from_bits(unsigned() as u32))),
        DataType::Real64 => c_g(f64::from_bits(unsigned() as u64)),
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
    }
}

/// `v` as C's `printf("%g")` shows it (six significant digits; the exponent form when the
/// exponent is below -4 or from 6 on, with a sign and at least two digits; no trailing zeros):
/// the text CANopenNode's gateway answers, which scripts written against it parse.
pub fn c_g(v: f64) -> String {
    const P: i32 = 6;
    if v.is_nan() {
        return if v.is_sign_negative() { "-nan" } else { "nan" }.to_string();
    }
    if v.is_infinite() {
        return if v < 0.0 { "-inf" } else { "inf" }.to_string();
    }
    if v == 0.0 {
        return if v.is_sign_negative() { "-0" } else { "0" }.to_string();
    }
    // The exponent after rounding to P digits decides the form.
    let e_form = format!("{:.*e}", (P - 1) as usize, v);
    let (mantissa, exp) = e_form.split_once('e').unwrap_or((&e_form, "0"));
    let exp: i32 = exp.parse().unwrap_or(0);
    if !(-4..P).contains(&exp) {
        let sign = if exp < 0 { '-' } else { '+' };
        format!("{}e{sign}{:02}", trim_zeros(mantissa), exp.unsigned_abs())
    } else {
        trim_zeros(&format!("{:.*}", (P - 1 - exp) as usize, v)).to_string()
    }
}

/// A decimal without the zeros at the end of its fraction (and without a point left bare).
fn trim_zeros(s: &str) -> &str {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s
    }
}

/// A visible string in double quotes, a quote doubled. NULs (padding some nodes send) and
/// CRs are dropped; a byte that is not text, and any control character, shows as U+FFFD:
/// a response is one line, whatever the node holds.
fn quote(data: &[u8]) -> String {
    // NUL (padding) and CR are dropped wherever they are, as CANopenNode drops them.
    let kept: Vec<u8> = data
        .iter()
        .copied()
        .filter(|b| *b != 0 && *b != b'\r')
        .collect();
    let text = String::from_utf8_lossy(&kept);
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
