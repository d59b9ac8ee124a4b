//! pcap files with link type 227 (LINKTYPE_CAN_SOCKETCAN), as Wireshark reads them.
//!
//! Each packet is a SocketCAN frame header — identifier word big-endian with the EFF (bit 31),
//! RTR (bit 30) and ERR (bit 29) flags, one length byte, three reserved bytes — followed by the
//! payload. Timestamps have microsecond resolution.
//!
//! CAN FD records are Linux's `struct canfd_frame` (`include/uapi/linux/can.h`): the same
//! identifier word, the length byte (0–64), then a flags byte with `CANFD_BRS` 0x01,
//! `CANFD_ESI` 0x02 and, since Linux 6.x and in libpcap's captures, `CANFD_FDF` 0x04, which
//! marks an FD frame; two reserved bytes and up to 64 data bytes. Wireshark's SocketCAN
//! dissector tells FD from classic by `CANFD_FDF` (a classic `can_frame` has a padding byte,
//! always zero, where the flags are); older captures lack the flag and have the whole 72-byte
//! `canfd_frame` (CANFD_MTU) as packet. The reader takes a record as FD when `CANFD_FDF`, BRS or
//! ESI is set, the packet is 72 bytes, or the length is above 8; the writer sets `CANFD_FDF`
//! and writes the whole 72 bytes, so readers of either kind see FD. An FD record with the RTR
//! flag, an undefined flag bit or a length between the FD steps is an error naming the record
//! and its byte offset.

use super::Record;
use crate::frame::fd::{BRS, ESI};
use crate::frame::{FdFrame, Frame, Id};
use crate::port::error_frame::{CAN_EFF_FLAG, CAN_ERR_FLAG, CAN_ERR_MASK, CAN_RTR_FLAG};
use std::fmt;
use std::io::{self, Read, Write};

/// LINKTYPE_CAN_SOCKETCAN.
pub const LINKTYPE_CAN_SOCKETCAN: u32 = 227;
/// Snapshot length written in the header (a CAN FD frame is 72 bytes).
pub const SNAPLEN: u32 = 72;
const MAGIC_US: u32 = 0xA1B2_C3D4;
const MAGIC_NS: u32 = 0xA1B2_3C4D;
/// Largest packet the reader accepts (anything bigger is a corrupt length field).
pub const MAX_PACKET: u32 = 4096;

/// `CANFD_FDF`: the flags byte's mark of a CAN FD frame.
pub const CANFD_FDF: u8 = 0x04;
/// Size of Linux's `struct canfd_frame`: a whole FD record.
pub const CANFD_MTU: usize = 72;

/// A CAN FD frame as a whole `canfd_frame`: identifier word big-endian, length, flags with
/// `CANFD_FDF` set, two reserved bytes, 64 data bytes (zero beyond the length).
pub fn encode_fd_frame(frame: &FdFrame) -> [u8; CANFD_MTU] {
    let word = match frame.id() {
        Id::Standard(r) => r as u32,
        Id::Extended(r) => r | CAN_EFF_FLAG,
    };
    let mut b = [0u8; CANFD_MTU];
    b[..4].copy_from_slice(&word.to_be_bytes());
    b[4] = frame.len() as u8;
    b[5] = frame.flags() | CANFD_FDF;
    b[8..8 + frame.len()].copy_from_slice(frame.data());
    b
}

/// The 8-byte SocketCAN header plus payload of one frame.
pub fn encode_frame(frame: &Frame) -> ([u8; 16], usize) {
    let mut word = match frame.id() {
        Id::Standard(r) => r as u32,
        Id::Extended(r) => r | CAN_EFF_FLAG,
    };
    if frame.is_remote() {
        word |= CAN_RTR_FLAG;
    }
    let mut b = [0u8; 16];
    b[..4].copy_from_slice(&word.to_be_bytes());
    b[4] = frame.dlc();
    let data = frame.data();
    b[8..8 + data.len()].copy_from_slice(data);
    (b, 8 + data.len())
}

