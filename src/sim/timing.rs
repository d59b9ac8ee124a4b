//! Wire time of classic CAN frames, exact to the bit.
//!
//! [`frame_bits`] builds the frame's real bit stream (SOF, arbitration field, control field, data,
//! CRC-15), counts the stuff bits a transmitter would insert, and adds the unstuffed trailer (CRC
//! delimiter, ACK slot, ACK delimiter, 7 EOF bits) plus the 3-bit intermission, which the bus cannot
//! use for another frame. Durations are whole microseconds, rounded up: exact for every bit rate
//! whose bit time is a whole number of microseconds (1 Mbit/s, 500, 250, 125, 100, 50, 20,
//! 10 kbit/s), and never optimistic for the others.

use crate::frame::instant::Duration;
use crate::frame::{Frame, Id};

/// CRC delimiter, ACK slot, ACK delimiter and end of frame: never stuffed.
const TRAILER_BITS: u32 = 3 + 7;
/// Bits of interframe space after every frame; counted as bus occupancy.
pub const INTERMISSION_BITS: u32 = 3;
/// The CAN CRC-15 generator polynomial (x^15 + x^14 + x^10 + x^8 + x^7 + x^4 + x^3 + 1).
pub const CRC15_POLY: u16 = 0x4599;

/// A bit stream of at most 128 bits, first bit most significant: the longest stuffed region
/// (extended, 8 bytes) is 118 bits, so nothing on the frame path allocates.
#[derive(Clone, Copy, Default)]
struct Bits {
    bits: u128,
    len: u32,
}

impl Bits {
    fn push(&mut self, value: u64, n: u32) {
        let mask = if n == 64 { u64::MAX } else { (1u64 << n) - 1 };
        self.bits = (self.bits << n) | u128::from(value & mask);
        self.len += n;
    }
    fn iter(self) -> impl Iterator<Item = bool> {
        (0..self.len).rev().map(move |i| (self.bits >> i) & 1 == 1)
    }
}

/// CRC-15/CAN over a bit sequence, as the transmitter computes it over SOF..data.
fn crc15_bits(bits: impl Iterator<Item = bool>) -> u16 {
    let mut crc: u16 = 0;
    for bit in bits {
        let feedback = bit ^ (crc & 0x4000 != 0);
        crc = (crc << 1) & 0x7FFF;
        if feedback {
            crc ^= CRC15_POLY;
        }
    }
    crc
}

/// CRC-15/CAN of a byte string (most significant bit first): the catalogue check value of
/// `b"123456789"` is `0x059E`.
pub fn crc15(bytes: &[u8]) -> u16 {
    crc15_bits(
        bytes
            .iter()
            .flat_map(|b| (0..8).rev().map(move |i| (b >> i) & 1 == 1)),
    )
}

/// The frame from SOF to the end of the CRC sequence, before stuffing.
fn stuffed_region(frame: &Frame) -> Bits {
    let mut s = Bits::default();
    let rtr = u64::from(frame.is_remote());
    s.push(0, 1); // SOF
    match frame.id() {
        Id::Standard(id) => {
            s.push(u64::from(id), 11);
            s.push(rtr, 1);
            s.push(0, 1); // IDE: dominant for a base frame
            s.push(0, 1); // r0
        }
        Id::Extended(id) => {
            s.push(u64::from(id >> 18), 11);
            s.push(1, 1); // SRR: recessive
            s.push(1, 1); // IDE: recessive
            s.push(u64::from(id & 0x3_FFFF), 18);
            s.push(rtr, 1);
            s.push(0, 2); // r1, r0
        }
    }
    s.push(u64::from(frame.dlc()), 4);
    for &b in frame.data() {
        s.push(u64::from(b), 8);
    }
    let crc = crc15_bits(s.iter());
    s.push(u64::from(crc), 15);
    s
}

/// Stuff bits a transmitter inserts: one after every five equal bits, and the stuff bit itself
/// starts the next run (so five zeros, stuff one, four zeros and a one make no second stuff bit).
fn stuff_bits(region: Bits) -> u32 {
    let mut count = 0;
    let mut last = None;
    let mut run = 0;
    for bit in region.iter() {
        if last == Some(bit) {
            run += 1;
        } else {
            last = Some(bit);
            run = 1;
        }
        if run == 5 {
            count += 1;
            last = Some(!bit);
            run = 1;
        }
    }
    count
}

/// Bits the frame occupies the bus for: stuffed SOF..CRC, the fixed trailer and the intermission.
pub fn frame_bits(frame: &Frame) -> u32 {
    let region = stuffed_region(frame);
    region.len + stuff_bits(region) + TRAILER_BITS + INTERMISSION_BITS
}

