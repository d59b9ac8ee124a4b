//! Frames between duocan's types and the kernel's and the socketcan crate's: lossless both
//! ways for classic data and remote frames and for CAN FD frames (the kernel's `struct
//! canfd_frame`); error frames are decoded into port statuses.

use super::CANFD_MTU;
use crate::frame::{FdFrame, Frame, FrameError, Id};
use crate::port::error_frame::{self, ErrorStatuses};
use socketcan::{
    CanAnyFrame, CanDataFrame, CanErrorFrame, CanFrame, CanRemoteFrame, EmbeddedFrame,
};

/// `canfd_frame.flags`: bit rate switch, error state indicator, FD frame (linux/can.h).
const CANFD_BRS: u8 = 0x01;
const CANFD_ESI: u8 = 0x02;
pub(super) const CANFD_FDF: u8 = 0x04;

/// The flags and mask of the identifier word of the kernel's `struct can_frame`: extended
/// frame, remote request, and the 29 identifier bits.
pub(super) const CAN_EFF_FLAG: u32 = 0x8000_0000;
pub(super) const CAN_RTR_FLAG: u32 = 0x4000_0000;
pub(super) const CAN_EFF_MASK: u32 = 0x1FFF_FFFF;

pub(super) fn id_of(id: socketcan::Id) -> Id {
    Id::from(id)
}

/// The [`Frame`] a frame of the socketcan crate carries (a `CanFrame`, `CanDataFrame`,
/// `CanRemoteFrame` or `CanAnyFrame`): lossless for classic data and remote frames; error and FD
/// frames are refused with [`FrameError::NotClassic`].
///
/// A function rather than `TryFrom`: [`Frame`] is the protocol core's type (`duocan-core`) and
/// the socketcan types are the socketcan crate's, so neither crate may implement the
/// conversion as a trait here.
pub fn frame_from_socketcan(f: impl Into<CanAnyFrame>) -> Result<Frame, FrameError> {
    match f.into() {
        CanAnyFrame::Normal(d) => Frame::new(id_of(EmbeddedFrame::id(&d)), EmbeddedFrame::data(&d)),
        CanAnyFrame::Remote(r) => {
            let dlc = u8::try_from(EmbeddedFrame::dlc(&r)).map_err(|_| FrameError::TooLong {
                len: EmbeddedFrame::dlc(&r),
            })?;
            Frame::remote(id_of(EmbeddedFrame::id(&r)), dlc)
        }
        CanAnyFrame::Error(_) | CanAnyFrame::Fd(_) => Err(FrameError::NotClassic),
    }
}

/// The socketcan crate's frame of a [`Frame`], lossless (a data or a remote frame); wrap it in
/// `CanAnyFrame::from` where that type is wanted. See [`frame_from_socketcan`] for why this is
/// not a `From`.
pub fn socketcan_frame(f: &Frame) -> CanFrame {
    // `Frame` guarantees an in-range identifier and DLC ≤ 8, which is all the socketcan
    // constructors check; the fallbacks are unreachable but keep this total.
    let id: socketcan::Id = f.id().into();
    if f.is_remote() {
        CanRemoteFrame::new_remote(id, f.dlc() as usize)
            .map(CanFrame::Remote)
            .unwrap_or_default()
    } else {
        CanDataFrame::new(id, f.data())
            .map(CanFrame::Data)
            .unwrap_or_default()
    }
}

/// Decodes a SocketCAN error frame into the statuses it reports.
pub fn decode_error_frame(f: &CanErrorFrame) -> ErrorStatuses {
    error_frame::decode(f.error_bits(), EmbeddedFrame::data(f))
}

/// The kernel's `struct canfd_frame` of `f`.
pub(super) fn canfd_bytes(f: &FdFrame) -> [u8; CANFD_MTU] {
    let word = match f.id() {
        Id::Standard(r) => u32::from(r),
        Id::Extended(r) => r | CAN_EFF_FLAG,
    };
    let mut raw = [0u8; CANFD_MTU];
    raw[..4].copy_from_slice(&word.to_ne_bytes());
    raw[4] = f.len() as u8;
    raw[5] = CANFD_FDF | if f.brs() { CANFD_BRS } else { 0 } | if f.esi() { CANFD_ESI } else { 0 };
    raw[8..8 + f.len()].copy_from_slice(f.data());
    raw
}

/// The CAN FD frame of a kernel `struct canfd_frame`; an error for a length that is not a CAN
/// FD length.
pub(super) fn fd_from_kernel(
    raw: &[u8; CANFD_MTU],
) -> Result<FdFrame, crate::frame::fd::FdFrameError> {
    let word = u32::from_ne_bytes([raw[0], raw[1], raw[2], raw[3]]);
    let id = if word & CAN_EFF_FLAG != 0 {
        Id::Extended(word & CAN_EFF_MASK)
    } else {
        Id::Standard((word & 0x7FF) as u16)
    };
    let len = usize::from(raw[4]).min(64);
    let f = FdFrame::new(id, &raw[8..8 + len])?;
    Ok(f.with_brs(raw[5] & CANFD_BRS != 0)
        .with_esi(raw[5] & CANFD_ESI != 0))
}
