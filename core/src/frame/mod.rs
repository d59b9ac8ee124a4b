//! CAN frames: classic (2.0A and 2.0B, data and remote, DLC 0–8) and CAN FD (`fd`).
//!
//! A classic [`Frame`] is a 16-byte value type. Bytes beyond the DLC are always zero, so two
//! frames that are equal on the wire compare equal and hash equal: the dual-bus merger relies
//! on that.
//!
//! A CAN FD frame is an `FdFrame` of its own (module `fd`, feature `fd`, on with `std`): up to
//! 64 bytes of the CAN FD lengths, the BRS and ESI flags, no remote frames, its own error type
//! (`fd::FdFrameError`). The classic path keeps its size, its code and [`FrameError`], and an
//! image built without the feature is the same as before it. A classic data frame converts to
//! an FD one (`FdFrame::try_from`) and an FD frame of at most 8 bytes back (`Frame::try_from`).
//!
//! ```
//! use duocan_core::frame::cob_id::predefined::{self, Function};
//! use duocan_core::frame::FrameError;
//! use duocan_core::{CobId, Frame, Id, NodeId};
//!
//! // TPDO1 of node 5 in the predefined connection set, as 0x1800 sub 1 would hold it.
//! let node = NodeId::must(5);
//! let cob = CobId::from_id(predefined::tpdo(1, node));
//! assert_eq!(cob.can_id(), Some(Id::Standard(0x185)));
//! assert!(!cob.with_valid(false).is_valid()); // bit 31: the PDO is switched off
//!
//! let f = Frame::new(cob.can_id().unwrap(), &[0x34, 0x12])?;
//! assert_eq!((f.id().raw(), f.dlc(), f.data()), (0x185, 2, &[0x34, 0x12][..]));
//! assert_eq!(predefined::classify(f.id()), Function::Tpdo(1, node));
//! // Bad input is an error, not a panic: nine bytes do not fit a classic frame.
//! assert_eq!(Frame::new(f.id(), &[0; 9]), Err(FrameError::TooLong { len: 9 }));
//! # Ok::<(), FrameError>(())
//! ```

#[cfg(any(test, feature = "proptest"))]
pub mod arbitrary;
pub mod cob_id;
#[cfg(feature = "fd")]
pub mod fd;
pub mod instant;
pub mod queue;
pub mod storage;

use core::fmt;

#[cfg(feature = "fd")]
pub use fd::FdFrame;

/// Largest 11-bit identifier.
pub const STANDARD_ID_MAX: u16 = 0x7FF;
/// Largest 29-bit identifier.
pub const EXTENDED_ID_MAX: u32 = 0x1FFF_FFFF;

/// A CAN identifier: 11-bit (CAN 2.0A) or 29-bit (CAN 2.0B).
#[derive(Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Id {
    /// 11-bit identifier.
    Standard(u16),
    /// 29-bit identifier.
    Extended(u32),
}

impl Id {
    /// An 11-bit identifier, or `None` if `raw` does not fit in 11 bits.
    pub const fn standard(raw: u16) -> Option<Id> {
        if raw <= STANDARD_ID_MAX {
            Some(Id::Standard(raw))
        } else {
            None
        }
    }
    /// A 29-bit identifier, or `None` if `raw` does not fit in 29 bits.
    pub const fn extended(raw: u32) -> Option<Id> {
        if raw <= EXTENDED_ID_MAX {
            Some(Id::Extended(raw))
        } else {
            None
        }
    }
    /// The numeric identifier (without any format flag).
    pub const fn raw(self) -> u32 {
        match self {
            Id::Standard(r) => r as u32,
            Id::Extended(r) => r,
        }
    }
    /// True for a 29-bit identifier.
    pub const fn is_extended(self) -> bool {
        matches!(self, Id::Extended(_))
    }

    /// The arbitration priority of a frame with this identifier: lower wins the bus.
    ///
    /// Compares the bits as they appear on the wire: the 11 base bits first; on equal base bits a
    /// standard data frame beats a standard remote frame, which beats any extended frame (SRR and
    /// IDE are recessive), and extended frames then compare their 18 extension bits and RTR.
    pub const fn arbitration_key(self, rtr: bool) -> u64 {
        match self {
            Id::Standard(r) => ((r as u64) << 21) | ((rtr as u64) << 20),
            Id::Extended(r) => {
                let base = (r >> 18) as u64;
                let ext = (r & 0x3_FFFF) as u64;
                (base << 21) | (1 << 20) | (1 << 19) | (ext << 1) | rtr as u64
            }
        }
    }
}

impl fmt::Debug for Id {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// `0x123` for standard and `0x1234567x` for extended identifiers.
impl fmt::Display for Id {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Id::Standard(r) => write!(f, "{r:#05x}"),
            Id::Extended(r) => write!(f, "{r:#010x}x"),
        }
    }
}

