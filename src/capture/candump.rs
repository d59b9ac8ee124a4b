//! can-utils candump log format: `(SECONDS.MICROS) IFACE ID#DATA`.
//!
//! `ID` is 3 hex digits for standard and 8 for extended identifiers; `#R` (optionally followed
//! by the DLC digit) marks a remote frame; `##F` starts a CAN FD payload with flags nibble `F`;
//! an 8-digit identifier with the error flag (0x20000000) is an error frame. What `candump -l`
//! writes and `canplayer` reads.

use super::Record;
use crate::frame::{Frame, Id};
use crate::port::error_frame::{CAN_ERR_FLAG, CAN_ERR_MASK};
use std::fmt::{self, Write as _};
use std::io::{self, BufRead, Write};

/// One log line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LogEntry {
    /// Wall-clock time, microseconds since the Unix epoch.
    pub timestamp_us: u64,
    /// Interface name.
    pub interface: String,
    /// What was captured.
    pub record: Record,
}

/// Why a line is not a candump log line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// 1-based line number (0 for a single parsed line).
    pub line: usize,
    /// What is wrong.
    pub reason: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "candump log line {}: {}", self.line, self.reason)
    }
}

impl std::error::Error for ParseError {}

fn err(reason: impl Into<String>) -> ParseError {
    ParseError {
        line: 0,
        reason: reason.into(),
    }
}

/// Formats a frame as a log line (without newline).
pub fn format_frame(timestamp_us: u64, interface: &str, frame: &Frame) -> String {
    let mut s = String::with_capacity(48);
    let _ = write!(
        s,
        "({}.{:06}) {} ",
        timestamp_us / 1_000_000,
        timestamp_us % 1_000_000,
        interface
    );
    match frame.id() {
        Id::Standard(r) => {
            let _ = write!(s, "{r:03X}#");
        }
        Id::Extended(r) => {
            let _ = write!(s, "{r:08X}#");
        }
    }
    if frame.is_remote() {
        s.push('R');
        if frame.dlc() > 0 {
            let _ = write!(s, "{:X}", frame.dlc());
        }
    } else {
        for b in frame.data() {
            let _ = write!(s, "{b:02X}");
        }
    }
    s
}

fn hex_bytes(s: &str, max: usize) -> Result<Vec<u8>, ParseError> {
    // can-utils allows '.' separators between bytes.
    let digits: Vec<u8> = s.bytes().filter(|b| *b != b'.').collect();
    if !digits.len().is_multiple_of(2) {
        return Err(err("odd number of hex digits in data"));
    }
    if digits.len() / 2 > max {
        return Err(err(format!("more than {max} data bytes")));
    }
    digits
        .chunks(2)
        .map(|p| {
            std::str::from_utf8(p)
                .ok()
                .and_then(|t| u8::from_str_radix(t, 16).ok())
                .ok_or_else(|| err("bad hex digit in data"))
        })
        .collect()
}

fn parse_timestamp(t: &str) -> Result<u64, ParseError> {
    let inner = t
        .strip_prefix('(')
        .and_then(|x| x.strip_suffix(')'))
        .ok_or_else(|| err("timestamp not in parentheses"))?;
    let (secs, frac) = inner
        .split_once('.')
        .ok_or_else(|| err("timestamp without fraction"))?;
    let secs: u64 = secs.parse().map_err(|_| err("bad timestamp seconds"))?;
    if frac.is_empty() || frac.len() > 9 || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return Err(err("bad timestamp fraction"));
    }
    let mut micros: u64 = 0;
    for (i, b) in frac.bytes().take(6).enumerate() {
        micros += u64::from(b - b'0') * 10u64.pow(5 - i as u32);
    }
    secs.checked_mul(1_000_000)
        .and_then(|s| s.checked_add(micros))
        .ok_or_else(|| err("timestamp out of range"))
}

