//! CAN FD frames (ISO 11898-1:2015 FD format): up to 64 data bytes, the BRS and ESI flags.
//!
//! An [`FdFrame`] is a value type of its own beside the classic [`Frame`], so the classic
//! path (queues, the merger, the node) keeps its 16-byte frames and its code untouched: FD
//! costs nothing where it is not used.
//!
//! A CAN FD data field has 0 to 8 bytes, or 12, 16, 20, 24, 32, 48 or 64 ([`FD_LENGTHS`]): the
//! 4-bit DLC names one of these 16 lengths ([`len_for_dlc`], [`dlc_for_len`]). A payload of
//! another length is sent in the next longer frame, the gap filled with a padding byte
//! ([`FdFrame::padded`], [`padded_len`]): ISO 11898-1 leaves the fill value to the sender
//! (CiA 1301 asks for 0xCC in padding, but a caller chooses). CAN FD has no remote frames.
//!
//! ```
//! use duocan_core::frame::fd::{dlc_for_len, len_for_dlc, padded_len, FdFrame, FdFrameError};
//! use duocan_core::frame::FrameError;
//! use duocan_core::{Frame, Id};
//!
//! let f = FdFrame::new(Id::Standard(0x185), &[7; 12])?.with_brs(true);
//! assert_eq!((f.len(), f.dlc(), f.brs(), f.esi()), (12, 9, true, false));
//! assert_eq!((len_for_dlc(15), dlc_for_len(48), padded_len(13)), (Some(64), Some(14), Some(16)));
//! // 13 bytes are no CAN FD length: an error naming it, or padding up to 16.
//! assert_eq!(FdFrame::new(f.id(), &[1; 13]), Err(FdFrameError::NotFdLength { len: 13 }));
//! let p = FdFrame::padded(f.id(), &[1; 13], 0xCC)?;
//! assert_eq!((p.len(), p.data()[12], p.data()[13]), (16, 1, 0xCC));
//! // At most 8 bytes go back to a classic frame; 12 do not.
//! assert_eq!(Frame::try_from(&f), Err(FrameError::TooLong { len: 12 }));
//! # Ok::<(), FdFrameError>(())
//! ```

use super::{pack, unpack, Frame, FrameError, Id};
use core::fmt;

/// The payload lengths a CAN FD frame can have, indexed by DLC.
pub const FD_LENGTHS: [u8; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];
/// Most data bytes a CAN FD frame carries.
pub const FD_MAX_LEN: usize = 64;
/// The bit rate switch flag, as SocketCAN's `CANFD_BRS`: the data phase runs at the data bit
/// rate.
pub const BRS: u8 = 0x01;
/// The error state indicator flag, as SocketCAN's `CANFD_ESI`: the sender is error passive.
pub const ESI: u8 = 0x02;

/// Why a CAN FD frame could not be built. Its own type, not [`FrameError`]: the classic
/// path's error (and the code that formats and compares it) stays as it was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FdFrameError {
    /// More than 64 data bytes.
    TooLong {
        /// The length that was asked for.
        len: usize,
    },
    /// A payload of a length between the CAN FD steps (9–11, 13–15, …): a CAN FD frame holds
    /// 0–8, 12, 16, 20, 24, 32, 48 or 64 bytes ([`FdFrame::padded`] rounds up).
    NotFdLength {
        /// The length that was asked for.
        len: usize,
    },
    /// A remote frame asked for in CAN FD, which has none.
    Remote,
}

impl fmt::Display for FdFrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FdFrameError::TooLong { len } => {
                write!(f, "CAN FD frame of {len} bytes: CAN FD carries at most 64")
            }
            FdFrameError::NotFdLength { len } => write!(
                f,
                "CAN FD payload of {len} bytes: a CAN FD frame holds 0–8, 12, 16, 20, 24, 32, 48 or 64"
            ),
            FdFrameError::Remote => f.write_str("CAN FD has no remote frames"),
        }
    }
}

impl core::error::Error for FdFrameError {}

