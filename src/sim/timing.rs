//! Wire time of classic CAN frames, exact to the bit.
//!
//! [`frame_bits`] builds the frame's real bit stream (SOF, arbitration field, control field, data,
//! CRC-15), counts the stuff bits a transmitter would insert, and adds the unstuffed trailer (CRC
//! delimiter, ACK slot, ACK delimiter, 7 EOF bits) plus the 3-bit intermission, which the bus cannot
//! use for another frame. Durations are whole microseconds, rounded up: exact for every bit rate
//! whose bit time is a whole number of microseconds (1 Mbit/s, 500, 250, 125, 100, 50, 20,
//! 10 kbit/s), and never optimistic for the others.
//!
//! CAN FD frames ([`fd_frame_bits`], [`fd_frame_duration`]) run in two phases: the arbitration
//! phase at the nominal bit rate and, when BRS is set, the data phase at the data bit rate.
//! What is counted, as ISO 11898-1:2015 lays out the FD formats:
//!
//! - exactly: the bits from SOF to the end of the data field (base format: SOF, 11 identifier
//!   bits, RRS, IDE, FDF, res, BRS, ESI, 4 DLC bits; extended format: SOF, 11 base bits, SRR,
//!   IDE, 18 extension bits, RRS, FDF, res, BRS, ESI, DLC) and the dynamic stuff bits a
//!   transmitter inserts there (one after five equal bits, the stuff bit starting the next
//!   run, including one that falls due after the last data bit); the 4-bit stuff count (the
//!   number of dynamic stuff bits modulo 8, gray-coded, plus a parity bit); the CRC sequence,
//!   CRC-17 for up to 16 data bytes and CRC-21 above; the fixed stuff bits of the CRC field
//!   (one before the stuff count and one after every four bits of stuff count and CRC: 6 with
//!   CRC-17, 7 with CRC-21); the unstuffed trailer (CRC delimiter, ACK slot, ACK delimiter, 7
//!   EOF bits) and the 3-bit intermission. None of these depends on the CRC's value, so no CRC
//!   is computed.
//! - bounded: where the bit rate switches. A controller switches at the sample point of the
//!   BRS bit and back at the sample point of the CRC delimiter; here the BRS bit and the CRC
//!   delimiter count whole at the nominal rate, and ESI to the last CRC bit (with their stuff
//!   bits) at the data rate. With a data rate at least the nominal one this is never
//!   optimistic, and too long by less than two data bits. Transceiver delay compensation and
//!   the secondary sample point do not change the bit count and are not modelled.

use crate::frame::instant::Duration;
use crate::frame::{FdFrame, Frame, Id};

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

/// The bits of a CAN FD frame in each phase (see the module documentation for what is counted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FdBits {
    /// Bits at the nominal bit rate: SOF to BRS with their stuff bits, CRC delimiter to the
    /// end of the intermission; every bit when BRS is off.
    pub nominal: u32,
    /// Bits at the data bit rate: ESI to the end of the CRC field, stuff bits included; 0 when
    /// BRS is off.
    pub data: u32,
}

impl FdBits {
    /// Bits in all.
    pub const fn total(self) -> u32 {
        self.nominal + self.data
    }
}

/// A run-length stuff counter over a bit stream fed a field at a time (an FD frame's 553
/// bits up to the CRC field do not fit the classic path's 128-bit stream).
#[derive(Default)]
struct Stuffer {
    last: Option<bool>,
    run: u32,
    count: u32,
}

impl Stuffer {
    /// Feeds the `n` low bits of `value`, most significant first.
    fn push(&mut self, value: u64, n: u32) {
        for i in (0..n).rev() {
            let bit = (value >> i) & 1 == 1;
            if self.last == Some(bit) {
                self.run += 1;
            } else {
                self.last = Some(bit);
                self.run = 1;
            }
            if self.run == 5 {
                self.count += 1;
                self.last = Some(!bit);
                self.run = 1;
            }
        }
    }
}

/// The CRC length of an FD frame with `len` data bytes: CRC-17 up to 16 bytes, CRC-21 above.
pub const fn fd_crc_bits(len: usize) -> u32 {
    if len <= 16 {
        17
    } else {
        21
    }
}

/// Fixed stuff bits of an FD CRC field: one before the stuff count and one after every four
/// bits of the stuff count (4) and the CRC.
pub const fn fd_fixed_stuff_bits(len: usize) -> u32 {
    1 + (4 + fd_crc_bits(len)) / 4
}

