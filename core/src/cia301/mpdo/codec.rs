//! The classic MPDO frame: eight bytes, an address byte, the multiplexer and four data bytes.

use crate::frame::{Frame, Id};
use core::fmt;

/// Length of a classic MPDO: always eight bytes.
pub const LEN: usize = 8;
/// Data bytes a classic MPDO carries.
pub const DATA_LEN: usize = 4;
/// Bit 7 of byte 0: set for destination-address mode.
const DAM_BIT: u8 = 0x80;

/// Which address byte 0 carries (its bit 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// Source-address mode (bit 7 clear): the node-ID is the producer's own, the multiplexer
    /// names an object of the producer, and each consumer maps it through its dispatcher list.
    Source,
    /// Destination-address mode (bit 7 set): the node-ID is the consumer's (0: every node) and
    /// the multiplexer names the object of the consumer to write.
    Destination,
}

impl Mode {
    /// The mapping count (sub 0 of 0x16xx/0x1Axx) that makes a PDO an MPDO of this mode:
    /// 0xFE source-address, 0xFF destination-address mode.
    pub const fn mapping_count(self) -> u8 {
        match self {
            Mode::Source => SAM_COUNT,
            Mode::Destination => DAM_COUNT,
        }
    }

    /// The mode a mapping count stands for; `None` for a classic PDO's count.
    pub const fn from_mapping_count(count: u32) -> Option<Mode> {
        match count {
            0xFE => Some(Mode::Source),
            0xFF => Some(Mode::Destination),
            _ => None,
        }
    }
}

/// Mapping count of a source-address-mode MPDO (CiA 301).
pub const SAM_COUNT: u8 = 0xFE;
/// Mapping count of a destination-address-mode MPDO (CiA 301).
pub const DAM_COUNT: u8 = 0xFF;

/// One classic MPDO.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Mpdo {
    /// Address mode (byte 0, bit 7).
    pub mode: Mode,
    /// Byte 0, bits 0–6: the producer (source mode, 1–127) or the destination (destination
    /// mode, 0 = every node). Only its seven low bits are sent.
    pub node: u8,
    /// Object index (bytes 1–2, little-endian).
    pub index: u16,
    /// Sub-index (byte 3).
    pub sub: u8,
    /// The value, little-endian, zero-filled after the object's size (bytes 4–7).
    pub data: [u8; DATA_LEN],
}

/// Why bytes are no MPDO.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MpdoDecodeError {
    /// Not the length the form requires (classic: 8 bytes; FD: a CAN FD length of 8 to 64).
    Length {
        /// Bytes received.
        got: usize,
    },
    /// A source-address MPDO from node 0, which no producer has.
    NoProducer,
}

impl fmt::Display for MpdoDecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MpdoDecodeError::Length { got } => write!(f, "MPDO of {got} bytes"),
            MpdoDecodeError::NoProducer => f.write_str("source-address MPDO from node 0"),
        }
    }
}

/// Decodes the four header bytes every MPDO form shares.
pub(super) fn header(b: &[u8]) -> Result<(Mode, u8, u16, u8), MpdoDecodeError> {
    let [a, i0, i1, sub, ..] = *b else {
        return Err(MpdoDecodeError::Length { got: b.len() });
    };
    let mode = if a & DAM_BIT != 0 {
        Mode::Destination
    } else {
        Mode::Source
    };
    let node = a & 0x7F;
    if mode == Mode::Source && node == 0 {
        return Err(MpdoDecodeError::NoProducer);
    }
    Ok((mode, node, u16::from_le_bytes([i0, i1]), sub))
}

/// Encodes the four header bytes.
pub(super) fn put_header(out: &mut [u8], mode: Mode, node: u8, index: u16, sub: u8) {
    let dam = if mode == Mode::Destination {
        DAM_BIT
    } else {
        0
    };
    let i = index.to_le_bytes();
    out[..4].copy_from_slice(&[dam | (node & 0x7F), i[0], i[1], sub]);
}

impl Mpdo {
    /// A destination-address MPDO writing `data` (up to 4 bytes, little-endian; the rest zero)
    /// to (`index`, `sub`) of node `dest` (0: every node). `None` for more than 4 bytes or a
    /// destination above 127.
    #[must_use]
    pub fn dam(dest: u8, index: u16, sub: u8, data: &[u8]) -> Option<Mpdo> {
        Self::with(Mode::Destination, dest, index, sub, data)
    }

    /// A source-address MPDO: producer `node` (1–127) sends the value of its (`index`, `sub`).
    /// `None` for more than 4 bytes or a node-ID outside 1–127.
    #[must_use]
    pub fn sam(node: u8, index: u16, sub: u8, data: &[u8]) -> Option<Mpdo> {
        if node == 0 {
            return None;
        }
        Self::with(Mode::Source, node, index, sub, data)
    }

    fn with(mode: Mode, node: u8, index: u16, sub: u8, data: &[u8]) -> Option<Mpdo> {
        if node > 127 || data.len() > DATA_LEN {
            return None;
        }
        let mut d = [0u8; DATA_LEN];
        d[..data.len()].copy_from_slice(data);
        Some(Mpdo {
            mode,
            node,
            index,
            sub,
            data: d,
        })
    }

    /// Decodes a received MPDO: exactly 8 bytes, else [`MpdoDecodeError::Length`]; never panics.
    pub fn decode(b: &[u8]) -> Result<Mpdo, MpdoDecodeError> {
        if b.len() != LEN {
            return Err(MpdoDecodeError::Length { got: b.len() });
        }
        let (mode, node, index, sub) = header(b)?;
        Ok(Mpdo {
            mode,
            node,
            index,
            sub,
            data: [b[4], b[5], b[6], b[7]],
        })
    }

    /// The eight bytes on the bus.
    #[must_use]
    pub fn to_bytes(&self) -> [u8; LEN] {
        let mut b = [0u8; LEN];
        put_header(&mut b, self.mode, self.node, self.index, self.sub);
        b[4..].copy_from_slice(&self.data);
        b
    }

    /// The frame on identifier `id` (the MPDO's TPDO COB-ID).
    #[must_use]
    pub fn frame(&self, id: Id) -> Frame {
        Frame::from_array(id, self.to_bytes())
    }
}
