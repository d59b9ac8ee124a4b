//! What a USDO client reports: the end of each transfer ([`UsdoEvent`]), why one failed
//! ([`UsdoError`]), and its counters.

use super::abort::UsdoAbort;
use crate::cia301::sdo::{Direction, TransferBuffer};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::od::abort::AbortCode;
use core::fmt;

/// Why a USDO transfer failed or could not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UsdoErrorKind {
    /// A transfer is running, or the last result has not been polled yet.
    Busy,
    /// The value is longer than the client's limit.
    TooLong {
        /// Bytes asked for.
        len: usize,
        /// The limit.
        limit: usize,
    },
    /// The server aborted.
    Server(UsdoAbort),
    /// This client aborted (timeout, a protocol error of the server, or [`UsdoClient::abort`](super::UsdoClient::abort)).
    Client(AbortCode),
}

/// A failed USDO transfer: with whom, on what, and why.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UsdoError {
    /// The server.
    pub server: NodeId,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Read or write.
    pub direction: Direction,
    /// Why.
    pub kind: UsdoErrorKind,
}

impl UsdoError {
    /// The CiA 301 abort code of the failure, where it has one.
    pub fn code(&self) -> Option<AbortCode> {
        match self.kind {
            UsdoErrorKind::Server(a) => a.code(),
            UsdoErrorKind::Client(c) => Some(c),
            _ => None,
        }
    }
}

impl fmt::Display for UsdoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let what = match self.direction {
            Direction::Upload => "read",
            Direction::Download => "write",
        };
        write!(
            f,
            "USDO {what} of {:#06x} sub {} on node {}: ",
            self.index,
            self.sub,
            self.server.raw()
        )?;
        match self.kind {
            UsdoErrorKind::Busy => f.write_str("a transfer is running"),
            UsdoErrorKind::TooLong { len, limit } => write!(f, "{len} bytes, the limit is {limit}"),
            UsdoErrorKind::Server(a) => write!(f, "aborted by the server: {a}"),
            UsdoErrorKind::Client(c) => write!(f, "aborted: {c}"),
        }
    }
}

impl core::error::Error for UsdoError {}

/// The end of a transfer.
#[derive(Debug)]
pub struct UsdoEvent<B> {
    /// When it ended.
    pub at: Instant,
    /// The session byte it ran under.
    pub session: u8,
    /// The value read (empty for a write), or why it failed.
    pub result: Result<B, UsdoError>,
}

impl<B: TransferBuffer> UsdoEvent<B> {
    /// The value read, if the transfer was a read that succeeded.
    pub fn data(&self) -> Option<&[u8]> {
        self.result.as_ref().ok().map(|b| b.as_slice())
    }
}

/// Counters of a USDO client.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UsdoClientStats {
    /// Transfers that succeeded.
    pub completed: u32,
    /// Transfers that failed.
    pub failed: u32,
    /// Answers ignored: another session's (late), another node's, or no transfer running.
    pub ignored: u32,
    /// Second copies of a segment answer ignored (see the module docs).
    pub repeats: u32,
}