/// Decodes one packet of link type 227. Strict: a standard identifier with bits above 0x7FF, a
/// remote frame's DLC above 8, a length beyond the packet or above 64 is an error, not masked or
/// cut. The error's record number and offset are 0 (the reader fills them in).
pub fn decode_packet(p: &[u8]) -> Result<Record, PcapError> {
    let bad = |reason: String| PcapError::BadPacket {
        record: 0,
        offset: 0,
        reason,
    };
    if p.len() < 8 {
        return Err(bad(format!(
            "{} bytes, shorter than the 8-byte SocketCAN header",
            p.len()
        )));
    }
    let word = u32::from_be_bytes([p[0], p[1], p[2], p[3]]);
    let len = p[4] as usize;
    let fd_flags = p[5];
    let payload = &p[8..];
    if word & CAN_ERR_FLAG != 0 {
        let mut data = [0u8; 8];
        let n = payload.len().min(8);
        data[..n].copy_from_slice(&payload[..n]);
        return Ok(Record::Error {
            bits: word & CAN_ERR_MASK,
            data,
        });
    }
    let id = if word & CAN_EFF_FLAG != 0 {
        Id::Extended(word & CAN_ERR_MASK)
    } else {
        // Without the extended flag only the 11 low bits may be set (besides RTR): anything
        // above them is a corrupt record, not an identifier to cut down.
        let raw = word & !CAN_RTR_FLAG;
        u16::try_from(raw)
            .ok()
            .and_then(Id::standard)
            .ok_or_else(|| {
                bad(format!(
                    "identifier {raw:#X} above 0x7FF without the extended flag"
                ))
            })?
    };
    // A classic `can_frame` has zero padding where an FD record has its flags.
    let fd = fd_flags & (CANFD_FDF | BRS | ESI) != 0 || p.len() == CANFD_MTU;
    if word & CAN_RTR_FLAG != 0 {
        if fd {
            return Err(bad(format!(
                "remote frame (RTR flag) in a CAN FD record (flags {fd_flags:#04X}): CAN FD has no remote frames"
            )));
        }
        return u8::try_from(len)
            .ok()
            .and_then(|dlc| Frame::remote(id, dlc).ok())
            .map(Record::Frame)
            .ok_or_else(|| bad(format!("remote frame DLC {len} above 8")));
    }
    if len > payload.len() {
        return Err(bad(format!(
            "length field {len} beyond the packet's {} data bytes",
            payload.len()
        )));
    }
    if len > 64 {
        return Err(bad(format!("length field {len} above 64")));
    }
    if fd || len > 8 {
        if fd_flags & !(CANFD_FDF | BRS | ESI) != 0 {
            return Err(bad(format!(
                "CAN FD flags {fd_flags:#04X}: only BRS (0x01), ESI (0x02) and FDF (0x04) are defined"
            )));
        }
        return FdFrame::new(id, &payload[..len])
            .map(|f| Record::Fd(Box::new(f.with_flags(fd_flags))))
            .map_err(|_| {
                bad(format!(
                    "CAN FD length field {len}: a CAN FD frame holds 0–8, 12, 16, 20, 24, 32, 48 or 64 bytes"
                ))
            });
    }
    Frame::new(id, &payload[..len])
        .map(Record::Frame)
        .map_err(|e| bad(e.to_string()))
}

/// Why a pcap file could not be read.
#[derive(Debug)]
pub enum PcapError {
    /// An I/O error.
    Io(io::Error),
    /// Not a pcap file (bad magic).
    NotPcap,
    /// A pcap file of another link type.
    LinkType(u32),
    /// The file ends inside a header or packet.
    Truncated {
        /// Byte offset where the incomplete part starts.
        offset: u64,
    },
    /// A packet length above [`MAX_PACKET`].
    Oversized {
        /// Byte offset of the packet header.
        offset: u64,
        /// The length it claims.
        len: u32,
    },
    /// A packet that is not a valid SocketCAN frame.
    BadPacket {
        /// 1-based record number in the file (0 when decoding a lone packet).
        record: u64,
        /// Byte offset of the record header (0 when decoding a lone packet).
        offset: u64,
        /// What is wrong.
        reason: String,
    },
    /// A record whose timestamp fraction is not below one second.
    BadTimestamp {
        /// 1-based record number.
        record: u64,
        /// Byte offset of the record header.
        offset: u64,
        /// The fraction field as written (microseconds, or nanoseconds in a nanosecond file).
        fraction: u32,
    },
}

