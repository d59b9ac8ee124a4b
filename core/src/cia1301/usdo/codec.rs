//! USDO frame formats: every message both sides send, encoded into and decoded from the data
//! field of a CAN FD frame. Which byte holds what, and where each choice came from, is in the
//! [module documentation](super).
//!
//! Decoding takes any bytes: a frame too short for its command, a length past the frame's end,
//! an unknown command specifier or flag bits a command does not use are a [`UsdoDecodeError`]
//! naming the abort code the receiver answers with, never a panic. Bytes after the message
//! (CAN FD padding) are ignored, so a message decodes the same from every FD length that holds
//! it; encoding pads with [`PADDING`].

use super::abort::UsdoAbort;
use crate::frame::fd::FdFrame;
use crate::frame::Id;
use crate::od::abort::AbortCode;

/// The destination byte of a request to every server.
pub const BROADCAST: u8 = 0;
/// Most data bytes an expedited message carries: 64 less the 8-byte header.
pub const EXPEDITED_MAX: usize = 56;
/// Most data bytes a segment carries: 64 less the 4-byte segment header.
pub const SEGMENT_MAX: usize = 60;
/// The fill byte of a frame longer than its message (CiA 1301 asks for 0xCC).
pub const PADDING: u8 = 0xCC;

// Command specifiers (byte 1): duocan's values (see the module docs). Responses are the
// request's value with bit 6 set.
const DOWNLOAD_EXPEDITED: u8 = 0x01;
const DOWNLOAD_INITIATE: u8 = 0x02;
const DOWNLOAD_SEGMENT: u8 = 0x03;
const UPLOAD_INITIATE: u8 = 0x04;
const UPLOAD_SEGMENT: u8 = 0x05;
const DOWNLOAD_ACK: u8 = 0x41;
const DOWNLOAD_SEGMENT_ACK: u8 = 0x43;
const UPLOAD_EXPEDITED: u8 = 0x44;
const UPLOAD_SEGMENT_DATA: u8 = 0x45;
const UPLOAD_SEGMENTED: u8 = 0x46;
const ABORT: u8 = 0x80;

// The control byte of a segment (byte 3): last, toggle, and the data length in the low six
// bits.
const LAST: u8 = 0x80;
const TOGGLE: u8 = 0x40;
const LEN_MASK: u8 = 0x3F;

/// Up to 60 data bytes, held inline.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct UsdoPayload {
    len: u8,
    bytes: [u8; SEGMENT_MAX],
}

impl UsdoPayload {
    /// `data` as a payload; `None` above [`SEGMENT_MAX`] bytes.
    pub fn new(data: &[u8]) -> Option<UsdoPayload> {
        let mut bytes = [0; SEGMENT_MAX];
        bytes.get_mut(..data.len())?.copy_from_slice(data);
        Some(UsdoPayload {
            len: data.len() as u8,
            bytes,
        })
    }
    /// The bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }
}

impl core::fmt::Debug for UsdoPayload {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{:02X?}", self.bytes())
    }
}

/// One USDO message, without its addressing ([`Usdo`] adds that).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Msg {
    /// Client: write `data` (at most [`EXPEDITED_MAX`] bytes) to (index, sub) in one frame.
    DownloadExpedited {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// CiA 301 data type index of the value (0: not given).
        data_type: u8,
        /// The value.
        data: UsdoPayload,
    },
    /// Client: a segmented write of `size` bytes to (index, sub) starts.
    DownloadInitiate {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// CiA 301 data type index of the value (0: not given).
        data_type: u8,
        /// Bytes that follow in segments.
        size: u32,
    },
    /// Client: the next part of a segmented write.
    DownloadSegment {
        /// Alternates from `false`, segment by segment.
        toggle: bool,
        /// The write's last segment.
        last: bool,
        /// Up to [`SEGMENT_MAX`] bytes.
        data: UsdoPayload,
    },
    /// Client: read (index, sub).
    UploadInitiate {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Client: send the next segment of a segmented read.
    UploadSegment {
        /// Alternates from `false`, segment by segment.
        toggle: bool,
    },
    /// Server: an expedited write done, or a segmented write accepted.
    DownloadAck {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// Server: a segment of a write taken.
    DownloadSegmentAck {
        /// The segment's toggle.
        toggle: bool,
    },
    /// Server: the value read, in one frame.
    UploadExpedited {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// CiA 301 data type index of the entry (0: not given).
        data_type: u8,
        /// The value, at most [`EXPEDITED_MAX`] bytes.
        data: UsdoPayload,
    },
    /// Server: the value read has `size` bytes, sent in segments.
    UploadSegmented {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// CiA 301 data type index of the entry (0: not given).
        data_type: u8,
        /// Bytes that follow in segments.
        size: u32,
    },
    /// Server: the next part of a segmented read.
    UploadSegmentData {
        /// The request's toggle.
        toggle: bool,
        /// The read's last segment.
        last: bool,
        /// Up to [`SEGMENT_MAX`] bytes.
        data: UsdoPayload,
    },
    /// Either side: the transfer on (index, sub) ends, for `code`.
    Abort {
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: UsdoAbort,
    },
}

/// A USDO message with its addressing: the node it is for and the session it belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Usdo {
    /// The node-ID of the receiver, or [`BROADCAST`].
    pub dest: u8,
    /// The client's number for the transfer; answers carry it back.
    pub session: u8,
    /// The message.
    pub msg: Msg,
}

