//! What an SDO client reports when a transfer fails: which node, which object, which direction,
//! and why.

use crate::frame::cob_id::NodeId;
use crate::od::abort::AbortCode;
use core::fmt;

/// Upload (server → client) or download (client → server).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Reading an entry of the server.
    Upload,
    /// Writing an entry of the server.
    Download,
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Direction::Upload => "upload from",
            Direction::Download => "download to",
        })
    }
}

/// Why a transfer failed (or could not start).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoErrorKind {
    /// The server aborted the transfer with this code.
    Server(AbortCode),
    /// This client aborted the transfer with this code and told the server: a timeout
    /// ([`AbortCode::TIMEOUT`]), a protocol error in the server's answers (toggle, sequence,
    /// CRC, command), or data that does not fit.
    Client(AbortCode),
    /// A transfer to this server is already running; one at a time per server.
    Busy,
    /// Every client session is taken (running, or finished with a result not yet polled).
    NoSession {
        /// How many sessions the client has.
        sessions: usize,
    },
    /// The data is larger than the client's transfer limit.
    TooLong {
        /// Bytes asked for.
        len: usize,
        /// The limit.
        limit: usize,
    },
    /// The requested mode cannot carry this data (expedited carries 1–4 bytes).
    TransferMode,
}

/// A failed SDO transfer: node, object, direction and cause. `Display` says all of it, with the
/// CiA 301 meaning of the abort code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoError {
    /// The server's node.
    pub node: NodeId,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// Upload or download.
    pub direction: Direction,
    /// Why.
    pub kind: SdoErrorKind,
}

impl SdoError {
    /// The abort code, if the transfer was aborted (by either side).
    pub fn code(&self) -> Option<AbortCode> {
        match self.kind {
            SdoErrorKind::Server(c) | SdoErrorKind::Client(c) => Some(c),
            _ => None,
        }
    }
    /// True if either side gave up waiting (abort code 0x05040000).
    pub fn is_timeout(&self) -> bool {
        self.code() == Some(AbortCode::TIMEOUT)
    }
}

impl fmt::Display for SdoError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "SDO {} node {} ({:#04x}), object {:#06x} sub {}: ",
            self.direction,
            self.node.raw(),
            self.node.raw(),
            self.index,
            self.sub
        )?;
        match self.kind {
            SdoErrorKind::Server(code) => write!(f, "the server aborted with {code}"),
            SdoErrorKind::Client(AbortCode::TIMEOUT) => write!(
                f,
                "no answer in time, aborted with {}: check that the node is on the bus and not stopped, or raise the timeout",
                AbortCode::TIMEOUT
            ),
            SdoErrorKind::Client(code) => write!(f, "the client aborted with {code}"),
            SdoErrorKind::Busy => f.write_str(
                "a transfer to this node is already running: wait for its result event",
            ),
            SdoErrorKind::NoSession { sessions } => write!(
                f,
                "all {sessions} client sessions are in use: poll the finished results or raise the session count"
            ),
            SdoErrorKind::TooLong { len, limit } => write!(
                f,
                "{len} bytes exceed the client's transfer limit of {limit}: raise the limit"
            ),
            SdoErrorKind::TransferMode => {
                f.write_str("an expedited transfer carries 1 to 4 bytes: use segmented or auto")
            }
        }
    }
}

// The abort code, when there is one, is the cause (its CiA 301 meaning is in the message too).
impl core::error::Error for SdoError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match &self.kind {
            SdoErrorKind::Server(c) | SdoErrorKind::Client(c) => Some(c),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_names_node_object_and_meaning() {
        let e = SdoError {
            node: NodeId::must(5),
            index: 0x2000,
            sub: 1,
            direction: Direction::Download,
            kind: SdoErrorKind::Server(AbortCode::READ_ONLY),
        };
        assert_eq!(
            format!("{e}"),
            "SDO download to node 5 (0x05), object 0x2000 sub 1: the server aborted with 0x06010002 (attempt to write a read only object)"
        );
        let t = SdoError {
            kind: SdoErrorKind::Client(AbortCode::TIMEOUT),
            direction: Direction::Upload,
            ..e
        };
        assert!(t.is_timeout());
        assert!(format!("{t}").starts_with(
            "SDO upload from node 5 (0x05), object 0x2000 sub 1: no answer in time, aborted with 0x05040000 (SDO protocol timed out)"
        ));
    }
}
