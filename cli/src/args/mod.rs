//! The tool's arguments as text: numbers, node-IDs, values to write, how a value read shows.
//! Strict and total: every string gives a value or an error that quotes it, never a panic
//! (the tests run these functions on any string).
//!
//! A number is decimal digits, or `0x`/`0X` followed by hex digits; only a signed value may
//! start with one `-`. Nothing else: no `+`, no spaces, no second sign, no `_`, no non-ASCII
//! digit, nothing out of range.

use clap::ValueEnum;
use duocan::NodeId;

/// Longest timeout accepted, in milliseconds (an hour).
pub const MAX_TIMEOUT_MS: u64 = 3_600_000;

/// Data types a value is written or shown as.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Type {
    /// Bytes in hex, and the unsigned value for 1, 2, 4 or 8 bytes
    Auto,
    U8,
    U16,
    U32,
    U64,
    I8,
    I16,
    I32,
    I64,
    F32,
    F64,
    /// 0 or 1 (also false/true)
    Bool,
    /// Visible string
    Str,
    /// Raw bytes
    Hex,
}

/// `s` as a number; a leading `-` only when `signed`. The magnitude may be up to `u64::MAX`
/// (`i64::MIN` when negative): the caller checks its own range.
pub fn parse_int(s: &str, signed: bool) -> Result<i128, String> {
    let bad = |why: &str| format!("{s:?} is not a number: {why}");
    let (neg, body) = match s.strip_prefix('-') {
        Some(rest) if signed => (true, rest),
        Some(_) => return Err(bad("no sign allowed here")),
        None => (false, s),
    };
    let (radix, digits) = match body.strip_prefix("0x").or_else(|| body.strip_prefix("0X")) {
        Some(h) => (16, h),
        None => (10, body),
    };
    if digits.is_empty() {
        return Err(bad("no digits (decimal, or hex after 0x)"));
    }
    let mut v: i128 = 0;
    for c in digits.chars() {
        let d = c.to_digit(radix).ok_or_else(|| {
            bad(&if radix == 16 {
                format!("{c:?} is not a hex digit")
            } else {
                format!("{c:?} is not a decimal digit (hex needs 0x)")
            })
        })?;
        v = v
            .checked_mul(i128::from(radix))
            .and_then(|v| v.checked_add(i128::from(d)))
            .filter(|v| *v <= i128::from(u64::MAX))
            .ok_or_else(|| bad("too large"))?;
    }
    Ok(if neg { -v } else { v })
}

/// `s` as an unsigned number that fits `T`; `what` names the field in the error.
pub fn parse_unsigned<T: TryFrom<i128>>(s: &str, what: &str) -> Result<T, String> {
    let v = parse_int(s, false)?;
    T::try_from(v).map_err(|_| format!("{s} does not fit {what}"))
}

/// `s` as a signed number that fits `T`.
pub fn parse_signed<T: TryFrom<i128>>(s: &str, what: &str) -> Result<T, String> {
    let v = parse_int(s, true)?;
    T::try_from(v).map_err(|_| format!("{s} does not fit {what}"))
}

/// An object index, 0–0xFFFF.
pub fn parse_index(s: &str) -> Result<u16, String> {
    parse_unsigned(s, "an object index (0-0xFFFF)")
}

/// A sub-index, 0–255.
pub fn parse_sub(s: &str) -> Result<u8, String> {
    parse_unsigned(s, "a sub-index (0-255)")
}

/// A node-ID, 1–127.
pub fn parse_node(s: &str) -> Result<NodeId, String> {
    let v: u8 = parse_unsigned(s, "a node-ID (1-127)")?;
    NodeId::new(v).ok_or_else(|| format!("node-ID {s}: a node-ID is 1-127"))
}

/// A timeout in milliseconds, 1 to [`MAX_TIMEOUT_MS`].
pub fn parse_timeout_ms(s: &str) -> Result<u64, String> {
    let v: u64 = parse_unsigned(s, "a timeout in milliseconds")?;
    if (1..=MAX_TIMEOUT_MS).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "timeout {s} ms: give 1 to {MAX_TIMEOUT_MS} (an hour)"
        ))
    }
}

/// A decimal floating-point number: digits with an optional point and exponent, a `-` in front
/// and a sign after the exponent's `e` only. Words like `inf` and `nan` are not numbers here.
fn parse_f32(s: &str) -> Result<f32, String> {
    check_decimal(s)?;
    s.parse::<f32>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("{s:?} is not a decimal number f32 holds"))
}

/// [`parse_f32`] for `f64`.
fn parse_f64(s: &str) -> Result<f64, String> {
    check_decimal(s)?;
    s.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("{s:?} is not a decimal number f64 holds"))
}