/// The payload length a DLC stands for in a CAN FD frame; `None` above 15.
pub const fn len_for_dlc(dlc: u8) -> Option<usize> {
    if dlc < 16 {
        Some(FD_LENGTHS[dlc as usize] as usize)
    } else {
        None
    }
}

/// The DLC of a CAN FD payload of exactly `len` bytes; `None` for a length that is not one of
/// [`FD_LENGTHS`] (see [`padded_len`]).
pub const fn dlc_for_len(len: usize) -> Option<u8> {
    let mut dlc = 0;
    while dlc < 16 {
        if FD_LENGTHS[dlc] as usize == len {
            return Some(dlc as u8);
        }
        dlc += 1;
    }
    None
}

/// The shortest CAN FD length that holds `len` bytes; `None` above 64.
pub const fn padded_len(len: usize) -> Option<usize> {
    let mut dlc = 0;
    while dlc < 16 {
        if FD_LENGTHS[dlc] as usize >= len {
            return Some(FD_LENGTHS[dlc] as usize);
        }
        dlc += 1;
    }
    None
}

/// One CAN FD data frame (FD base or extended format).
///
/// Bytes beyond the length are always zero, so frames equal on the wire compare and hash
/// equal, as classic frames do.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct FdFrame {
    /// The identifier, packed as in [`Frame`].
    id: u32,
    /// [`BRS`] and [`ESI`]; no other bit is ever set.
    flags: u8,
    /// One of [`FD_LENGTHS`].
    len: u8,
    data: [u8; FD_MAX_LEN],
}

impl FdFrame {
    /// A data frame with BRS and ESI off. Fails for more than 64 bytes
    /// ([`FdFrameError::TooLong`]) or a length between the CAN FD steps
    /// ([`FdFrameError::NotFdLength`]: pad it with [`FdFrame::padded`]).
    pub fn new(id: Id, data: &[u8]) -> Result<FdFrame, FdFrameError> {
        if data.len() > FD_MAX_LEN {
            return Err(FdFrameError::TooLong { len: data.len() });
        }
        if dlc_for_len(data.len()).is_none() {
            return Err(FdFrameError::NotFdLength { len: data.len() });
        }
        Ok(Self::fill(id, data, data.len(), 0))
    }

    /// A data frame of the shortest CAN FD length that holds `data`, the bytes after it set to
    /// `fill`. Fails only for more than 64 bytes.
    pub fn padded(id: Id, data: &[u8], fill: u8) -> Result<FdFrame, FdFrameError> {
        let len = padded_len(data.len()).ok_or(FdFrameError::TooLong { len: data.len() })?;
        Ok(Self::fill(id, data, len, fill))
    }

    /// `data` then `fill` up to `len`; the caller has checked both lengths.
    fn fill(id: Id, data: &[u8], len: usize, fill: u8) -> FdFrame {
        let mut buf = [0u8; FD_MAX_LEN];
        buf[..data.len()].copy_from_slice(data);
        for b in &mut buf[data.len()..len] {
            *b = fill;
        }
        FdFrame {
            id: pack(id),
            flags: 0,
            len: len as u8,
            data: buf,
        }
    }

    /// The same frame with the bit rate switch set or cleared.
    #[must_use]
    pub const fn with_brs(mut self, on: bool) -> FdFrame {
        self.flags = if on {
            self.flags | BRS
        } else {
            self.flags & !BRS
        };
        self
    }

    /// The same frame with the error state indicator set (sender error passive) or cleared.
    #[must_use]
    pub const fn with_esi(mut self, on: bool) -> FdFrame {
        self.flags = if on {
            self.flags | ESI
        } else {
            self.flags & !ESI
        };
        self
    }

    /// The same frame with the flags of a SocketCAN `canfd_frame` flags byte: [`BRS`] and
    /// [`ESI`] are taken, other bits (`CANFD_FDF` among them) ignored.
    #[must_use]
    pub const fn with_flags(mut self, flags: u8) -> FdFrame {
        self.flags = flags & (BRS | ESI);
        self
    }

