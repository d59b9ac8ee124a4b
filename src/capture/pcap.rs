//! pcap files with link type 227 (LINKTYPE_CAN_SOCKETCAN), as Wireshark reads them.
//!
//! Each packet is a SocketCAN frame header — identifier word big-endian with the EFF (bit 31),
//! RTR (bit 30) and ERR (bit 29) flags, one length byte, three reserved bytes — followed by the
//! payload. Timestamps have microsecond resolution.

use super::Record;
use crate::frame::{Frame, Id};
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

/// Decodes one packet of link type 227.
pub fn decode_packet(p: &[u8]) -> Result<Record, PcapError> {
    if p.len() < 8 {
        return Err(PcapError::BadPacket(
            "shorter than the 8-byte SocketCAN header",
        ));
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
        Id::Extended(word & 0x1FFF_FFFF)
    } else {
        Id::standard((word & 0x7FF) as u16).ok_or(PcapError::BadPacket("bad identifier"))?
    };
    if word & CAN_RTR_FLAG != 0 {
        let dlc = u8::try_from(len).map_err(|_| PcapError::BadPacket("bad DLC"))?;
        return Frame::remote(id, dlc)
            .map(Record::Frame)
            .map_err(|_| PcapError::BadPacket("remote frame DLC above 8"));
    }
    if len > payload.len() {
        return Err(PcapError::BadPacket("length field beyond the packet"));
    }
    if len > 8 || fd_flags & 0x04 != 0 {
        return Ok(Record::Fd {
            id,
            flags: fd_flags & 0x03,
            data: payload[..len].to_vec(),
        });
    }
    Frame::new(id, &payload[..len])
        .map(Record::Frame)
        .map_err(|_| PcapError::BadPacket("bad length"))
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
    BadPacket(&'static str),
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
            PcapError::BadPacket(why) => write!(f, "bad SocketCAN packet: {why}"),
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

    /// The next packet, `Ok(None)` at a clean end of file.
    pub fn next_packet(&mut self) -> Result<Option<Packet>, PcapError> {
        if self.done {
            return Ok(None);
        }
        let mut h = [0u8; 16];
        let n = read_full(&mut self.inp, &mut h).map_err(PcapError::Io)?;
        if n == 0 {
            self.done = true;
            return Ok(None);
        }
        let at = self.offset;
        if n < 16 {
            self.done = true;
            return Err(PcapError::Truncated { offset: at });
        }
        let secs = u64::from(self.u32(&h[0..4]));
        let frac = u64::from(self.u32(&h[4..8]));
        let incl = self.u32(&h[8..12]);
        if incl > MAX_PACKET {
            self.done = true;
            return Err(PcapError::Oversized {
                offset: at,
                len: incl,
            });
        }
        let mut p = vec![0u8; incl as usize];
        let k = read_full(&mut self.inp, &mut p).map_err(PcapError::Io)?;
        if k < p.len() {
            self.done = true;
            return Err(PcapError::Truncated { offset: at });
        }
        self.offset += 16 + u64::from(incl);
        let micros = if self.nanos { frac / 1000 } else { frac };
        let record = decode_packet(&p)?;
        Ok(Some(Packet {
            timestamp_us: secs * 1_000_000 + micros.min(999_999),
            record,
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
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn file(frames: &[(u64, Frame)]) -> Vec<u8> {
        let mut w = PcapWriter::new(Vec::new()).unwrap();
        for (t, f) in frames {
            w.write(*t, f).unwrap();
        }
        w.into_inner()
    }

    #[test]
    fn header_and_packet_layout() {
        let b = file(&[(
            1_700_000_000_000_001,
            Frame::from_array(Id::Extended(0x1234_5678), [0xAA]),
        )]);
        assert_eq!(&b[..4], &[0xD4, 0xC3, 0xB2, 0xA1]);
        assert_eq!(u32::from_le_bytes(b[20..24].try_into().unwrap()), 227);
        // record header then 0x92345678 (EFF flag) big-endian, len 1, 3 reserved, data.
        assert_eq!(&b[40..49], &[0x92, 0x34, 0x56, 0x78, 1, 0, 0, 0, 0xAA]);
        assert_eq!(b.len(), 24 + 16 + 9);
    }

    #[test]
    fn truncated_and_foreign_files_are_errors() {
        let b = file(&[
            (1, Frame::from_array(Id::Standard(0x181), [1, 2, 3])),
            (2, Frame::from_array(Id::Standard(0x701), [5])),
        ]);
        for cut in 0..b.len() {
            let r = PcapReader::new(&b[..cut]);
            let Ok(r) = r else { continue };
            let items: Vec<_> = r.collect();
            let complete = items.iter().filter(|x| x.is_ok()).count();
            if cut == 24 || cut == 24 + 27 || cut == b.len() {
                assert!(items.iter().all(|x| x.is_ok()), "cut {cut}");
            } else {
                assert!(
                    matches!(items.last(), Some(Err(PcapError::Truncated { .. }))),
                    "cut {cut}: {items:?}"
                );
            }
            assert!(complete <= 2);
        }
        assert!(matches!(
            PcapReader::new(&b"hello world, not pcap"[..]),
            Err(PcapError::NotPcap)
        ));
        let mut other = b.clone();
        other[20] = 1;
        assert!(matches!(
            PcapReader::new(&other[..]),
            Err(PcapError::LinkType(1))
        ));
        let mut huge = b.clone();
        huge[32..36].copy_from_slice(&1_000_000u32.to_le_bytes());
        let first = PcapReader::new(&huge[..]).unwrap().next().unwrap();
        assert!(matches!(first, Err(PcapError::Oversized { .. })));
    }

    proptest! {
        #[test]
        fn round_trip(frames in proptest::collection::vec((0u64..4_000_000_000_000_000, crate::frame::tests::any_frame()), 0..20)) {
            let b = file(&frames);
            let back: Vec<_> = PcapReader::new(&b[..]).unwrap().map(|p| p.unwrap()).collect();
            prop_assert_eq!(back.len(), frames.len());
            for (p, (t, f)) in back.iter().zip(&frames) {
                prop_assert_eq!(p.timestamp_us, *t);
                prop_assert_eq!(&p.record, &Record::Frame(*f));
            }
        }

        #[test]
        fn arbitrary_bytes_never_panic(mut b in proptest::collection::vec(any::<u8>(), 0..200)) {
            if b.len() >= 24 {
                b[..4].copy_from_slice(&MAGIC_US.to_le_bytes());
                b[20..24].copy_from_slice(&227u32.to_le_bytes());
            }
            if let Ok(r) = PcapReader::new(&b[..]) {
                for _ in r {}
            }
        }
    }
}
