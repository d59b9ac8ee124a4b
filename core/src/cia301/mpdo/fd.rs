//! The CAN FD form of an MPDO (`fd` feature): the classic header, then up to 60 data bytes.
//!
//! The layout is this crate's choice (see the module doc of [`super`]): bytes 0–3 exactly as
//! in the classic MPDO, the value from byte 4, little-endian, zero-filled up to the CAN FD
//! length that holds it (8, 12, 16, 20, 24, 32, 48 or 64 bytes).

use super::codec::{header, put_header, Mode, MpdoDecodeError};
use crate::frame::fd::{dlc_for_len, padded_len, FdFrame, FD_MAX_LEN};
use crate::frame::Id;

/// Data bytes an FD MPDO carries at most (64 − the 4-byte header).
pub const FD_DATA_MAX: usize = FD_MAX_LEN - 4;

/// One MPDO in a CAN FD frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct FdMpdo {
    /// Address mode (byte 0, bit 7).
    pub mode: Mode,
    /// Byte 0, bits 0–6, as in the classic form.
    pub node: u8,
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    data: [u8; FD_DATA_MAX],
    /// Data bytes: the frame's length − 4, so the zero fill up to the CAN FD length is part
    /// of it; a consumer takes as many bytes as its object holds.
    len: u8,
}

impl FdMpdo {
    /// An FD MPDO carrying `data` (up to 60 bytes), zero-filled to the next CAN FD length.
    /// `None` for more data, a node-ID above 127, or a source-address MPDO from node 0.
    #[must_use]
    pub fn new(mode: Mode, node: u8, index: u16, sub: u8, data: &[u8]) -> Option<FdMpdo> {
        if node > 127 || (mode == Mode::Source && node == 0) || data.len() > FD_DATA_MAX {
            return None;
        }
        let len = padded_len(data.len().max(4) + 4)? - 4;
        let mut d = [0u8; FD_DATA_MAX];
        d[..data.len()].copy_from_slice(data);
        Some(FdMpdo {
            mode,
            node,
            index,
            sub,
            data: d,
            len: len as u8,
        })
    }

    /// The data bytes (zero fill included).
    #[must_use]
    pub fn data(&self) -> &[u8] {
        &self.data[..self.len as usize]
    }

    /// Decodes an FD MPDO: a CAN FD length from 8 to 64 bytes, else
    /// [`MpdoDecodeError::Length`]; never panics.
    pub fn decode(b: &[u8]) -> Result<FdMpdo, MpdoDecodeError> {
        if b.len() < 8 || b.len() > FD_MAX_LEN || dlc_for_len(b.len()).is_none() {
            return Err(MpdoDecodeError::Length { got: b.len() });
        }
        let (mode, node, index, sub) = header(b)?;
        let mut data = [0u8; FD_DATA_MAX];
        data[..b.len() - 4].copy_from_slice(&b[4..]);
        Ok(FdMpdo {
            mode,
            node,
            index,
            sub,
            data,
            len: (b.len() - 4) as u8,
        })
    }

    /// The CAN FD frame on identifier `id` (BRS and ESI off).
    #[must_use]
    pub fn frame(&self, id: Id) -> FdFrame {
        let mut b = [0u8; FD_MAX_LEN];
        put_header(&mut b, self.mode, self.node, self.index, self.sub);
        let n = 4 + self.len as usize;
        b[4..n].copy_from_slice(self.data());
        match FdFrame::new(id, &b[..n]) {
            Ok(f) => f,
            // Unreachable: `len` + 4 is always a CAN FD length (the constructors keep it so).
            Err(_) => unreachable!("an FD MPDO is always a CAN FD length"),
        }
    }
}