/// Why bytes are no USDO message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UsdoDecodeError {
    /// Fewer than 3 bytes: no destination and session to answer to.
    NoHeader,
    /// Addressed, but not a message: answered with `code` (the destination and session are
    /// those of the frame).
    Bad {
        /// The destination byte.
        dest: u8,
        /// The session byte.
        session: u8,
        /// The abort code the receiver answers with.
        code: AbortCode,
    },
}

fn mux(d: &[u8]) -> (u16, u8) {
    (u16::from_le_bytes([d[3], d[4]]), d[5])
}

fn segment(c: u8, d: &[u8]) -> Option<(bool, bool, UsdoPayload)> {
    let len = usize::from(c & LEN_MASK);
    let data = UsdoPayload::new(d.get(4..4 + len)?)?;
    Some((c & TOGGLE != 0, c & LAST != 0, data))
}

impl Usdo {
    /// Decodes a frame's data field.
    pub fn decode(d: &[u8]) -> Result<Usdo, UsdoDecodeError> {
        let [dest, cs, session, ..] = *d else {
            return Err(UsdoDecodeError::NoHeader);
        };
        let bad = |code| UsdoDecodeError::Bad {
            dest,
            session,
            code,
        };
        let short = bad(AbortCode::TYPE_MISMATCH);
        let need = |n: usize| if d.len() < n { Err(short) } else { Ok(()) };
        let size = || u32::from_le_bytes([d[8], d[9], d[10], d[11]]);
        let ctl = || d.get(3).copied().ok_or(short);
        let msg = match cs {
            DOWNLOAD_EXPEDITED | UPLOAD_EXPEDITED => {
                need(8)?;
                let (index, sub) = mux(d);
                let len = usize::from(d[7]);
                if len > EXPEDITED_MAX {
                    return Err(bad(AbortCode::LENGTH_TOO_HIGH));
                }
                let data = d.get(8..8 + len).and_then(UsdoPayload::new).ok_or(short)?;
                let data_type = d[6];
                if cs == DOWNLOAD_EXPEDITED {
                    Msg::DownloadExpedited {
                        index,
                        sub,
                        data_type,
                        data,
                    }
                } else {
                    Msg::UploadExpedited {
                        index,
                        sub,
                        data_type,
                        data,
                    }
                }
            }
            DOWNLOAD_INITIATE | UPLOAD_SEGMENTED => {
                need(12)?;
                let (index, sub) = mux(d);
                let (data_type, size) = (d[6], size());
                if cs == DOWNLOAD_INITIATE {
                    Msg::DownloadInitiate {
                        index,
                        sub,
                        data_type,
                        size,
                    }
                } else {
                    Msg::UploadSegmented {
                        index,
                        sub,
                        data_type,
                        size,
                    }
                }
            }
            UPLOAD_INITIATE | DOWNLOAD_ACK | ABORT => {
                need(8)?;
                let (index, sub) = mux(d);
                match cs {
                    UPLOAD_INITIATE => Msg::UploadInitiate { index, sub },
                    DOWNLOAD_ACK => Msg::DownloadAck { index, sub },
                    _ => Msg::Abort {
                        index,
                        sub,
                        code: UsdoAbort(d[6]),
                    },
                }
            }
            DOWNLOAD_SEGMENT | UPLOAD_SEGMENT_DATA => {
                let c = ctl()?;
                let (toggle, last, data) = segment(c, d).ok_or(short)?;
                if cs == DOWNLOAD_SEGMENT {
                    Msg::DownloadSegment { toggle, last, data }
                } else {
                    Msg::UploadSegmentData { toggle, last, data }
                }
            }
            UPLOAD_SEGMENT | DOWNLOAD_SEGMENT_ACK => {
                let c = ctl()?;
                if c & !TOGGLE != 0 {
                    return Err(bad(AbortCode::COMMAND_SPECIFIER));
                }
                let toggle = c & TOGGLE != 0;
                if cs == UPLOAD_SEGMENT {
                    Msg::UploadSegment { toggle }
                } else {
                    Msg::DownloadSegmentAck { toggle }
                }
            }
            _ => return Err(bad(AbortCode::COMMAND_SPECIFIER)),
        };
        Ok(Usdo { dest, session, msg })
    }