/// Bits an attempt destroyed by a detected error occupies the bus for.
///
/// Modelled as a CRC error: receivers flag it after the ACK delimiter, so the frame runs to there,
/// then a 6-bit error flag, an 8-bit error delimiter and the intermission follow. That is
/// [`frame_bits`] minus EOF (7) plus 6 + 8, i.e. 7 bits more than a good frame.
pub fn error_frame_bits(frame: &Frame) -> u32 {
    frame_bits(frame) + 7
}

/// The classic worst case (every stuff bit that can occur does), including the intermission:
/// `8n + 47 + ⌊(34 + 8n − 1)/4⌋` for base frames and `8n + 67 + ⌊(54 + 8n − 1)/4⌋` for extended
/// ones, with `n` data bytes (0 for remote frames).
pub fn worst_case_bits(extended: bool, data_len: u8) -> u32 {
    let n = u32::from(data_len.min(8));
    let (g, fixed) = if extended { (54, 67) } else { (34, 47) };
    8 * n + fixed + (g + 8 * n - 1) / 4
}

/// Time `bits` take at `bitrate` bit/s, rounded up to whole microseconds. A bit rate of 0 is
/// treated as 1 bit/s rather than dividing by zero.
pub fn bits_duration(bits: u32, bitrate: u32) -> Duration {
    let rate = u64::from(bitrate.max(1));
    Duration::from_micros((u64::from(bits) * 1_000_000).div_ceil(rate))
}

/// How long `frame` occupies a bus running at `bitrate` bit/s, intermission included.
pub fn frame_duration(frame: &Frame, bitrate: u32) -> Duration {
    bits_duration(frame_bits(frame), bitrate)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::arbitrary::any_frame;
    use proptest::prelude::*;

    fn std_frame(id: u16, data: &[u8]) -> Frame {
        Frame::new(Id::Standard(id), data).unwrap()
    }

    #[test]
    fn crc15_matches_the_catalogue_check_value() {
        assert_eq!(crc15(b"123456789"), 0x059E);
    }

    #[test]
    fn id_zero_dlc_zero_is_34_zero_bits_with_six_stuff_bits() {
        // SOF, id, RTR, IDE, r0, DLC are 19 dominant bits and the CRC of all zeros is zero, so
        // the region is 34 zeros: a stuff bit after every fifth one, 6 in all.
        let f = std_frame(0, &[]);
        assert_eq!(stuff_bits(stuffed_region(&f)), 6);
        assert_eq!(frame_bits(&f), 34 + 6 + 10 + 3);
    }

    /// Values checked against an independent implementation (bit list in Python, written from
    /// ISO 11898-1), and the unstuffed lengths by hand: 19 + 8n + 15 (base), 39 + 8n + 15 (ext).
    #[test]
    fn known_frames_have_exact_lengths() {
        let cases = [
            (std_frame(0x000, &[]), 53),
            (std_frame(0x7FF, &[]), 50),
            (
                std_frame(0x123, &[0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77, 0x88]),
                112,
            ),
            (std_frame(0x701, &[0x05]), 58),
            (std_frame(0x000, &[0; 8]), 127),
            (std_frame(0x7FF, &[0xFF; 8]), 126),
            (
                Frame::new(Id::Extended(0x1234_5678), &[0xAA, 0x55]).unwrap(),
                84,
            ),
            (Frame::remote(Id::Standard(0x701), 1).unwrap(), 51),
            (Frame::remote(Id::Extended(0x1FFF_FFFF), 0).unwrap(), 74),
        ];
        for (f, bits) in cases {
            assert_eq!(frame_bits(&f), bits, "{f}");
        }
    }

    #[test]
    fn durations_round_up_to_whole_microseconds() {
        let f = std_frame(0, &[]);
        assert_eq!(frame_duration(&f, 1_000_000), Duration::from_micros(53));
        assert_eq!(frame_duration(&f, 500_000), Duration::from_micros(106));
        assert_eq!(frame_duration(&f, 125_000), Duration::from_micros(424));
        // 53 bits at 800 kbit/s are 66.25 µs.
        assert_eq!(frame_duration(&f, 800_000), Duration::from_micros(67));
        assert_eq!(bits_duration(1, 0), Duration::from_secs(1));
    }

    #[test]
    fn worst_case_formula_matches_the_classic_numbers() {
        assert_eq!(worst_case_bits(false, 8), 135);
        assert_eq!(worst_case_bits(false, 0), 55);
        assert_eq!(worst_case_bits(true, 8), 160);
    }

    proptest! {
        #[test]
        fn length_is_between_unstuffed_and_worst_case(f in any_frame()) {
            let n = if f.is_remote() { 0 } else { f.dlc() };
            let unstuffed = 8 * u32::from(n) + if f.id().is_extended() { 67 } else { 47 };
            let bits = frame_bits(&f);
            prop_assert!(bits >= unstuffed);
            prop_assert!(bits <= worst_case_bits(f.id().is_extended(), n));
            prop_assert_eq!(error_frame_bits(&f), bits + 7);
        }
    }
}