impl fmt::Display for PcapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PcapError::Io(e) => write!(f, "pcap read error: {e}"),
            PcapError::NotPcap => f.write_str("not a pcap file (bad magic number)"),
            PcapError::LinkType(t) => write!(
                f,
                "pcap link type {t}, expected {LINKTYPE_CAN_SOCKETCAN} (CAN_SOCKETCAN)"
            ),
            PcapError::Truncated { offset } => {
                write!(f, "pcap file truncated at byte {offset}")
            }
            PcapError::Oversized { offset, len } => {
                write!(
                    f,
                    "pcap packet at byte {offset} claims {len} bytes: corrupt file"
                )
            }
            PcapError::BadPacket {
                record: 0, reason, ..
            } => write!(f, "bad SocketCAN packet: {reason}"),
            PcapError::BadPacket {
                record,
                offset,
                reason,
            } => write!(
                f,
                "pcap record {record} (byte {offset}): bad SocketCAN packet: {reason}"
            ),
            PcapError::BadTimestamp {
                record,
                offset,
                fraction,
            } => write!(
                f,
                "pcap record {record} (byte {offset}): timestamp fraction {fraction} is not below one second"
            ),
        }
    }
}

impl std::error::Error for PcapError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            PcapError::Io(e) => Some(e),
            _ => None,
        }
    }
}

/// Writes a pcap file.
#[derive(Debug)]
pub struct PcapWriter<W: Write> {
    out: W,
}

impl<W: Write> PcapWriter<W> {
    /// Writes the file header.
    pub fn new(mut out: W) -> io::Result<Self> {
        let mut h = Vec::with_capacity(24);
        h.extend_from_slice(&MAGIC_US.to_le_bytes());
        h.extend_from_slice(&2u16.to_le_bytes());
        h.extend_from_slice(&4u16.to_le_bytes());
        h.extend_from_slice(&0i32.to_le_bytes());
        h.extend_from_slice(&0u32.to_le_bytes());
        h.extend_from_slice(&SNAPLEN.to_le_bytes());
        h.extend_from_slice(&LINKTYPE_CAN_SOCKETCAN.to_le_bytes());
        out.write_all(&h)?;
        Ok(PcapWriter { out })
    }
    /// Writes one frame at `timestamp_us` (microseconds since the Unix epoch).
    pub fn write(&mut self, timestamp_us: u64, frame: &Frame) -> io::Result<()> {
        let (b, n) = encode_frame(frame);
        let mut rec = [0u8; 32];
        let secs = u32::try_from(timestamp_us / 1_000_000).unwrap_or(u32::MAX);
        rec[0..4].copy_from_slice(&secs.to_le_bytes());
        rec[4..8].copy_from_slice(&((timestamp_us % 1_000_000) as u32).to_le_bytes());
        rec[8..12].copy_from_slice(&(n as u32).to_le_bytes());
        rec[12..16].copy_from_slice(&(n as u32).to_le_bytes());
        rec[16..16 + n].copy_from_slice(&b[..n]);
        self.out.write_all(&rec[..16 + n])
    }
    /// Writes one CAN FD frame at `timestamp_us`, as a whole 72-byte `canfd_frame`.
    pub fn write_fd(&mut self, timestamp_us: u64, frame: &FdFrame) -> io::Result<()> {
        let mut rec = [0u8; 16 + CANFD_MTU];
        let secs = u32::try_from(timestamp_us / 1_000_000).unwrap_or(u32::MAX);
        rec[0..4].copy_from_slice(&secs.to_le_bytes());
        rec[4..8].copy_from_slice(&((timestamp_us % 1_000_000) as u32).to_le_bytes());
        rec[8..12].copy_from_slice(&(CANFD_MTU as u32).to_le_bytes());
        rec[12..16].copy_from_slice(&(CANFD_MTU as u32).to_le_bytes());
        rec[16..].copy_from_slice(&encode_fd_frame(frame));
        self.out.write_all(&rec)
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

/// Reads a pcap file of link type 227.
#[derive(Debug)]
pub struct PcapReader<R: Read> {
    inp: R,
    swapped: bool,
    nanos: bool,
    offset: u64,
    /// Records read so far (the next one's number minus one).
    records: u64,
    done: bool,
}

/// One packet: its time and content.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Packet {
    /// Microseconds since the Unix epoch.
    pub timestamp_us: u64,
    /// The frame.
    pub record: Record,
}

fn read_full<R: Read>(r: &mut R, buf: &mut [u8]) -> io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match r.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

impl<R: Read> PcapReader<R> {
    /// Reads and checks the file header.
    pub fn new(mut inp: R) -> Result<Self, PcapError> {
        let mut h = [0u8; 24];
        let n = read_full(&mut inp, &mut h).map_err(PcapError::Io)?;
        if n < 4 {
            return Err(PcapError::NotPcap);
        }
        let magic = u32::from_le_bytes([h[0], h[1], h[2], h[3]]);
        let (swapped, nanos) = match magic {
            MAGIC_US => (false, false),
            MAGIC_NS => (false, true),
            m if m.swap_bytes() == MAGIC_US => (true, false),
            m if m.swap_bytes() == MAGIC_NS => (true, true),
            _ => return Err(PcapError::NotPcap),
        };
        if n < 24 {
            return Err(PcapError::Truncated { offset: 0 });
        }
        let r = PcapReader {
            inp,
            swapped,
            nanos,
            offset: 24,
            records: 0,
            done: false,
        };
        let lt = r.u32(&h[20..24]) & 0x0FFF_FFFF;
        if lt != LINKTYPE_CAN_SOCKETCAN {
            return Err(PcapError::LinkType(lt));
        }
        Ok(r)
    }