    /// The identifier.
    pub const fn id(&self) -> Id {
        unpack(self.id)
    }
    /// True when the data phase runs at the data bit rate.
    pub const fn brs(&self) -> bool {
        self.flags & BRS != 0
    }
    /// True when the sender was error passive.
    pub const fn esi(&self) -> bool {
        self.flags & ESI != 0
    }
    /// [`BRS`] and [`ESI`] as SocketCAN's flags byte holds them (without `CANFD_FDF`).
    pub const fn flags(&self) -> u8 {
        self.flags
    }
    /// Data length code, 0–15.
    pub const fn dlc(&self) -> u8 {
        match dlc_for_len(self.len as usize) {
            Some(d) => d,
            // Unreachable: every constructor keeps `len` in FD_LENGTHS.
            None => 15,
        }
    }
    /// Payload length in bytes, one of [`FD_LENGTHS`].
    pub const fn len(&self) -> usize {
        self.len as usize
    }
    /// True for a frame without data bytes.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The payload.
    pub fn data(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }
    /// Priority key for bus arbitration: lower wins. An FD frame's RRS bit is dominant like a
    /// classic data frame's RTR bit, so it arbitrates as a data frame of its identifier.
    pub const fn arbitration_key(&self) -> u64 {
        self.id().arbitration_key(false)
    }
}

/// A classic data frame as an FD frame with the same identifier and bytes, BRS and ESI off.
///
/// Not the same thing on the wire: the result is sent in FD format (FDF recessive, a CRC-17
/// and a stuff count), which a classic-only node answers with error frames. CAN FD has no
/// remote frames, so a remote frame is [`FdFrameError::Remote`].
impl TryFrom<Frame> for FdFrame {
    type Error = FdFrameError;
    fn try_from(f: Frame) -> Result<FdFrame, FdFrameError> {
        if f.is_remote() {
            return Err(FdFrameError::Remote);
        }
        // 0–8 bytes are all CAN FD lengths.
        Ok(FdFrame::fill(f.id(), f.data(), f.data().len(), 0))
    }
}

/// The classic frame with the same identifier and bytes: only for at most 8 bytes
/// ([`FrameError::TooLong`] otherwise). BRS and ESI are dropped; a classic frame has neither.
impl TryFrom<&FdFrame> for Frame {
    type Error = FrameError;
    fn try_from(f: &FdFrame) -> Result<Frame, FrameError> {
        Frame::new(f.id(), f.data())
    }
}

