//! Captures: candump logs, pcap files, and a recorder that taps ports and the logical bus.
//!
//! - [`candump`]: can-utils log lines (`(1700000000.123456) vcan0 123#DEADBEEF`), read and write.
//! - [`pcap`]: classic pcap with link type 227 (LINKTYPE_CAN_SOCKETCAN), read and write; what
//!   Wireshark and `tshark` open.
//! - [`recorder`]: a [`Tap`](recorder::Tap) the runtime (every port) and a [`Tapped`](recorder::Tapped)
//!   machine wrapper (the logical bus above the dual-bus layer) feed, writing to any of the above.
//!
//! Readers never panic on bad files and never guess: a truncated, garbled or out-of-range
//! capture gives an error naming the source and line (candump) or the record and byte offset
//! (pcap), and the records before it. Lines are read with a bound ([`candump::MAX_LINE`]), so a
//! file that is not a log costs no more memory than a line.

pub mod candump;
pub mod pcap;
pub mod recorder;

use crate::frame::Id;

/// One captured record: a classic frame, or what a classic frame cannot hold.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Record {
    /// A classic data or remote frame.
    Frame(crate::Frame),
    /// A SocketCAN error frame: error class bits and payload.
    Error {
        /// Error class bits (identifier word without the error flag).
        bits: u32,
        /// Payload (controller and protocol details).
        data: [u8; 8],
    },
    /// A CAN FD frame (kept, not interpreted: the stack is classic CAN).
    Fd {
        /// Identifier.
        id: Id,
        /// FD flags (BRS = 1, ESI = 2).
        flags: u8,
        /// Payload, up to 64 bytes.
        data: Vec<u8>,
    },
}

impl Record {
    /// The classic frame, if this is one.
    pub fn frame(&self) -> Option<&crate::Frame> {
        match self {
            Record::Frame(f) => Some(f),
            _ => None,
        }
    }
}
