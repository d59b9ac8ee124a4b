//! One candump log line, token by token. Every token is checked whole: no sign, no stray
//! character, no digit past what its field holds; an error names the token and what is wrong.

use super::LogEntry;
use crate::capture::Record;
use crate::frame::fd::{FdFrameError, BRS, ESI, FD_MAX_LEN};
use crate::frame::{FdFrame, Frame, Id, STANDARD_ID_MAX};
use crate::port::error_frame::{CAN_ERR_FLAG, CAN_ERR_MASK};

/// Longest interface name accepted (Linux allows 15 characters; recorders name buses freely).
pub const MAX_INTERFACE: usize = 32;

/// A token as it appears in a message: quoted and cut short.
fn shown(t: &str) -> String {
    const SHOWN: usize = 40;
    if t.chars().count() > SHOWN {
        let cut: String = t.chars().take(SHOWN).collect();
        format!("{cut:?}…")
    } else {
        format!("{t:?}")
    }
}

/// Parses one line; the error is the reason alone (the caller adds source and line).
pub(super) fn parse(line: &str) -> Result<LogEntry, String> {
    let mut parts = line.split_ascii_whitespace();
    let ts = parts.next().ok_or("empty line")?;
    let iface = parts
        .next()
        .ok_or("missing interface after the timestamp")?;
    let body = parts.next().ok_or("missing frame after the interface")?;
    // candump -x appends the direction (R received, T transmitted); nothing else may follow.
    if let Some(dir) = parts.next() {
        if dir != "R" && dir != "T" {
            return Err(format!(
                "unexpected {} after the frame (only a direction R or T may follow)",
                shown(dir)
            ));
        }
    }
    if let Some(junk) = parts.next() {
        return Err(format!("unexpected {} at the end of the line", shown(junk)));
    }
    let timestamp_us = parse_timestamp(ts)?;
    check_interface(iface)?;
    let record = parse_body(body)?;
    Ok(LogEntry {
        timestamp_us,
        interface: iface.to_owned(),
        record,
    })
}

fn all_digits(s: &str) -> bool {
    !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit())
}

fn parse_timestamp(t: &str) -> Result<u64, String> {
    let bad = |why: &str| format!("timestamp {}: {why}", shown(t));
    let inner = t
        .strip_prefix('(')
        .and_then(|x| x.strip_suffix(')'))
        .ok_or_else(|| bad("not in parentheses"))?;
    let (secs, frac) = inner
        .split_once('.')
        .ok_or_else(|| bad("no fraction (SECONDS.MICROSECONDS)"))?;
    if !all_digits(secs) {
        return Err(bad("seconds are not decimal digits"));
    }
    if !all_digits(frac) || frac.len() > 9 {
        return Err(bad("fraction is not 1 to 9 decimal digits"));
    }
    let secs: u64 = secs.parse().map_err(|_| bad("seconds out of range"))?;
    let micros = frac
        .bytes()
        .chain(core::iter::repeat(b'0'))
        .take(6)
        .fold(0u64, |m, b| m * 10 + u64::from(b - b'0'));
    secs.checked_mul(1_000_000)
        .and_then(|s| s.checked_add(micros))
        .ok_or_else(|| bad("out of range"))
}

fn check_interface(i: &str) -> Result<(), String> {
    if i.len() > MAX_INTERFACE {
        return Err(format!(
            "interface name {} longer than {MAX_INTERFACE} characters",
            shown(i)
        ));
    }
    if !i.bytes().all(|b| b.is_ascii_graphic()) {
        return Err(format!(
            "interface name {} has a character that is not printable ASCII",
            shown(i)
        ));
    }
    Ok(())
}

fn hex_value(s: &str) -> Option<u32> {
    if s.is_empty() || s.len() > 8 || !s.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    u32::from_str_radix(s, 16).ok()
}