impl fmt::Debug for FdFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// Like a classic frame's text, marked FD: `0x185 [12] FD BRS 07 07 …`.
impl fmt::Display for FdFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} [{}] FD", self.id(), self.len)?;
        if self.brs() {
            f.write_str(" BRS")?;
        }
        if self.esi() {
            f.write_str(" ESI")?;
        }
        for b in self.data() {
            write!(f, " {b:02X}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::arbitrary::{any_fd_frame, any_frame};
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn classic_frame_stays_16_bytes() {
        assert_eq!(core::mem::size_of::<Frame>(), 16);
        assert!(core::mem::size_of::<FdFrame>() <= 72);
    }

    #[test]
    fn dlc_table_is_iso_11898_1() {
        let lens: [usize; 16] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64];
        for (dlc, len) in lens.into_iter().enumerate() {
            assert_eq!(len_for_dlc(dlc as u8), Some(len));
            assert_eq!(dlc_for_len(len), Some(dlc as u8));
        }
        assert_eq!(len_for_dlc(16), None);
        assert_eq!(dlc_for_len(9), None);
        assert_eq!(dlc_for_len(65), None);
        assert_eq!(padded_len(9), Some(12));
        assert_eq!(padded_len(49), Some(64));
        assert_eq!(padded_len(65), None);
    }

    #[test]
    fn bad_lengths_are_errors_naming_the_length() {
        let id = Id::Standard(0x100);
        assert_eq!(
            FdFrame::new(id, &[0; 65]),
            Err(FdFrameError::TooLong { len: 65 })
        );
        assert_eq!(
            FdFrame::new(id, &[0; 33]),
            Err(FdFrameError::NotFdLength { len: 33 })
        );
        assert_eq!(
            FdFrame::padded(id, &[0; 65], 0),
            Err(FdFrameError::TooLong { len: 65 })
        );
        let e = FdFrameError::NotFdLength { len: 33 };
        assert!(e.to_string().contains("33"));
    }

    #[test]
    fn flags_and_text() {
        let f = FdFrame::new(Id::Extended(0x1234_5678), &[1, 2])
            .unwrap()
            .with_brs(true)
            .with_esi(true);
        assert_eq!(f.flags(), BRS | ESI);
        assert_eq!(f.to_string(), "0x12345678x [2] FD BRS ESI 01 02");
        assert_eq!(f.with_flags(0x04).flags(), 0);
        assert_eq!(f.with_brs(false).flags(), ESI);
        assert_eq!(
            f.arbitration_key(),
            Id::Extended(0x1234_5678).arbitration_key(false)
        );
    }

    #[test]
    fn remote_frames_have_no_fd_form() {
        let r = Frame::remote(Id::Standard(0x701), 1).unwrap();
        assert_eq!(FdFrame::try_from(r), Err(FdFrameError::Remote));
    }

    proptest! {
        #[test]
        fn dlc_round_trip(dlc in 0u8..16) {
            let len = len_for_dlc(dlc).unwrap();
            prop_assert_eq!(dlc_for_len(len), Some(dlc));
            prop_assert_eq!(padded_len(len), Some(len));
        }

        #[test]
        fn padding_is_the_shortest_length_that_holds(len in 0usize..=64, fill in any::<u8>()) {
            let p = padded_len(len).unwrap();
            prop_assert!(p >= len && dlc_for_len(p).is_some());
            prop_assert!(FD_LENGTHS.iter().all(|&l| usize::from(l) < len || usize::from(l) >= p));
            let data: std::vec::Vec<u8> = (0..len).map(|i| i as u8).collect();
            let f = FdFrame::padded(Id::Standard(1), &data, fill).unwrap();
            prop_assert_eq!(&f.data()[..len], &data[..]);
            prop_assert!(f.data()[len..].iter().all(|&b| b == fill));
            prop_assert_eq!(f.len(), p);
            prop_assert_eq!(len_for_dlc(f.dlc()), Some(p));
        }

        #[test]
        fn new_accepts_exactly_the_fd_lengths(len in 0usize..=80) {
            let r = FdFrame::new(Id::Standard(1), &std::vec![0xA5; len]);
            match (len > 64, dlc_for_len(len)) {
                (true, _) => prop_assert_eq!(r, Err(FdFrameError::TooLong { len })),
                (false, None) => prop_assert_eq!(r, Err(FdFrameError::NotFdLength { len })),
                (false, Some(dlc)) => prop_assert_eq!(r.map(|f| f.dlc()), Ok(dlc)),
            }
        }

        #[test]
        fn any_fd_frame_is_consistent(f in any_fd_frame()) {
            prop_assert_eq!(len_for_dlc(f.dlc()), Some(f.len()));
            prop_assert_eq!(f.flags() & !(BRS | ESI), 0);
            let again = FdFrame::new(f.id(), f.data()).unwrap().with_flags(f.flags());
            prop_assert_eq!(again, f);
            match Frame::try_from(&f) {
                Ok(c) => {
                    prop_assert!(f.len() <= 8);
                    prop_assert_eq!(c.data(), f.data());
                    prop_assert_eq!(FdFrame::try_from(c).map(|x| x.with_flags(f.flags())), Ok(f));
                }
                Err(e) => prop_assert_eq!(e, FrameError::TooLong { len: f.len() }),
            }
        }

        #[test]
        fn classic_data_frames_round_trip_through_fd(c in any_frame()) {
            match FdFrame::try_from(c) {
                Ok(f) => {
                    prop_assert!(!f.brs() && !f.esi());
                    prop_assert_eq!(Frame::try_from(&f), Ok(c));
                }
                Err(e) => {
                    prop_assert!(c.is_remote());
                    prop_assert_eq!(e, FdFrameError::Remote);
                }
            }
        }
    }
}