/// Why a frame could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// More than 8 data bytes, or a remote frame DLC above 8.
    TooLong {
        /// The length that was asked for.
        len: usize,
    },
    /// The identifier does not fit its format (11 or 29 bits).
    BadId {
        /// The identifier that was asked for.
        raw: u32,
    },
    /// The source frame is not a classic CAN frame (CAN FD or an error frame).
    NotClassic,
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::TooLong { len } => {
                write!(f, "CAN frame of {len} bytes: classic CAN carries at most 8")
            }
            FrameError::BadId { raw } => {
                write!(f, "CAN identifier {raw:#x} does not fit 11 (or 29) bits")
            }
            FrameError::NotClassic => f.write_str("not a classic CAN data or remote frame"),
        }
    }
}

impl core::error::Error for FrameError {}

/// One classic CAN frame.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Frame {
    /// The identifier packed into one word ([`pack`]): 16 bytes a frame instead of 20, in
    /// every queue, merge slot and event that holds frames.
    id: u32,
    rtr: bool,
    dlc: u8,
    data: [u8; 8],
}

impl Frame {
    /// A data frame. Fails if `data` is longer than 8 bytes.
    pub fn new(id: Id, data: &[u8]) -> Result<Frame, FrameError> {
        if data.len() > 8 {
            return Err(FrameError::TooLong { len: data.len() });
        }
        let mut buf = [0u8; 8];
        buf[..data.len()].copy_from_slice(data);
        Ok(Frame {
            id: pack(id),
            rtr: false,
            dlc: data.len() as u8,
            data: buf,
        })
    }

    /// A data frame from a fixed-size payload; the length is checked at compile time.
    #[must_use]
    pub const fn from_array<const N: usize>(id: Id, data: [u8; N]) -> Frame {
        const { assert!(N <= 8, "classic CAN carries at most 8 bytes") };
        let mut buf = [0u8; 8];
        let mut i = 0;
        while i < N {
            buf[i] = data[i];
            i += 1;
        }
        Frame {
            id: pack(id),
            rtr: false,
            dlc: N as u8,
            data: buf,
        }
    }

    /// A remote (RTR) frame requesting `dlc` bytes.
    pub fn remote(id: Id, dlc: u8) -> Result<Frame, FrameError> {
        if dlc > 8 {
            return Err(FrameError::TooLong { len: dlc as usize });
        }
        Ok(Frame {
            id: pack(id),
            rtr: true,
            dlc,
            data: [0; 8],
        })
    }

    /// The identifier.
    pub const fn id(&self) -> Id {
        unpack(self.id)
    }
    /// True for a remote (RTR) frame.
    pub const fn is_remote(&self) -> bool {
        self.rtr
    }
    /// Data length code, 0–8.
    pub const fn dlc(&self) -> u8 {
        self.dlc
    }
    /// The payload: `dlc` bytes for a data frame, empty for a remote frame.
    pub fn data(&self) -> &[u8] {
        if self.rtr {
            &[]
        } else {
            &self.data[..self.dlc as usize]
        }
    }
    /// Priority key for bus arbitration: lower wins (see [`Id::arbitration_key`]).
    pub const fn arbitration_key(&self) -> u64 {
        self.id().arbitration_key(self.rtr)
    }
}

/// Marks an extended identifier in a packed one: above the 29 bits of any valid identifier.
const EXTENDED: u32 = 1 << 31;

/// `id` in one word: its raw value, with [`EXTENDED`] set for an extended one. (An extended
/// value with bit 31 set is no CAN identifier; it loses that bit.)
const fn pack(id: Id) -> u32 {
    match id {
        Id::Standard(raw) => raw as u32,
        Id::Extended(raw) => raw | EXTENDED,
    }
}

/// The identifier [`pack`] packed.
const fn unpack(packed: u32) -> Id {
    if packed & EXTENDED != 0 {
        Id::Extended(packed & !EXTENDED)
    } else {
        Id::Standard(packed as u16)
    }
}

impl fmt::Debug for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// candump-like text: `0x701 [1] 05` or `0x701 [1] remote`.
impl fmt::Display for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} [{}]", self.id(), self.dlc)?;
        if self.rtr {
            return f.write_str(" remote");
        }
        for b in self.data() {
            write!(f, " {b:02X}")?;
        }
        Ok(())
    }
}

impl From<embedded_can::Id> for Id {
    fn from(id: embedded_can::Id) -> Self {
        match id {
            embedded_can::Id::Standard(s) => Id::Standard(s.as_raw()),
            embedded_can::Id::Extended(e) => Id::Extended(e.as_raw()),
        }
    }
}