fn parse_body(body: &str) -> Result<Record, String> {
    let (id_s, rest) = body
        .split_once('#')
        .ok_or_else(|| format!("frame {} has no '#' after the identifier", shown(body)))?;
    if id_s.is_empty() || !id_s.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!(
            "identifier {} is not hexadecimal digits",
            shown(id_s)
        ));
    }
    if id_s.len() != 3 && id_s.len() != 8 {
        return Err(format!(
            "identifier {} has {} digits: 3 (11-bit) or 8 (29-bit)",
            shown(id_s),
            id_s.len()
        ));
    }
    // At most 8 hex digits: fits.
    let raw = hex_value(id_s).unwrap_or(u32::MAX);
    if id_s.len() == 3 {
        let id = u16::try_from(raw)
            .ok()
            .and_then(Id::standard)
            .ok_or_else(|| format!("standard identifier {id_s} above {STANDARD_ID_MAX:#05X}"))?;
        return classic_or_fd(id, rest);
    }
    if raw & CAN_ERR_FLAG != 0 {
        if raw & !(CAN_ERR_FLAG | CAN_ERR_MASK) != 0 {
            return Err(format!(
                "error frame identifier {id_s} has bits above the error flag"
            ));
        }
        // SocketCAN error frames always carry 8 bytes (CAN_ERR_DLC).
        let v = hex_bytes(rest, 8)?;
        let data: [u8; 8] = v
            .try_into()
            .map_err(|v: Vec<u8>| format!("error frame with {} data bytes, not 8", v.len()))?;
        return Ok(Record::Error {
            bits: raw & CAN_ERR_MASK,
            data,
        });
    }
    let id =
        Id::extended(raw).ok_or_else(|| format!("extended identifier {id_s} above 0x1FFFFFFF"))?;
    classic_or_fd(id, rest)
}

/// Hex byte pairs, optionally separated by single dots between bytes (can-utils writes
/// `DE.AD.BE.EF` with `-x`), at most `max` bytes.
fn hex_bytes(s: &str, max: usize) -> Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(max.min(64));
    if s.is_empty() {
        return Ok(out);
    }
    for group in s.split('.') {
        if group.is_empty() || !group.len().is_multiple_of(2) {
            return Err(format!(
                "data {}: hex digits must come in pairs, a dot only between bytes",
                shown(s)
            ));
        }
        for pair in group.as_bytes().chunks(2) {
            let b = core::str::from_utf8(pair)
                .ok()
                .and_then(hex_value)
                .ok_or_else(|| format!("data {}: not hexadecimal digits", shown(s)))?;
            if out.len() == max {
                return Err(format!("data {}: more than {max} bytes", shown(s)));
            }
            out.push(b as u8);
        }
    }
    Ok(out)
}

fn classic_or_fd(id: Id, rest: &str) -> Result<Record, String> {
    if let Some(fd) = rest.strip_prefix('#') {
        return parse_fd(id, fd).map(|f| Record::Fd(Box::new(f)));
    }
    if let Some(r) = rest.strip_prefix('R').or_else(|| rest.strip_prefix('r')) {
        let dlc = match r.as_bytes() {
            [] => 0,
            [d @ b'0'..=b'8'] => d - b'0',
            _ => {
                return Err(format!(
                    "remote frame {}: after R only a DLC digit 0–8 may follow",
                    shown(rest)
                ))
            }
        };
        return Frame::remote(id, dlc)
            .map(Record::Frame)
            .map_err(|e| e.to_string());
    }
    // A classic 8-byte frame may carry `_X`, its raw DLC 9–F; the data decides the length.
    let (data, raw_dlc) = match rest.split_once('_') {
        Some((d, x)) => (d, Some(x)),
        None => (rest, None),
    };
    let bytes = hex_bytes(data, 8)?;
    if let Some(x) = raw_dlc {
        let ok = matches!(x.as_bytes(), [b'9'..=b'9' | b'A'..=b'F' | b'a'..=b'f']);
        if !ok || bytes.len() != 8 {
            return Err(format!(
                "raw DLC suffix {}: one digit 9–F after 8 data bytes",
                shown(x)
            ));
        }
    }
    Frame::new(id, &bytes)
        .map(Record::Frame)
        .map_err(|e| e.to_string())
}

/// `CANFD_FDF` in the flags nibble: newer can-utils may write it; `##` already says FD.
const FDF: u8 = 0x04;

/// The part after `ID##`: the flags nibble, then 0–64 data bytes of a CAN FD length.
fn parse_fd(id: Id, fd: &str) -> Result<FdFrame, String> {
    let mut chars = fd.chars();
    let flags = chars
        .next()
        .and_then(|c| c.to_digit(16))
        .ok_or_else(|| format!("CAN FD frame {}: no flags digit after '##'", shown(fd)))?
        as u8;
    if flags & !(BRS | ESI | FDF) != 0 {
        return Err(format!(
            "CAN FD flags digit {flags:X}: only BRS (1), ESI (2) and FDF (4) are defined"
        ));
    }
    let data = hex_bytes(chars.as_str(), FD_MAX_LEN)?;
    FdFrame::new(id, &data)
        .map(|f| f.with_flags(flags))
        .map_err(|e| match e {
            FdFrameError::NotFdLength { len } => format!(
                "CAN FD frame with {len} data bytes (a CAN FD frame holds 0–8, 12, 16, 20, 24, 32, 48 or 64)"
            ),
            e => e.to_string(),
        })
}