    fn u32(&self, b: &[u8]) -> u32 {
        let v = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        if self.swapped {
            v.swap_bytes()
        } else {
            v
        }
    }

    /// Fills `buf` as far as the input goes; an I/O error ends the reading.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, PcapError> {
        read_full(&mut self.inp, buf).map_err(|e| {
            self.done = true;
            PcapError::Io(e)
        })
    }

    /// The next packet, `Ok(None)` at a clean end of file. A record that is not a valid
    /// SocketCAN frame is an error naming its number and offset, and reading can go on with
    /// the next; a truncated or oversized record or an I/O error ends the file.
    pub fn next_packet(&mut self) -> Result<Option<Packet>, PcapError> {
        if self.done {
            return Ok(None);
        }
        let mut h = [0u8; 16];
        let n = self.read(&mut h)?;
        if n == 0 {
            self.done = true;
            return Ok(None);
        }
        let at = self.offset;
        if n < 16 {
            self.done = true;
            return Err(PcapError::Truncated { offset: at });
        }
        self.records += 1;
        let record = self.records;
        let secs = u64::from(self.u32(&h[0..4]));
        let frac = self.u32(&h[4..8]);
        let incl = self.u32(&h[8..12]);
        if incl > MAX_PACKET {
            self.done = true;
            return Err(PcapError::Oversized {
                offset: at,
                len: incl,
            });
        }
        let mut p = vec![0u8; incl as usize];
        let k = self.read(&mut p)?;
        if k < p.len() {
            self.done = true;
            return Err(PcapError::Truncated { offset: at });
        }
        self.offset += 16 + u64::from(incl);
        // A bad record is reported and skipped: its length field framed it, so the next
        // record starts where it should.
        if frac >= if self.nanos { 1_000_000_000 } else { 1_000_000 } {
            return Err(PcapError::BadTimestamp {
                record,
                offset: at,
                fraction: frac,
            });
        }
        let micros = u64::from(if self.nanos { frac / 1000 } else { frac });
        let packet = decode_packet(&p).map_err(|e| match e {
            PcapError::BadPacket { reason, .. } => PcapError::BadPacket {
                record,
                offset: at,
                reason,
            },
            e => e,
        })?;
        Ok(Some(Packet {
            timestamp_us: secs * 1_000_000 + micros,
            record: packet,
        }))
    }
}

impl<R: Read> Iterator for PcapReader<R> {
    type Item = Result<Packet, PcapError>;
    fn next(&mut self) -> Option<Self::Item> {
        self.next_packet().transpose()
    }
}

#[cfg(test)]
mod tests;