/// Only the characters of a decimal number, signs only where one belongs.
fn check_decimal(s: &str) -> Result<(), String> {
    let b = s.as_bytes();
    let sign_ok = |i: usize| match b[i] {
        b'-' => i == 0 || matches!(b[i - 1], b'e' | b'E'),
        b'+' => i > 0 && matches!(b[i - 1], b'e' | b'E'),
        _ => true,
    };
    let chars_ok = b
        .iter()
        .all(|c| c.is_ascii_digit() || matches!(c, b'.' | b'e' | b'E' | b'-' | b'+'));
    if !chars_ok || !(0..b.len()).all(sign_ok) {
        return Err(format!("{s:?} is not a decimal number"));
    }
    Ok(())
}

/// Bytes in hex: pairs of hex digits, optionally `0x` in front and spaces between bytes.
pub fn parse_hex_bytes(s: &str) -> Result<Vec<u8>, String> {
    let compact: String = s.split_ascii_whitespace().collect();
    let digits = compact
        .strip_prefix("0x")
        .or_else(|| compact.strip_prefix("0X"))
        .unwrap_or(&compact);
    if !digits.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("{s:?} is not hex (digits 0-9, a-f)"));
    }
    if digits.is_empty() || !digits.len().is_multiple_of(2) {
        return Err(format!("{s:?}: give whole bytes in hex, like 01020a"));
    }
    // All ASCII now: byte offsets are character boundaries.
    (0..digits.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&digits[i..i + 2], 16).map_err(|e| format!("{s:?}: {e}")))
        .collect()
}

/// The bytes to write for `value` as `ty` (little-endian, as CANopen sends numbers).
pub fn encode(ty: Type, value: &str) -> Result<Vec<u8>, String> {
    fn le<T: TryFrom<i128>, const N: usize>(
        v: Result<T, String>,
        bytes: impl Fn(T) -> [u8; N],
    ) -> Result<Vec<u8>, String> {
        v.map(|v| bytes(v).to_vec())
    }
    match ty {
        Type::U8 => le(parse_unsigned(value, "u8"), u8::to_le_bytes),
        Type::U16 => le(parse_unsigned(value, "u16"), u16::to_le_bytes),
        Type::U32 => le(parse_unsigned(value, "u32"), u32::to_le_bytes),
        Type::U64 => le(parse_unsigned(value, "u64"), u64::to_le_bytes),
        Type::I8 => le(parse_signed(value, "i8"), i8::to_le_bytes),
        Type::I16 => le(parse_signed(value, "i16"), i16::to_le_bytes),
        Type::I32 => le(parse_signed(value, "i32"), i32::to_le_bytes),
        Type::I64 => le(parse_signed(value, "i64"), i64::to_le_bytes),
        Type::F32 => parse_f32(value).map(|v| v.to_le_bytes().to_vec()),
        Type::F64 => parse_f64(value).map(|v| v.to_le_bytes().to_vec()),
        Type::Bool => match value {
            "0" | "false" => Ok(vec![0]),
            "1" | "true" => Ok(vec![1]),
            _ => Err(format!(
                "{value:?} is not a boolean: give 0, 1, false or true"
            )),
        },
        Type::Str => Ok(value.as_bytes().to_vec()),
        Type::Hex | Type::Auto => parse_hex_bytes(value),
    }
}

/// How a value read shows.
pub fn show(ty: Type, data: &[u8]) -> String {
    fn fixed<const N: usize>(data: &[u8]) -> Option<[u8; N]> {
        data.try_into().ok()
    }
    let hex = data
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect::<Vec<_>>()
        .join(" ");
    let wrong = || format!("[{hex}] ({} bytes: not this type)", data.len());
    match ty {
        Type::Auto => {
            let unsigned = match data.len() {
                1 | 2 | 4 | 8 => {
                    let mut b = [0u8; 8];
                    b[..data.len()].copy_from_slice(data);
                    let v = u64::from_le_bytes(b);
                    format!(" = {v} ({v:#0w$x})", w = 2 + 2 * data.len())
                }
                _ => String::new(),
            };
            let text = match std::str::from_utf8(data) {
                Ok(s) if data.len() > 1 && s.chars().all(|c| !c.is_control()) => {
                    format!(" {s:?}")
                }
                _ => String::new(),
            };
            format!("[{hex}]{unsigned}{text}")
        }
        Type::U8 => fixed::<1>(data).map_or_else(wrong, |b| u8::from_le_bytes(b).to_string()),
        Type::U16 => fixed::<2>(data).map_or_else(wrong, |b| u16::from_le_bytes(b).to_string()),
        Type::U32 => fixed::<4>(data).map_or_else(wrong, |b| u32::from_le_bytes(b).to_string()),
        Type::U64 => fixed::<8>(data).map_or_else(wrong, |b| u64::from_le_bytes(b).to_string()),
        Type::I8 => fixed::<1>(data).map_or_else(wrong, |b| i8::from_le_bytes(b).to_string()),
        Type::I16 => fixed::<2>(data).map_or_else(wrong, |b| i16::from_le_bytes(b).to_string()),
        Type::I32 => fixed::<4>(data).map_or_else(wrong, |b| i32::from_le_bytes(b).to_string()),
        Type::I64 => fixed::<8>(data).map_or_else(wrong, |b| i64::from_le_bytes(b).to_string()),
        Type::F32 => fixed::<4>(data).map_or_else(wrong, |b| f32::from_le_bytes(b).to_string()),
        Type::F64 => fixed::<8>(data).map_or_else(wrong, |b| f64::from_le_bytes(b).to_string()),
        Type::Bool => match data {
            [0] => "false".into(),
            [1] => "true".into(),
            _ => wrong(),
        },
        Type::Str => String::from_utf8_lossy(data).into_owned(),
        Type::Hex => hex,
    }
}