/// The header bits of an FD frame up to and including BRS, and those after it up to the DLC
/// (ESI, DLC): both unstuffed.
const fn fd_header_bits(extended: bool) -> (u32, u32) {
    if extended {
        (36, 5)
    } else {
        (17, 5)
    }
}

/// The bits of `frame` without any dynamic stuff bit: the lower bound of [`fd_frame_bits`].
pub fn fd_unstuffed_bits(frame: &FdFrame) -> u32 {
    let (arb, ctl) = fd_header_bits(frame.id().is_extended());
    let n = frame.len() as u32;
    arb + ctl
        + 8 * n
        + 4
        + fd_crc_bits(frame.len())
        + fd_fixed_stuff_bits(frame.len())
        + TRAILER_BITS
        + INTERMISSION_BITS
}

/// The most dynamic stuff bits an FD frame of this format and length can have: the first after
/// five bits, then one after every four (each stuff bit starts the next run).
pub fn fd_worst_case_stuff_bits(extended: bool, len: usize) -> u32 {
    let (arb, ctl) = fd_header_bits(extended);
    let region = arb + ctl + 8 * (len.min(64) as u32);
    (region - 1) / 4
}

/// Bits `frame` occupies the bus for, in each phase, intermission included.
pub fn fd_frame_bits(frame: &FdFrame) -> FdBits {
    let mut s = Stuffer::default();
    s.push(0, 1); // SOF
    match frame.id() {
        Id::Standard(id) => {
            s.push(u64::from(id), 11);
            s.push(0, 1); // RRS: dominant
            s.push(0, 1); // IDE: dominant for a base frame
        }
        Id::Extended(id) => {
            s.push(u64::from(id >> 18), 11);
            s.push(1, 1); // SRR: recessive
            s.push(1, 1); // IDE: recessive
            s.push(u64::from(id & 0x3_FFFF), 18);
            s.push(0, 1); // RRS: dominant
        }
    }
    s.push(1, 1); // FDF: recessive, an FD frame
    s.push(0, 1); // res: dominant
    s.push(u64::from(frame.brs()), 1);
    let arbitration_stuff = s.count;
    s.push(u64::from(frame.esi()), 1);
    s.push(u64::from(frame.dlc()), 4);
    for &b in frame.data() {
        s.push(u64::from(b), 8);
    }
    let data_stuff = s.count - arbitration_stuff;
    let (arb, ctl) = fd_header_bits(frame.id().is_extended());
    let fast = ctl
        + 8 * frame.len() as u32
        + data_stuff
        + 4
        + fd_crc_bits(frame.len())
        + fd_fixed_stuff_bits(frame.len());
    let slow = arb + arbitration_stuff + TRAILER_BITS + INTERMISSION_BITS;
    if frame.brs() {
        FdBits {
            nominal: slow,
            data: fast,
        }
    } else {
        FdBits {
            nominal: slow + fast,
            data: 0,
        }
    }
}

