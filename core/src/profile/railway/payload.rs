//! The railway payload of process frames: index (2 bytes, little-endian) + sub-index (1) +
//! data (0–3) + CRC (2, little-endian), 5–8 bytes.
//!
//! # The CRC
//!
//! CRC-16/IBM-3740 (also called CCITT-FALSE: polynomial 0x1021, initial value 0xFFFF, no
//! reflection, no final XOR) over
//!
//! ```text
//! identifier (4 bytes, big-endian, bit 31 set for 29-bit) · content length (1) · content
//! ```
//!
//! where the content is everything before the CRC. Why this one:
//!
//! - **End to end, over the identifier.** The CAN CRC protects one hop; this one goes from the
//!   producing board to the interlocking's application, through controllers, drivers and the
//!   dual-bus merger. Covering the identifier means a frame whose address bits were corrupted,
//!   or one board's frame replayed under another board's identifier, fails the check.
//! - **Not the CAN polynomial.** CAN uses CRC-15 (0x4599); an error pattern that slips through
//!   it is not systematically a multiple of 0x1021 too (the black-channel rule of EN 50159).
//! - **Hamming distance 4** for messages up to 32 751 bits: every 1-, 2- and 3-bit error and
//!   every burst of up to 16 bits in the at most 13 bytes checked is detected; anything else
//!   passes with probability 2⁻¹⁶.
//! - **Non-zero start value.** With 0 (CRC-16/XMODEM, the SDO block CRC) an all-zero message has
//!   CRC 0, so a stuck-at-0 frame would check; with 0xFFFF it does not.
//! - **The length is checked too**, so a frame truncated to a shorter valid length does not keep
//!   a matching CRC by construction.
//! - It shares the SDO block CRC's 512-byte table: no extra flash.
//!
//! Decoding never panics: a remote frame, a wrong length or a CRC mismatch is a
//! [`PayloadError`].

use crate::cia301::sdo::crc;
use crate::frame::{Frame, Id};
use core::fmt;

/// Most data bytes a payload carries (8 − index − sub-index − CRC).
pub const MAX_DATA: usize = 3;
/// Bytes of a payload besides its data.
pub const OVERHEAD: usize = 5;
/// Start value of the CRC (CRC-16/IBM-3740).
pub const CRC_INIT: u16 = 0xFFFF;

/// Index, sub-index and up to three data bytes.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Payload {
    index: u16,
    sub: u8,
    len: u8,
    data: [u8; MAX_DATA],
}

/// Why a payload could not be built or read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PayloadError {
    /// More than [`MAX_DATA`] data bytes to encode.
    DataTooLong {
        /// Bytes given.
        len: usize,
    },
    /// A remote frame carries no payload.
    Remote {
        /// Its identifier.
        id: Id,
    },
    /// Fewer than 5 or more than 8 bytes.
    Length {
        /// Its identifier.
        id: Id,
        /// Bytes received.
        len: usize,
    },
    /// The CRC does not match the identifier and content: corrupted, or not meant for this
    /// identifier.
    Crc {
        /// Its identifier.
        id: Id,
        /// The CRC of what arrived.
        computed: u16,
        /// The CRC the frame carries.
        carried: u16,
    },
}

impl fmt::Display for PayloadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PayloadError::DataTooLong { len } => write!(
                f,
                "railway payload of {len} data bytes: at most {MAX_DATA} fit beside index, sub-index and CRC"
            ),
            PayloadError::Remote { id } => {
                write!(f, "frame {id}: a remote frame carries no railway payload")
            }
            PayloadError::Length { id, len } => write!(
                f,
                "frame {id}: {len} bytes; a railway payload has {OVERHEAD}-8 (index, sub-index, data, CRC)"
            ),
            PayloadError::Crc {
                id,
                computed,
                carried,
            } => write!(
                f,
                "frame {id}: CRC {carried:#06x} does not match {computed:#06x}: corrupted or misrouted, discard it"
            ),
        }
    }
}

impl core::error::Error for PayloadError {}

/// The CRC of `content` sent under `id`.
pub fn crc(id: Id, content: &[u8]) -> u16 {
    let word = match id {
        Id::Extended(r) => r | 0x8000_0000,
        Id::Standard(r) => r as u32,
    };
    let c = crc::update(CRC_INIT, &word.to_be_bytes());
    let c = crc::update(c, &[content.len() as u8]);
    crc::update(c, content)
}