/// Parses one log line.
pub fn parse_line(line: &str) -> Result<LogEntry, ParseError> {
    let mut parts = line.split_whitespace();
    let ts = parts.next().ok_or_else(|| err("empty line"))?;
    let iface = parts.next().ok_or_else(|| err("missing interface"))?;
    let body = parts.next().ok_or_else(|| err("missing frame"))?;
    // A trailing direction flag (candump -x: R/T) may follow; anything else is not ours.
    let timestamp_us = parse_timestamp(ts)?;
    let (id_s, rest) = body
        .split_once('#')
        .ok_or_else(|| err("frame without '#'"))?;
    let raw = u32::from_str_radix(id_s, 16).map_err(|_| err("bad identifier"))?;
    let record = match id_s.len() {
        3 => {
            let id = u16::try_from(raw)
                .ok()
                .and_then(Id::standard)
                .ok_or_else(|| err("standard identifier above 0x7FF"))?;
            classic_or_fd(id, rest)?
        }
        8 if raw & CAN_ERR_FLAG != 0 => {
            let v = hex_bytes(rest, 8)?;
            let mut data = [0u8; 8];
            data[..v.len()].copy_from_slice(&v);
            Record::Error {
                bits: raw & CAN_ERR_MASK,
                data,
            }
        }
        8 => {
            let id = Id::extended(raw).ok_or_else(|| err("extended identifier above 29 bits"))?;
            classic_or_fd(id, rest)?
        }
        _ => return Err(err("identifier must have 3 or 8 hex digits")),
    };
    Ok(LogEntry {
        timestamp_us,
        interface: iface.to_owned(),
        record,
    })
}

fn classic_or_fd(id: Id, rest: &str) -> Result<Record, ParseError> {
    if let Some(fd) = rest.strip_prefix('#') {
        let mut chars = fd.chars();
        let flags = chars
            .next()
            .and_then(|c| c.to_digit(16))
            .ok_or_else(|| err("CAN FD frame without flags nibble"))? as u8;
        let data = hex_bytes(chars.as_str(), 64)?;
        return Ok(Record::Fd { id, flags, data });
    }
    if let Some(r) = rest.strip_prefix('R').or_else(|| rest.strip_prefix('r')) {
        let dlc = match r.chars().next() {
            None => 0,
            Some(c) => c.to_digit(16).ok_or_else(|| err("bad remote DLC"))? as u8,
        };
        return Frame::remote(id, dlc)
            .map(Record::Frame)
            .map_err(|e| err(e.to_string()));
    }
    // Classic frames may carry `_X`, the raw DLC 9–15 of an 8-byte frame; the data decides.
    let data = rest.split_once('_').map_or(rest, |(d, _)| d);
    let bytes = hex_bytes(data, 8)?;
    Frame::new(id, &bytes)
        .map(Record::Frame)
        .map_err(|e| err(e.to_string()))
}

/// Reads every line of a log; each item is an entry or the error of its line. Blank lines
/// are skipped; I/O errors end the iteration after being reported.
pub fn read_log<R: BufRead>(r: R) -> impl Iterator<Item = Result<LogEntry, ParseError>> {
    let mut failed = false;
    r.lines().enumerate().filter_map(move |(i, l)| {
        if failed {
            return None;
        }
        match l {
            Ok(line) if line.trim().is_empty() => None,
            Ok(line) => Some(parse_line(&line).map_err(|mut e| {
                e.line = i + 1;
                e
            })),
            Err(e) => {
                failed = true;
                Some(Err(ParseError {
                    line: i + 1,
                    reason: format!("read error: {e}"),
                }))
            }
        }
    })
}

/// Writes log lines.
#[derive(Debug)]
pub struct CandumpWriter<W: Write> {
    out: W,
}