impl From<Id> for embedded_can::Id {
    fn from(id: Id) -> Self {
        // The constructors only accept in-range values, which `Id` guarantees when built
        // through `Id::standard`/`Id::extended`; out-of-range variants built by hand are masked.
        match id {
            Id::Standard(r) => embedded_can::Id::Standard(
                embedded_can::StandardId::new(r & STANDARD_ID_MAX)
                    .unwrap_or(embedded_can::StandardId::ZERO),
            ),
            Id::Extended(r) => embedded_can::Id::Extended(
                embedded_can::ExtendedId::new(r & EXTENDED_ID_MAX)
                    .unwrap_or(embedded_can::ExtendedId::ZERO),
            ),
        }
    }
}

impl Frame {
    /// Lossless conversion from any `embedded_can::Frame` (driver frames of no_std HALs).
    pub fn from_embedded<F: embedded_can::Frame>(f: &F) -> Result<Frame, FrameError> {
        let id = Id::from(f.id());
        if f.is_remote_frame() {
            Frame::remote(id, u8::try_from(f.dlc()).unwrap_or(u8::MAX))
        } else {
            Frame::new(id, f.data())
        }
    }

    /// Lossless conversion to any `embedded_can::Frame`; `None` if the driver type refuses it.
    pub fn to_embedded<F: embedded_can::Frame>(&self) -> Option<F> {
        let id: embedded_can::Id = self.id().into();
        if self.rtr {
            F::new_remote(id, self.dlc as usize)
        } else {
            F::new(id, self.data())
        }
    }
}

/// `Frame` itself is an `embedded_can::Frame`, so duocan frames can be handed to any HAL driver.
impl embedded_can::Frame for Frame {
    fn new(id: impl Into<embedded_can::Id>, data: &[u8]) -> Option<Self> {
        Frame::new(Id::from(id.into()), data).ok()
    }
    fn new_remote(id: impl Into<embedded_can::Id>, dlc: usize) -> Option<Self> {
        Frame::remote(Id::from(id.into()), u8::try_from(dlc).ok()?).ok()
    }
    fn is_extended(&self) -> bool {
        self.id().is_extended()
    }
    fn is_remote_frame(&self) -> bool {
        self.rtr
    }
    fn id(&self) -> embedded_can::Id {
        self.id().into()
    }
    fn dlc(&self) -> usize {
        self.dlc as usize
    }
    fn data(&self) -> &[u8] {
        Frame::data(self)
    }
}

/// What is wrong with a received frame (bad input is reported, never a panic).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Malformed {
    /// The DLC is not what the service defines.
    WrongLength {
        /// Bytes the service expects (minimum).
        expected: u8,
        /// Bytes received.
        got: u8,
    },
    /// A remote frame where a data frame is expected.
    UnexpectedRemote,
    /// A data frame where a remote frame is expected.
    UnexpectedData,
    /// A field holds a value the service does not define (command specifier, state byte).
    BadValue {
        /// The offending byte.
        value: u8,
    },
}

impl fmt::Display for Malformed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Malformed::WrongLength { expected, got } => {
                write!(f, "wrong length: {got} bytes, expected {expected}")
            }
            Malformed::UnexpectedRemote => f.write_str("remote frame where data was expected"),
            Malformed::UnexpectedData => {
                f.write_str("data frame where a remote request was expected")
            }
            Malformed::BadValue { value } => write!(f, "undefined value {value:#04x}"),
        }
    }
}

impl core::error::Error for Malformed {}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn classic_frame_is_16_bytes() {
        assert_eq!(core::mem::size_of::<Frame>(), 16);
    }

    #[test]
    fn payload_beyond_dlc_is_zero_so_equal_frames_hash_equal() {
        let a = Frame::new(Id::Standard(0x181), &[1, 2]).unwrap();
        let b = Frame::from_array(Id::Standard(0x181), [1u8, 2]);
        assert_eq!(a, b);
        assert_eq!(a.data(), &[1, 2]);
    }

    #[test]
    fn too_long_payload_is_an_error_not_a_panic() {
        assert_eq!(
            Frame::new(Id::Standard(1), &[0; 9]),
            Err(FrameError::TooLong { len: 9 })
        );
        assert!(Frame::remote(Id::Standard(1), 9).is_err());
    }

    #[test]
    fn arbitration_order_matches_the_wire() {
        let std_data = Id::Standard(0x100).arbitration_key(false);
        let std_rtr = Id::Standard(0x100).arbitration_key(true);
        let ext_same_base = Id::Extended(0x100 << 18).arbitration_key(false);
        let std_lower = Id::Standard(0x0FF).arbitration_key(true);
        assert!(std_lower < std_data);
        assert!(std_data < std_rtr);
        assert!(std_rtr < ext_same_base);
        assert!(Id::Extended(5).arbitration_key(false) < Id::Extended(6).arbitration_key(false));
    }

    proptest! {
        #[test]
        fn embedded_can_round_trip_is_lossless(f in super::arbitrary::any_frame()) {
            let e: Frame = f.to_embedded().unwrap();
            prop_assert_eq!(Frame::from_embedded(&e).unwrap(), f);
        }
    }
}