impl Payload {
    /// A payload; fails beyond [`MAX_DATA`] data bytes.
    pub const fn new(index: u16, sub: u8, data: &[u8]) -> Result<Payload, PayloadError> {
        if data.len() > MAX_DATA {
            return Err(PayloadError::DataTooLong { len: data.len() });
        }
        let mut d = [0u8; MAX_DATA];
        let mut i = 0;
        while i < data.len() {
            d[i] = data[i];
            i += 1;
        }
        Ok(Payload {
            index,
            sub,
            len: data.len() as u8,
            data: d,
        })
    }
    /// A payload of one data byte (a safety state).
    #[must_use]
    pub const fn byte(index: u16, sub: u8, value: u8) -> Payload {
        Payload {
            index,
            sub,
            len: 1,
            data: [value, 0, 0],
        }
    }
    /// A payload without data (a state query).
    #[must_use]
    pub const fn empty(index: u16, sub: u8) -> Payload {
        Payload {
            index,
            sub,
            len: 0,
            data: [0; MAX_DATA],
        }
    }
    /// Object index.
    pub const fn index(&self) -> u16 {
        self.index
    }
    /// Sub-index.
    pub const fn sub(&self) -> u8 {
        self.sub
    }
    /// The data bytes.
    pub fn data(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }
    /// Encoded length in bytes (5–8).
    pub const fn encoded_len(&self) -> usize {
        OVERHEAD + self.len as usize
    }

    /// The bytes to send under `id` (the first [`Payload::encoded_len`] are used; the rest are
    /// zero). What a PDO-mapped entry holds when the stack's TPDO carries the frame.
    pub fn to_bytes(&self, id: Id) -> [u8; 8] {
        let mut b = [0u8; 8];
        let n = 3 + self.len as usize;
        b[..2].copy_from_slice(&self.index.to_le_bytes());
        b[2] = self.sub;
        b[3..n].copy_from_slice(self.data());
        let c = crc(id, &b[..n]);
        b[n..n + 2].copy_from_slice(&c.to_le_bytes());
        b
    }
    /// The frame carrying this payload under `id`.
    pub fn encode(&self, id: Id) -> Frame {
        let b = self.to_bytes(id);
        // At most 8 bytes: `Frame::new` cannot fail.
        Frame::new(id, &b[..self.encoded_len()]).unwrap_or_else(|_| Frame::from_array(id, b))
    }
    /// Reads and checks the payload of a frame.
    pub fn decode(frame: &Frame) -> Result<Payload, PayloadError> {
        if frame.is_remote() {
            return Err(PayloadError::Remote { id: frame.id() });
        }
        Self::decode_bytes(frame.id(), frame.data())
    }
    /// Reads and checks `bytes` received under `id`.
    pub fn decode_bytes(id: Id, bytes: &[u8]) -> Result<Payload, PayloadError> {
        let len = bytes.len();
        if !(OVERHEAD..=8).contains(&len) {
            return Err(PayloadError::Length { id, len });
        }
        let (content, tail) = bytes.split_at(len - 2);
        let carried = u16::from_le_bytes([tail[0], tail[1]]);
        let computed = crc(id, content);
        if computed != carried {
            return Err(PayloadError::Crc {
                id,
                computed,
                carried,
            });
        }
        let mut data = [0u8; MAX_DATA];
        data[..content.len() - 3].copy_from_slice(&content[3..]);
        Ok(Payload {
            index: u16::from_le_bytes([content[0], content[1]]),
            sub: content[2],
            len: (content.len() - 3) as u8,
            data,
        })
    }
}

impl fmt::Debug for Payload {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "Payload({:#06x}:{} {:02x?})",
            self.index,
            self.sub,
            self.data()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const ID: Id = Id::Extended(0x0201_2341);

    #[test]
    fn the_crc_is_crc16_ibm_3740() {
        // The catalogue check value of CRC-16/IBM-3740 ("123456789" → 0x29B1), computed the
        // way this module feeds the CRC.
        assert_eq!(crc::update(CRC_INIT, b"123456789"), 0x29B1);
    }

    #[test]
    fn layout_is_index_sub_data_crc_little_endian() {
        let p = Payload::new(0x6000, 3, &[0xAA]).unwrap();
        let f = p.encode(ID);
        assert_eq!(f.dlc(), 6);
        assert_eq!(&f.data()[..4], [0x00, 0x60, 3, 0xAA]);
        let c = crc(ID, &f.data()[..4]);
        assert_eq!(&f.data()[4..], c.to_le_bytes());
        assert_eq!(Payload::decode(&f), Ok(p));
        assert_eq!(p.to_bytes(ID)[..6], f.data()[..]);
        assert_eq!(p.to_bytes(ID)[6..], [0, 0]);
        let q = Payload::empty(0x6000, 3).encode(ID);
        assert_eq!(q.dlc(), 5);
        assert_eq!(Payload::decode(&q).unwrap().data(), []);
    }