/// Where the bus is, for the UDP forms of `--bus`: `udp`, `udp:N`, `udp:GROUP:PORT`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum UdpSpec {
    /// python-can's default bus.
    Default,
    /// Test bus N.
    Numbered(u8),
    /// A group and port.
    Group(std::net::Ipv4Addr, u16),
}

/// The UDP form of `--bus`, or `None` if `spec` names a SocketCAN interface.
pub fn parse_udp(spec: &str) -> Option<Result<UdpSpec, String>> {
    let rest = spec.strip_prefix("udp")?;
    if !rest.is_empty() && !rest.starts_with(':') {
        return None; // an interface whose name starts with "udp"
    }
    let parts: Vec<&str> = rest.split(':').skip(1).collect();
    Some(match parts.as_slice() {
        [] => Ok(UdpSpec::Default),
        [n] => parse_unsigned(n, "a bus number (0-255)")
            .map(UdpSpec::Numbered)
            .map_err(|e| format!("{spec}: udp:N takes a bus number 0-255 ({e})")),
        [group, port] => group
            .parse()
            .map_err(|_| format!("{spec}: {group} is not an IPv4 address"))
            .and_then(|g| {
                parse_unsigned(port, "a UDP port (0-65535)")
                    .map(|p| UdpSpec::Group(g, p))
                    .map_err(|e| format!("{spec}: {e}"))
            }),
        _ => Err(format!("{spec}: use udp, udp:N or udp:GROUP:PORT")),
    })
}

/// The type a value of data type `t` is written and shown as (`Hex` for the types the tool
/// has no number for: 24- to 56-bit integers, times, domains and octet strings).
pub fn type_of(t: duocan::od::DataType) -> Type {
    use duocan::od::DataType as D;
    match t {
        D::Boolean => Type::Bool,
        D::Integer8 => Type::I8,
        D::Integer16 => Type::I16,
        D::Integer32 => Type::I32,
        D::Integer64 => Type::I64,
        D::Unsigned8 => Type::U8,
        D::Unsigned16 => Type::U16,
        D::Unsigned32 => Type::U32,
        D::Unsigned64 => Type::U64,
        D::Real32 => Type::F32,
        D::Real64 => Type::F64,
        D::VisibleString | D::UnicodeString => Type::Str,
        _ => Type::Hex,
    }
}

/// A type by its name on the command line (`u32`, `str`…), or `None` if `s` names none.
pub fn parse_type(s: &str) -> Option<Type> {
    Type::from_str(s, true).ok()
}

/// Whom an NMT command is for: one node or every node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// Every node (`all`).
    All,
    /// One node.
    Node(NodeId),
}

/// `all` or a node-ID.
pub fn parse_target(s: &str) -> Result<Target, String> {
    if s == "all" {
        Ok(Target::All)
    } else {
        parse_node(s)
            .map(Target::Node)
            .map_err(|e| format!("{e} (or `all`)"))
    }
}

/// A device description on the command line: `NODE=FILE`, or `FILE` alone (a DCF names its
/// node in `[DeviceComissioning]`).
pub fn parse_description(s: &str) -> Result<(Option<NodeId>, std::path::PathBuf), String> {
    match s.split_once('=') {
        Some((node, file)) if !file.is_empty() => Ok((
            Some(parse_node(node).map_err(|e| format!("{s}: {e}"))?),
            file.into(),
        )),
        Some(_) => Err(format!("{s:?}: give NODE=FILE, as in 5=device.eds")),
        None if s.is_empty() => Err("an empty file name".into()),
        None => Ok((None, s.into())),
    }
}

/// The interfaces of `--bus`: one, or two joined by a comma (`can0,can1`: one logical bus on
/// two ports). Names are checked for what a name can be, not for whether the interface exists.
pub fn parse_bus(s: &str) -> Result<Vec<String>, String> {
    let names: Vec<&str> = s.split(',').collect();
    if names.len() > 2 {
        return Err(format!("--bus {s}: at most two interfaces (can0,can1)"));
    }
    for n in &names {
        if n.is_empty() {
            return Err(format!("--bus {s:?}: an empty interface name"));
        }
        if let Some(Err(e)) = parse_udp(n) {
            return Err(e);
        }
        if !n
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, ':' | '.' | '_' | '-'))
        {
            return Err(format!("--bus {s:?}: {n:?} is not an interface name"));
        }
    }
    if names.len() == 2 && names[0] == names[1] {
        return Err(format!("--bus {s}: the two ports must differ"));
    }
    Ok(names.into_iter().map(String::from).collect())
}

#[cfg(test)]
mod tests;