impl<W: Write> CandumpWriter<W> {
    /// A writer on `out`.
    #[must_use]
    pub fn new(out: W) -> Self {
        CandumpWriter { out }
    }
    /// Writes one frame.
    pub fn write(&mut self, timestamp_us: u64, interface: &str, frame: &Frame) -> io::Result<()> {
        writeln!(self.out, "{}", format_frame(timestamp_us, interface, frame))
    }
    /// Flushes the output.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }
    /// The output.
    pub fn into_inner(self) -> W {
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn formats_like_candump() {
        let f = Frame::from_array(Id::Standard(0x123), [0xDE, 0xAD, 0xBE, 0xEF]);
        assert_eq!(
            format_frame(1_700_000_000_123_456, "vcan0", &f),
            "(1700000000.123456) vcan0 123#DEADBEEF"
        );
        let r = Frame::remote(Id::Extended(0x1234567), 3).unwrap();
        assert_eq!(format_frame(5, "can1", &r), "(0.000005) can1 01234567#R3");
        let e = Frame::new(Id::Standard(0x80), &[]).unwrap();
        assert_eq!(format_frame(0, "x", &e), "(0.000000) x 080#");
    }

    #[test]
    fn parses_can_utils_variants() {
        let l = parse_line("(1700000000.123456) vcan0 123#DE.AD.BE.EF").unwrap();
        assert_eq!(l.timestamp_us, 1_700_000_000_123_456);
        assert_eq!(
            l.record,
            Record::Frame(Frame::from_array(
                Id::Standard(0x123),
                [0xDE, 0xAD, 0xBE, 0xEF]
            ))
        );
        let r = parse_line("(1.5) can0 701#R").unwrap();
        assert_eq!(r.timestamp_us, 1_500_000);
        assert_eq!(
            r.record,
            Record::Frame(Frame::remote(Id::Standard(0x701), 0).unwrap())
        );
        let e = parse_line("(1.000001) can0 20000040#0000000000000000").unwrap();
        assert_eq!(
            e.record,
            Record::Error {
                bits: 0x40,
                data: [0; 8]
            }
        );
        let fd = parse_line("(1.000001) can0 123##1112233").unwrap();
        assert_eq!(
            fd.record,
            Record::Fd {
                id: Id::Standard(0x123),
                flags: 1,
                data: vec![0x11, 0x22, 0x33]
            }
        );
        let dlc = parse_line("(1.000001) can0 123#1122334455667788_E").unwrap();
        assert_eq!(dlc.record.frame().unwrap().dlc(), 8);
        assert!(parse_line("(1.000001) can0 123#11 R").is_ok());
    }

    #[test]
    fn bad_and_truncated_lines_are_errors_with_line_numbers() {
        let log = "(1.000000) can0 123#11\n(1.000001) can0 12\n(1.0000\n\n(2.000000) can0 800#00\n(3.000000) can0 123#112";
        let items: Vec<_> = read_log(log.as_bytes()).collect();
        assert_eq!(items.len(), 5);
        assert!(items[0].is_ok());
        assert_eq!(items[1].as_ref().unwrap_err().line, 2);
        assert_eq!(items[2].as_ref().unwrap_err().line, 3);
        assert!(items[3]
            .as_ref()
            .unwrap_err()
            .reason
            .contains("above 0x7FF"));
        assert_eq!(items[4].as_ref().unwrap_err().line, 6);
        for bad in [
            "",
            "(x.1) a 1#",
            "(1.1234567890) a 123#",
            "(1.1) a 123#123456789012345678",
            "(1.1) a 1234#00",
            "(1.1) a 123#RZ",
            "(1.1) a 123##",
        ] {
            assert!(parse_line(bad).is_err(), "{bad:?} parsed");
        }
    }

    proptest! {
        #[test]
        fn round_trip(f in crate::frame::tests::any_frame(), ts in 0u64..4_000_000_000_000_000) {
            let line = format_frame(ts, "vcan1", &f);
            let e = parse_line(&line).unwrap();
            prop_assert_eq!(e.timestamp_us, ts);
            prop_assert_eq!(e.interface, "vcan1");
            prop_assert_eq!(e.record, Record::Frame(f));
        }

        #[test]
        fn arbitrary_text_never_panics(s in "\\PC{0,60}") {
            let _ = parse_line(&s);
        }
    }
}