    #[test]
    fn another_identifier_fails_the_check() {
        let f = Payload::byte(0x6000, 1, 0x55).encode(ID);
        let moved = Frame::new(Id::Extended(0x0201_2342), f.data()).unwrap();
        assert!(matches!(
            Payload::decode(&moved),
            Err(PayloadError::Crc { .. })
        ));
        let standard = Frame::new(Id::Standard(0x341), f.data()).unwrap();
        assert!(Payload::decode(&standard).is_err());
    }

    #[test]
    fn malformed_input_is_an_error_value() {
        assert_eq!(
            Payload::new(1, 2, &[1, 2, 3, 4]),
            Err(PayloadError::DataTooLong { len: 4 })
        );
        let r = Frame::remote(ID, 6).unwrap();
        assert_eq!(Payload::decode(&r), Err(PayloadError::Remote { id: ID }));
        let short = Frame::new(ID, &[1, 2, 3, 4]).unwrap();
        assert_eq!(
            Payload::decode(&short),
            Err(PayloadError::Length { id: ID, len: 4 })
        );
        assert_eq!(
            Payload::decode_bytes(ID, &[0; 9]),
            Err(PayloadError::Length { id: ID, len: 9 })
        );
        let msg = Payload::decode(&short).unwrap_err().to_string();
        assert!(
            msg.contains("0x02012341x") && msg.contains("4 bytes"),
            "{msg}"
        );
    }

    #[test]
    fn stuck_frames_do_not_check() {
        for id in [ID, Id::Extended(0x0080_0010), Id::Extended(0x0200_0001)] {
            for len in OVERHEAD..=8 {
                for b in [0x00u8, 0xFF] {
                    assert!(
                        Payload::decode_bytes(id, &[b; 8][..len]).is_err(),
                        "{id} {len}×{b:#x}"
                    );
                }
            }
        }
    }

    fn payload() -> impl Strategy<Value = Payload> {
        (
            any::<u16>(),
            any::<u8>(),
            proptest::collection::vec(any::<u8>(), 0..=MAX_DATA),
        )
            .prop_map(|(i, s, d)| Payload::new(i, s, &d).unwrap())
    }

    fn ext_id() -> impl Strategy<Value = Id> {
        (0u32..=crate::frame::EXTENDED_ID_MAX).prop_map(Id::Extended)
    }

    proptest! {
        #[test]
        fn round_trip(p in payload(), id in ext_id()) {
            let f = p.encode(id);
            prop_assert_eq!(f.dlc() as usize, p.encoded_len());
            prop_assert_eq!(Payload::decode(&f), Ok(p));
        }

        /// Every single-bit error, in the identifier or anywhere in the payload, is caught.
        #[test]
        fn any_single_bit_corruption_is_detected(p in payload(), id in ext_id(), bit in 0usize..(29 + 64)) {
            let f = p.encode(id);
            let corrupted = if bit < 29 {
                Frame::new(Id::Extended(id.raw() ^ (1 << bit)), f.data()).unwrap()
            } else {
                let bit = (bit - 29) % (f.dlc() as usize * 8);
                let mut d = [0u8; 8];
                d[..f.dlc() as usize].copy_from_slice(f.data());
                d[bit / 8] ^= 1 << (bit % 8);
                Frame::new(id, &d[..f.dlc() as usize]).unwrap()
            };
            prop_assert!(Payload::decode(&corrupted).is_err());
        }

        /// Random frames never panic, and whatever decodes re-encodes to the same bytes.
        #[test]
        fn random_bytes_never_panic(raw in 0u32..=crate::frame::EXTENDED_ID_MAX, data in proptest::collection::vec(any::<u8>(), 0..=8), remote in any::<bool>()) {
            let id = Id::Extended(raw);
            let f = if remote {
                Frame::remote(id, data.len() as u8).unwrap()
            } else {
                Frame::new(id, &data).unwrap()
            };
            if let Ok(p) = Payload::decode(&f) {
                prop_assert_eq!(p.encode(id), f);
            }
            let _ = Payload::decode_bytes(id, &data);
        }
    }
}