/// How long `frame` occupies a bus at `nominal` bit/s with a data phase at `data` bit/s (used
/// only when BRS is set), intermission included; rounded up to whole microseconds. A bit rate
/// of 0 is treated as 1 bit/s rather than dividing by zero.
pub fn fd_frame_duration(frame: &FdFrame, nominal: u32, data: u32) -> Duration {
    let bits = fd_frame_bits(frame);
    let n = u128::from(nominal.max(1));
    let d = u128::from(data.max(1));
    // nominal_bits / n + data_bits / d seconds, over the common denominator n·d, exact.
    let num = (u128::from(bits.nominal) * d + u128::from(bits.data) * n) * 1_000_000;
    let micros = num.div_ceil(n * d);
    Duration::from_micros(u64::try_from(micros).unwrap_or(u64::MAX))
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

    fn fd(id: Id, data: &[u8], brs: bool) -> FdFrame {
        FdFrame::new(id, data).unwrap().with_brs(brs)
    }

    #[test]
    fn fd_fixed_fields_follow_the_crc_length() {
        assert_eq!((fd_crc_bits(16), fd_fixed_stuff_bits(16)), (17, 6));
        assert_eq!((fd_crc_bits(20), fd_fixed_stuff_bits(20)), (21, 7));
        assert_eq!((fd_crc_bits(0), fd_fixed_stuff_bits(64)), (17, 7));
    }

    /// 0x555 and 0x55 bytes alternate: no run of five, no dynamic stuff bit. By hand: SOF, 11
    /// identifier bits, RRS, IDE, FDF, res, BRS = 17 nominal bits, plus CRC delimiter, ACK,
    /// ACK delimiter, EOF and intermission = 13; ESI, DLC (4), 512 data bits, stuff count (4),
    /// CRC-21 and 7 fixed stuff bits = 549 data-phase bits. At 1/5 Mbit/s: 30 µs + 109.8 µs.
    #[test]
    fn fd_64_bytes_at_1_and_5_mbit_by_hand() {
        let f = fd(Id::Standard(0x555), &[0x55; 64], true);
        assert_eq!(f.dlc(), 15);
        assert_eq!(
            fd_frame_bits(&f),
            FdBits {
                nominal: 30,
                data: 549
            }
        );
        assert_eq!(
            fd_frame_duration(&f, 1_000_000, 5_000_000),
            Duration::from_micros(140)
        );
        // Without BRS every bit is at the nominal rate; the BRS bit (now dominant) makes no run.
        let slow = f.with_brs(false);
        assert_eq!(
            fd_frame_bits(&slow),
            FdBits {
                nominal: 579,
                data: 0
            }
        );
        assert_eq!(
            fd_frame_duration(&slow, 1_000_000, 5_000_000),
            Duration::from_micros(579)
        );
        assert_eq!(fd_unstuffed_bits(&f), 579);
    }

    /// Identifier 0 and 64 zero bytes: SOF, identifier, RRS and IDE are 14 dominant bits (stuff
    /// bits after the 5th and 10th), then FDF 1, res 0, BRS 1, ESI 0, DLC 1111, and 512 zeros
    /// (a stuff bit after every five: 102). Nominal 17 + 2 + 13 = 32, data 549 + 102 = 651:
    /// 32 µs + 130.2 µs at 1/5 Mbit/s.
    #[test]
    fn fd_64_zero_bytes_at_1_and_5_mbit_by_hand() {
        let f = fd(Id::Standard(0), &[0; 64], true);
        assert_eq!(
            fd_frame_bits(&f),
            FdBits {
                nominal: 32,
                data: 651
            }
        );
        assert_eq!(
            fd_frame_duration(&f, 1_000_000, 5_000_000),
            Duration::from_micros(163)
        );
        assert_eq!(
            fd_frame_duration(&f, 1_000_000, 2_000_000),
            Duration::from_micros(358)
        );
    }

    /// 8 bytes of 0x55 behind 0x555 (DLC 1000, no run of five): CRC-17 and 6 fixed stuff
    /// bits; 20 bytes: CRC-21 and 7.
    #[test]
    fn fd_short_frames_use_crc17() {
        let f = fd(Id::Standard(0x555), &[0x55; 8], true);
        // 17 + 13 nominal; ESI + DLC 5 + 64 + 4 + 17 + 6 = 96 data.
        assert_eq!(
            fd_frame_bits(&f),
            FdBits {
                nominal: 30,
                data: 96
            }
        );
        let g = fd(Id::Standard(0x555), &[0x55; 20], false);
        // 17 + 13 + 5 + 160 + 4 + 21 + 7.
        assert_eq!(fd_frame_bits(&g).total(), 227);
    }

    #[test]
    fn fd_classic_length_frames_are_not_classic_frames_on_the_wire() {
        // The same 8 bytes take a different number of bits in FD format (stuff count, CRC-17
        // with fixed stuff bits) than in classic format.
        let c = std_frame(0x555, &[0x55; 8]);
        let f = FdFrame::try_from(c).unwrap();
        assert_ne!(fd_frame_bits(&f).total(), frame_bits(&c));
    }

    proptest! {
        #[test]
        fn fd_length_is_between_unstuffed_and_worst_case(f in crate::frame::arbitrary::any_fd_frame()) {
            let bits = fd_frame_bits(&f);
            let lo = fd_unstuffed_bits(&f);
            let hi = lo + fd_worst_case_stuff_bits(f.id().is_extended(), f.len());
            prop_assert!(bits.total() >= lo, "{} < {}", bits.total(), lo);
            prop_assert!(bits.total() <= hi, "{} > {}", bits.total(), hi);
            prop_assert_eq!(bits.data == 0, !f.brs());
            // The data phase at the nominal rate takes as long as no switch at all.
            prop_assert_eq!(
                fd_frame_duration(&f, 500_000, 500_000),
                bits_duration(bits.total(), 500_000)
            );
            // A faster data phase never makes the frame longer.
            prop_assert!(fd_frame_duration(&f, 500_000, 2_000_000) <= fd_frame_duration(&f, 500_000, 500_000));
        }
    }
}
