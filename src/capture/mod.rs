//! Captures: candump logs, pcap files, and a recorder that taps ports and the logical bus.
//!
//! - [`candump`]: can-utils log lines (`(1700000000.123456) vcan0 123#DEADBEEF`), read and write.
//! - [`pcap`]: classic pcap with link type 227 (LINKTYPE_CAN_SOCKETCAN), read and write; what
//!   Wireshark and `tshark` open.
//! - [`decode`]: every frame as one CANopen-aware line (NMT, heartbeat, SDO in its transfer,
//!   EMCY text, PDO values by name, LSS, flying master, railway 29-bit frames).
//! - [`recorder`]: a [`Tap`](recorder::Tap) the runtime (every port) and a [`Tapped`](recorder::Tapped)
//!   machine wrapper (the logical bus above the dual-bus layer) feed, writing to any of the above.
//!
//! Readers never panic on bad files and never guess: a truncated, garbled or out-of-range
//! capture gives an error naming the source and line (candump) or the record and byte offset
//! (pcap), and the records before it. Lines are read with a bound ([`candump::MAX_LINE`]), so a
//! file that is not a log costs no more memory than a line.
//!
//! Both formats written to memory and read back; a cut-off pcap record is an error with its
//! byte offset, after the records before it:
//!
//! ```
//! use duocan::capture::candump::{read_log, CandumpWriter};
//! use duocan::capture::pcap::{PcapError, PcapReader, PcapWriter};
//! use duocan::capture::Record;
//! use duocan::{Frame, Id};
//!
//! let sdo = Frame::from_array(Id::Standard(0x605), [0x40, 0x18, 0x10, 1, 0, 0, 0, 0]);
//! let mut log = CandumpWriter::new(Vec::new());
//! log.write(1_700_000_000_123_456, "can0", &sdo)?;
//! let text = log.into_inner();
//! assert_eq!(text, b"(1700000000.123456) can0 605#4018100100000000\n");
//! let entry = read_log("mem.log", &text[..]).next().unwrap()?;
//! assert_eq!((entry.interface.as_str(), entry.record), ("can0", Record::Frame(sdo)));
//!
//! let mut pcap = PcapWriter::new(Vec::new())?;
//! pcap.write(1_700_000_000_123_456, &sdo)?;
//! pcap.write(1_700_000_000_124_000, &sdo)?;
//! let mut bytes = pcap.into_inner();
//! bytes.truncate(bytes.len() - 3); // the second record loses its last bytes
//! let mut packets = PcapReader::new(&bytes[..])?;
//! assert_eq!(packets.next().unwrap()?.record.frame(), Some(&sdo));
//! // File header 24 bytes, each record 16 + 16: the second one starts at byte 56.
//! let err = packets.next().unwrap().unwrap_err();
//! assert!(matches!(err, PcapError::Truncated { offset: 56 }));
//! assert_eq!(err.to_string(), "pcap file truncated at byte 56");
//! assert!(packets.next().is_none());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod candump;
pub mod decode;
pub mod pcap;
pub mod recorder;

use crate::frame::FdFrame;

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
    /// A CAN FD frame (kept, not yet interpreted by the CANopen layers). Boxed: a capture of
    /// classic frames moves records of a classic frame's size, not of a 64-byte payload's.
    Fd(Box<FdFrame>),
}

impl Record {
    /// The classic frame, if this is one.
    pub fn frame(&self) -> Option<&crate::Frame> {
        match self {
            Record::Frame(f) => Some(f),
            _ => None,
        }
    }

    /// The CAN FD frame, if this is one.
    pub fn fd_frame(&self) -> Option<&FdFrame> {
        match self {
            Record::Fd(f) => Some(f),
            _ => None,
        }
    }
}
