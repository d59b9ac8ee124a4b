//! Reading a candump log line by line with a bound on the line: a file that is not a log (one
//! line of a gigabyte) fails at its first long line without holding more than the bound.

use super::{parse, LogEntry, ParseError};
use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

/// Longest line read, in bytes (line end included). The longest valid line — a 64-byte CAN FD
/// frame with dots between its bytes, a long interface name and a direction — has about 260.
pub const MAX_LINE: usize = 512;

/// The entries of a candump log, each with the error of its line; see [`read_log`].
///
/// A line that cannot be parsed gives its error and reading goes on with the next; a line
/// longer than [`MAX_LINE`] or a read error ends the iteration after its error.
#[derive(Debug)]
pub struct CandumpReader<R> {
    inp: R,
    source: String,
    line: usize,
    buf: Vec<u8>,
    done: bool,
}

/// Reads the log in `r`; errors name `source` (a file name, or what the text is).
pub fn read_log<R: BufRead>(source: impl Into<String>, r: R) -> CandumpReader<R> {
    CandumpReader {
        inp: r,
        source: source.into(),
        line: 0,
        buf: Vec::with_capacity(MAX_LINE + 1),
        done: false,
    }
}

impl CandumpReader<BufReader<File>> {
    /// Opens a log file; errors name its path.
    pub fn open(path: impl AsRef<Path>) -> Result<Self, ParseError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        match File::open(path) {
            Ok(f) => Ok(read_log(name, BufReader::new(f))),
            Err(e) => Err(ParseError {
                source: name,
                line: 0,
                reason: format!("cannot open: {e}"),
            }),
        }
    }
}

impl<R> CandumpReader<R> {
    fn error(&self, reason: String) -> ParseError {
        ParseError {
            source: self.source.clone(),
            line: self.line,
            reason,
        }
    }

    /// The source name errors carry.
    pub fn source_name(&self) -> &str {
        &self.source
    }

    /// Bytes held for the current line (the bound, whatever the input).
    #[cfg(test)]
    pub(super) fn held(&self) -> usize {
        self.buf.capacity()
    }
}

impl<R: BufRead> CandumpReader<R> {
    /// The next line's bytes (without its end), `Ok(None)` at the end of the input.
    fn next_line(&mut self) -> Result<Option<()>, ParseError> {
        self.buf.clear();
        let n = (&mut self.inp)
            .take(MAX_LINE as u64 + 1)
            .read_until(b'\n', &mut self.buf);
        self.line += 1;
        match n {
            Err(e) => Err(self.error(format!("read error: {e}"))),
            Ok(0) => Ok(None),
            Ok(_) => {
                if self.buf.last() == Some(&b'\n') {
                    self.buf.pop();
                } else if self.buf.len() > MAX_LINE {
                    return Err(self.error(format!(
                        "line longer than {MAX_LINE} bytes: not a candump log"
                    )));
                }
                if self.buf.last() == Some(&b'\r') {
                    self.buf.pop();
                }
                Ok(Some(()))
            }
        }
    }

    fn entry(&self) -> Option<Result<LogEntry, ParseError>> {
        if let Some(col) = self.buf.iter().position(|b| !b.is_ascii()) {
            return Some(Err(self.error(format!(
                "byte {:#04X} at column {} is not ASCII",
                self.buf[col],
                col + 1
            ))));
        }
        // ASCII is UTF-8.
        let text = core::str::from_utf8(&self.buf).unwrap_or_default();
        if text.trim().is_empty() {
            return None;
        }
        Some(parse::parse(text).map_err(|r| self.error(r)))
    }
}

impl<R: BufRead> Iterator for CandumpReader<R> {
    type Item = Result<LogEntry, ParseError>;

    fn next(&mut self) -> Option<Self::Item> {
        while !self.done {
            match self.next_line() {
                Err(e) => {
                    self.done = true;
                    return Some(Err(e));
                }
                Ok(None) => self.done = true,
                Ok(Some(())) => {
                    if let Some(item) = self.entry() {
                        return Some(item);
                    }
                }
            }
        }
        None
    }
}