    /// The message's bytes (at most 64) into `out`; returns how many.
    pub fn write(&self, out: &mut [u8; 64]) -> usize {
        out[0] = self.dest;
        out[2] = self.session;
        let head = |out: &mut [u8; 64], cs: u8, index: u16, sub: u8, ty: u8, len: u8| {
            out[1] = cs;
            out[3..5].copy_from_slice(&index.to_le_bytes());
            out[5] = sub;
            out[6] = ty;
            out[7] = len;
        };
        let seg = |out: &mut [u8; 64], cs: u8, toggle: bool, last: bool, data: &UsdoPayload| {
            out[1] = cs;
            let b = data.bytes();
            out[3] = if toggle { TOGGLE } else { 0 } | if last { LAST } else { 0 } | b.len() as u8;
            out[4..4 + b.len()].copy_from_slice(b);
            4 + b.len()
        };
        match self.msg {
            Msg::DownloadExpedited {
                index,
                sub,
                data_type,
                data,
            }
            | Msg::UploadExpedited {
                index,
                sub,
                data_type,
                data,
            } => {
                let cs = match self.msg {
                    Msg::DownloadExpedited { .. } => DOWNLOAD_EXPEDITED,
                    _ => UPLOAD_EXPEDITED,
                };
                // A payload built for a segment may be longer than an expedited frame holds.
                let b = &data.bytes()[..data.bytes().len().min(EXPEDITED_MAX)];
                head(out, cs, index, sub, data_type, b.len() as u8);
                out[8..8 + b.len()].copy_from_slice(b);
                8 + b.len()
            }
            Msg::DownloadInitiate {
                index,
                sub,
                data_type,
                size,
            }
            | Msg::UploadSegmented {
                index,
                sub,
                data_type,
                size,
            } => {
                let cs = match self.msg {
                    Msg::DownloadInitiate { .. } => DOWNLOAD_INITIATE,
                    _ => UPLOAD_SEGMENTED,
                };
                head(out, cs, index, sub, data_type, 0);
                out[8..12].copy_from_slice(&size.to_le_bytes());
                12
            }
            Msg::UploadInitiate { index, sub } => {
                head(out, UPLOAD_INITIATE, index, sub, 0, 0);
                8
            }
            Msg::DownloadAck { index, sub } => {
                head(out, DOWNLOAD_ACK, index, sub, 0, 0);
                8
            }
            Msg::Abort { index, sub, code } => {
                head(out, ABORT, index, sub, code.0, 0);
                8
            }
            Msg::DownloadSegment { toggle, last, data } => {
                seg(out, DOWNLOAD_SEGMENT, toggle, last, &data)
            }
            Msg::UploadSegmentData { toggle, last, data } => {
                seg(out, UPLOAD_SEGMENT_DATA, toggle, last, &data)
            }
            Msg::UploadSegment { toggle } => seg(out, UPLOAD_SEGMENT, toggle, false, &EMPTY),
            Msg::DownloadSegmentAck { toggle } => {
                seg(out, DOWNLOAD_SEGMENT_ACK, toggle, false, &EMPTY)
            }
        }
    }

    /// The message as a CAN FD frame on `id`, padded with [`PADDING`] to the next FD length,
    /// with the bit rate switch on.
    pub fn encode(&self, id: Id) -> FdFrame {
        let mut buf = [0; 64];
        let n = self.write(&mut buf);
        match FdFrame::padded(id, &buf[..n], PADDING) {
            Ok(f) => f.with_brs(true),
            // `write` never writes more than 64 bytes, the one case `padded` refuses: no input
            // reaches this.
            Err(e) => unreachable!("{e}"),
        }
    }
}

const EMPTY: UsdoPayload = UsdoPayload {
    len: 0,
    bytes: [0; SEGMENT_MAX],
};

#[cfg(test)]
#[path = "codec_tests.rs"]
mod tests;
