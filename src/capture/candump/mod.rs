//! can-utils candump log format: `(SECONDS.MICROS) IFACE ID#DATA`.
//!
//! `ID` is 3 hex digits for standard and 8 for extended identifiers; `#R` (optionally followed
//! by the DLC digit) marks a remote frame; an 8-digit identifier with the error flag
//! (0x20000000) is an error frame. What `candump -l` writes and `canplayer` reads.
//!
//! A CAN FD frame is `ID##F` then its data: `F` is one hex digit holding the `canfd_frame`
//! flags (BRS 1, ESI 2), the data 0–64 bytes of a CAN FD length. The layout is the one
//! can-utils' `lib.c` reads (`parse_canframe`: a second `#` after the identifier, one flags
//! nibble, then hex bytes with optional dots) and writes (`sprint_canframe`, the flags as one
//! upper-case digit). Newer can-utils may set `CANFD_FDF` (4) in the digit; it is accepted and
//! dropped (`##` already says FD), and duocan writes BRS and ESI only. A digit with bit 8, a
//! remote frame or a length between the FD steps is an error.
//!
//! ```
//! use duocan::capture::candump::{format_fd_frame, parse_line};
//! use duocan::{FdFrame, Id};
//!
//! let f = FdFrame::new(Id::Standard(0x123), &[0x11; 12])?.with_brs(true);
//! let line = format_fd_frame(1_000_000, "can0", &f);
//! assert_eq!(line, "(1.000000) can0 123##1111111111111111111111111");
//! assert_eq!(parse_line(&line)?.record.fd_frame(), Some(&f));
//! let e = parse_line("(1.0) can0 123##1112233445566778899").unwrap_err();
//! assert!(e.to_string().contains("9 data bytes"));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Reading is strict: every token is checked whole (no signs, no stray characters, identifier,
//! DLC and data in range), nothing but a direction (`R`/`T`) may follow the frame, and a line
//! may not pass [`MAX_LINE`] bytes. An error names the source, the line and what is wrong:
//!
//! ```
//! use duocan::capture::candump::read_log;
//!
//! let log = "(1.000000) can0 123#11\n(1.000001) can0 123#+1\n";
//! let mut entries = read_log("bus.log", log.as_bytes());
//! assert!(entries.next().unwrap().is_ok());
//! let e = entries.next().unwrap().unwrap_err();
//! assert_eq!(e.to_string(), r#"bus.log, line 2: data "+1": not hexadecimal digits"#);
//! ```

mod parse;
mod reader;

pub use parse::MAX_INTERFACE;
pub use reader::{read_log, CandumpReader, MAX_LINE};

use super::Record;
use crate::frame::{FdFrame, Frame, Id};
use std::fmt::{self, Write as _};
use std::io::{self, Write};

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

/// Why a line is not a candump log line, and where it is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParseError {
    /// Where the text came from: the file name or what the reader was told (empty for
    /// [`parse_line`]).
    pub source: String,
    /// 1-based line number (0 for [`parse_line`] and for a file that could not be opened).
    pub line: usize,
    /// What is wrong, naming the token.
    pub reason: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.source.is_empty(), self.line) {
            (true, 0) => write!(f, "candump line: {}", self.reason),
            (true, n) => write!(f, "candump log line {n}: {}", self.reason),
            (false, 0) => write!(f, "{}: {}", self.source, self.reason),
            (false, n) => write!(f, "{}, line {n}: {}", self.source, self.reason),
        }
    }
}

impl std::error::Error for ParseError {}

/// A line's `(SECONDS.MICROS) IFACE ` in a string with room for `body` more bytes.
fn line_start(timestamp_us: u64, interface: &str, body: usize) -> String {
    let mut s = String::with_capacity(32 + interface.len() + body);
    let _ = write!(
        s,
        "({}.{:06}) {} ",
        timestamp_us / 1_000_000,
        timestamp_us % 1_000_000,
        interface
    );
    s
}

/// Formats a frame as a log line (without newline).
pub fn format_frame(timestamp_us: u64, interface: &str, frame: &Frame) -> String {
    let mut s = line_start(timestamp_us, interface, 26);
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

/// Formats a CAN FD frame as a log line (without newline): `ID##F` with the flags digit
/// (BRS 1, ESI 2), then the data.
pub fn format_fd_frame(timestamp_us: u64, interface: &str, frame: &FdFrame) -> String {
    let mut s = line_start(timestamp_us, interface, 11 + 2 * frame.len());
    match frame.id() {
        Id::Standard(r) => {
            let _ = write!(s, "{r:03X}##{:X}", frame.flags());
        }
        Id::Extended(r) => {
            let _ = write!(s, "{r:08X}##{:X}", frame.flags());
        }
    }
    for b in frame.data() {
        let _ = write!(s, "{b:02X}");
    }
    s
}

/// Parses one log line (without its line end).
pub fn parse_line(line: &str) -> Result<LogEntry, ParseError> {
    parse::parse(line).map_err(|reason| ParseError {
        source: String::new(),
        line: 0,
        reason,
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
    /// Writes one CAN FD frame.
    pub fn write_fd(
        &mut self,
        timestamp_us: u64,
        interface: &str,
        frame: &FdFrame,
    ) -> io::Result<()> {
        writeln!(
            self.out,
            "{}",
            format_fd_frame(timestamp_us, interface, frame)
        )
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
mod tests;
