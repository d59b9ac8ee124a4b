//! SDO frames (CiA 301 §7.2.4.3): the command byte and its fields, decoded into [`Request`]
//! (client → server) and [`Response`] (server → client) and encoded back, byte for byte.
//!
//! Every SDO frame carries 8 bytes. Reserved bits are ignored when decoding and sent as zero, so
//! `decode(encode(x)) == x` for every value. Block segments carry no command specifier (byte 0 is
//! `c | seqno`), so they are decoded separately by [`BlockSegment`], in the states that expect them.

use crate::od::abort::AbortCode;

/// Data bytes of a segment (bytes 1–7 of the frame).
pub const SEGMENT_DATA: usize = 7;
/// Largest block size (segments per sub-block).
pub const MAX_BLOCK_SIZE: u8 = 127;

/// What follows an initiate frame: the data itself (expedited) or the size of the transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Init {
    /// Expedited: the data is in bytes 4–7.
    Expedited {
        /// The four data bytes (bytes past `len` are zero when `len` is given).
        data: [u8; 4],
        /// Valid bytes, 1–4, if indicated (`s = 1`); `None` means "unspecified".
        len: Option<u8>,
    },
    /// Segmented: the size follows in bytes 4–7, if indicated.
    Segmented {
        /// Size in bytes, if indicated.
        size: Option<u32>,
    },
}

impl Init {
    /// The expedited form of `data` (1–4 bytes); `None` for other lengths.
    pub fn expedited(data: &[u8]) -> Option<Init> {
        if data.is_empty() || data.len() > 4 {
            return None;
        }
        let mut d = [0u8; 4];
        d[..data.len()].copy_from_slice(data);
        Some(Init::Expedited {
            data: d,
            len: Some(data.len() as u8),
        })
    }

    /// Bits 3–0 of the command byte (`n n e s`) and bytes 4–7.
    fn encode(self) -> (u8, [u8; 4]) {
        match self {
            Init::Expedited { data, len: Some(l) } => {
                let l = l.clamp(1, 4);
                let mut d = [0u8; 4];
                d[..l as usize].copy_from_slice(&data[..l as usize]);
                (((4 - l) << 2) | 0b11, d)
            }
            Init::Expedited { data, len: None } => (0b10, data),
            Init::Segmented { size: Some(s) } => (0b01, s.to_le_bytes()),
            Init::Segmented { size: None } => (0, [0; 4]),
        }
    }

    fn decode(cmd: u8, d: &[u8; 8]) -> Init {
        let data = [d[4], d[5], d[6], d[7]];
        match (cmd & 0b10 != 0, cmd & 0b01 != 0) {
            (true, true) => {
                let len = 4 - ((cmd >> 2) & 0b11);
                let mut out = [0u8; 4];
                out[..len as usize].copy_from_slice(&data[..len as usize]);
                Init::Expedited {
                    data: out,
                    len: Some(len),
                }
            }
            (true, false) => Init::Expedited { data, len: None },
            (false, true) => Init::Segmented {
                size: Some(u32::from_le_bytes(data)),
            },
            (false, false) => Init::Segmented { size: None },
        }
    }
}

/// Up to seven data bytes of a segment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SegmentData {
    /// The bytes; those past `len` are zero.
    pub data: [u8; SEGMENT_DATA],
    /// How many are valid, 0–7.
    pub len: u8,
}

impl SegmentData {
    /// The first (up to) seven bytes of `src`.
    #[must_use]
    pub fn from_slice(src: &[u8]) -> SegmentData {
        let n = src.len().min(SEGMENT_DATA);
        let mut data = [0u8; SEGMENT_DATA];
        data[..n].copy_from_slice(&src[..n]);
        SegmentData { data, len: n as u8 }
    }
    /// The valid bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.data[..(self.len as usize).min(SEGMENT_DATA)]
    }
    /// `n << 1`: the count of unused bytes in the command byte.
    fn n_bits(&self) -> u8 {
        (SEGMENT_DATA as u8 - self.len.min(SEGMENT_DATA as u8)) << 1
    }
    fn decode(cmd: u8, d: &[u8; 8]) -> SegmentData {
        let len = SEGMENT_DATA as u8 - ((cmd >> 1) & 0b111);
        SegmentData::from_slice(&d[1..1 + len as usize])
    }
    fn write(&self, out: &mut [u8; 8]) {
        out[1..8].copy_from_slice(&self.data);
    }
}

/// A frame from client to server.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// ccs 1: initiate download.
    InitiateDownload {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Data or size.
        init: Init,
    },
    /// ccs 0: download segment.
    DownloadSegment {
        /// Toggle bit.
        toggle: bool,
        /// Data.
        data: SegmentData,
        /// No more segments.
        last: bool,
    },
    /// ccs 2: initiate upload.
    InitiateUpload {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// ccs 3: upload segment.
    UploadSegment {
        /// Toggle bit.
        toggle: bool,
    },
    /// ccs 4: abort transfer.
    Abort {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: AbortCode,
    },
    /// ccs 5, cs 0: initiate block upload.
    BlockUploadInitiate {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The client supports CRC.
        crc: bool,
        /// Segments per sub-block the client accepts.
        blksize: u8,
        /// Protocol switch threshold: the server may answer with a plain upload when the data
        /// is at most this many bytes (0: no switch).
        pst: u8,
    },
    /// ccs 5, cs 1: end block upload (the client's final confirmation).
    BlockUploadEnd,
    /// ccs 5, cs 2: block upload sub-block acknowledgement.
    BlockUploadAck {
        /// Last segment received in sequence.
        ackseq: u8,
        /// Block size for the next sub-block.
        blksize: u8,
    },
    /// ccs 5, cs 3: start block upload.
    BlockUploadStart,
    /// ccs 6, cs 0: initiate block download.
    BlockDownloadInitiate {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The client supports CRC.
        crc: bool,
        /// Size, if indicated.
        size: Option<u32>,
    },
    /// ccs 6, cs 1: end block download.
    BlockDownloadEnd {
        /// Bytes of the last segment that carry no data.
        unused: u8,
        /// CRC of the data (meaningful when both sides support CRC).
        crc: u16,
    },
}

/// A frame from server to client.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Response {
    /// scs 0: upload segment.
    UploadSegment {
        /// Toggle bit.
        toggle: bool,
        /// Data.
        data: SegmentData,
        /// No more segments.
        last: bool,
    },
    /// scs 1: download segment acknowledged.
    DownloadSegment {
        /// Toggle bit.
        toggle: bool,
    },
    /// scs 2: initiate upload response.
    InitiateUpload {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Data or size.
        init: Init,
    },
    /// scs 3: initiate download response.
    InitiateDownload {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
    /// scs 4: abort transfer.
    Abort {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Why.
        code: AbortCode,
    },
    /// scs 5, ss 0: initiate block download response.
    BlockDownloadInitiate {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The server supports CRC.
        crc: bool,
        /// Segments per sub-block the server accepts.
        blksize: u8,
    },
    /// scs 5, ss 1: end block download response.
    BlockDownloadEnd,
    /// scs 5, ss 2: block download sub-block acknowledgement.
    BlockDownloadAck {
        /// Last segment received in sequence.
        ackseq: u8,
        /// Block size for the next sub-block.
        blksize: u8,
    },
    /// scs 6, ss 0: initiate block upload response.
    BlockUploadInitiate {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The server supports CRC.
        crc: bool,
        /// Size, if indicated.
        size: Option<u32>,
    },
    /// scs 6, ss 1: end block upload.
    BlockUploadEnd {
        /// Bytes of the last segment that carry no data.
        unused: u8,
        /// CRC of the data.
        crc: u16,
    },
}

fn mux(d: &[u8; 8]) -> (u16, u8) {
    (u16::from_le_bytes([d[1], d[2]]), d[3])
}

fn with_mux(cmd: u8, index: u16, sub: u8, tail: [u8; 4]) -> [u8; 8] {
    let i = index.to_le_bytes();
    [cmd, i[0], i[1], sub, tail[0], tail[1], tail[2], tail[3]]
}

fn abort(index: u16, sub: u8, code: AbortCode) -> [u8; 8] {
    with_mux(0x80, index, sub, code.0.to_le_bytes())
}

fn size_bits(size: Option<u32>) -> (u8, [u8; 4]) {
    match size {
        Some(s) => (0b10, s.to_le_bytes()),
        None => (0, [0; 4]),
    }
}

fn toggle_bit(t: bool) -> u8 {
    (t as u8) << 4
}

impl Request {
    /// Decodes the 8 data bytes of a client frame. An unknown command specifier is
    /// [`AbortCode::COMMAND_SPECIFIER`].
    pub fn decode(d: &[u8; 8]) -> Result<Request, AbortCode> {
        let cmd = d[0];
        let (index, sub) = mux(d);
        let t = cmd & 0x10 != 0;
        Ok(match cmd >> 5 {
            0 => Request::DownloadSegment {
                toggle: t,
                data: SegmentData::decode(cmd, d),
                last: cmd & 1 != 0,
            },
            1 => Request::InitiateDownload {
                index,
                sub,
                init: Init::decode(cmd, d),
            },
            2 => Request::InitiateUpload { index, sub },
            3 => Request::UploadSegment { toggle: t },
            4 => Request::Abort {
                index,
                sub,
                code: AbortCode(u32::from_le_bytes([d[4], d[5], d[6], d[7]])),
            },
            5 => match cmd & 0b11 {
                0 => Request::BlockUploadInitiate {
                    index,
                    sub,
                    crc: cmd & 0b100 != 0,
                    blksize: d[4],
                    pst: d[5],
                },
                1 => Request::BlockUploadEnd,
                2 => Request::BlockUploadAck {
                    ackseq: d[1],
                    blksize: d[2],
                },
                _ => Request::BlockUploadStart,
            },
            6 if cmd & 1 == 0 => Request::BlockDownloadInitiate {
                index,
                sub,
                crc: cmd & 0b100 != 0,
                size: (cmd & 0b10 != 0).then(|| u32::from_le_bytes([d[4], d[5], d[6], d[7]])),
            },
            6 => Request::BlockDownloadEnd {
                unused: (cmd >> 2) & 0b111,
                crc: u16::from_le_bytes([d[1], d[2]]),
            },
            _ => return Err(AbortCode::COMMAND_SPECIFIER),
        })
    }

    /// The 8 data bytes of the frame.
    pub fn encode(&self) -> [u8; 8] {
        match *self {
            Request::InitiateDownload { index, sub, init } => {
                let (bits, tail) = init.encode();
                with_mux(0x20 | bits, index, sub, tail)
            }
            Request::DownloadSegment { toggle, data, last } => {
                let mut out = [
                    toggle_bit(toggle) | data.n_bits() | last as u8,
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                ];
                data.write(&mut out);
                out
            }
            Request::InitiateUpload { index, sub } => with_mux(0x40, index, sub, [0; 4]),
            Request::UploadSegment { toggle } => [0x60 | toggle_bit(toggle), 0, 0, 0, 0, 0, 0, 0],
            Request::Abort { index, sub, code } => abort(index, sub, code),
            Request::BlockUploadInitiate {
                index,
                sub,
                crc,
                blksize,
                pst,
            } => with_mux(0xA0 | (crc as u8) << 2, index, sub, [blksize, pst, 0, 0]),
            Request::BlockUploadEnd => [0xA1, 0, 0, 0, 0, 0, 0, 0],
            Request::BlockUploadAck { ackseq, blksize } => [0xA2, ackseq, blksize, 0, 0, 0, 0, 0],
            Request::BlockUploadStart => [0xA3, 0, 0, 0, 0, 0, 0, 0],
            Request::BlockDownloadInitiate {
                index,
                sub,
                crc,
                size,
            } => {
                let (s, tail) = size_bits(size);
                with_mux(0xC0 | (crc as u8) << 2 | s, index, sub, tail)
            }
            Request::BlockDownloadEnd { unused, crc } => {
                let c = crc.to_le_bytes();
                [0xC1 | (unused & 0b111) << 2, c[0], c[1], 0, 0, 0, 0, 0]
            }
        }
    }
}

impl Response {
    /// Decodes the 8 data bytes of a server frame. An unknown command specifier is
    /// [`AbortCode::COMMAND_SPECIFIER`].
    pub fn decode(d: &[u8; 8]) -> Result<Response, AbortCode> {
        let cmd = d[0];
        let (index, sub) = mux(d);
        let t = cmd & 0x10 != 0;
        Ok(match cmd >> 5 {
            0 => Response::UploadSegment {
                toggle: t,
                data: SegmentData::decode(cmd, d),
                last: cmd & 1 != 0,
            },
            1 => Response::DownloadSegment { toggle: t },
            2 => Response::InitiateUpload {
                index,
                sub,
                init: Init::decode(cmd, d),
            },
            3 => Response::InitiateDownload { index, sub },
            4 => Response::Abort {
                index,
                sub,
                code: AbortCode(u32::from_le_bytes([d[4], d[5], d[6], d[7]])),
            },
            5 => match cmd & 0b11 {
                0 => Response::BlockDownloadInitiate {
                    index,
                    sub,
                    crc: cmd & 0b100 != 0,
                    blksize: d[4],
                },
                1 => Response::BlockDownloadEnd,
                2 => Response::BlockDownloadAck {
                    ackseq: d[1],
                    blksize: d[2],
                },
                _ => return Err(AbortCode::COMMAND_SPECIFIER),
            },
            6 if cmd & 1 == 0 => Response::BlockUploadInitiate {
                index,
                sub,
                crc: cmd & 0b100 != 0,
                size: (cmd & 0b10 != 0).then(|| u32::from_le_bytes([d[4], d[5], d[6], d[7]])),
            },
            6 => Response::BlockUploadEnd {
                unused: (cmd >> 2) & 0b111,
                crc: u16::from_le_bytes([d[1], d[2]]),
            },
            _ => return Err(AbortCode::COMMAND_SPECIFIER),
        })
    }

    /// The 8 data bytes of the frame.
    pub fn encode(&self) -> [u8; 8] {
        match *self {
            Response::UploadSegment { toggle, data, last } => {
                let mut out = [
                    toggle_bit(toggle) | data.n_bits() | last as u8,
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                    0,
                ];
                data.write(&mut out);
                out
            }
            Response::DownloadSegment { toggle } => {
                [0x20 | toggle_bit(toggle), 0, 0, 0, 0, 0, 0, 0]
            }
            Response::InitiateUpload { index, sub, init } => {
                let (bits, tail) = init.encode();
                with_mux(0x40 | bits, index, sub, tail)
            }
            Response::InitiateDownload { index, sub } => with_mux(0x60, index, sub, [0; 4]),
            Response::Abort { index, sub, code } => abort(index, sub, code),
            Response::BlockDownloadInitiate {
                index,
                sub,
                crc,
                blksize,
            } => with_mux(0xA0 | (crc as u8) << 2, index, sub, [blksize, 0, 0, 0]),
            Response::BlockDownloadEnd => [0xA1, 0, 0, 0, 0, 0, 0, 0],
            Response::BlockDownloadAck { ackseq, blksize } => {
                [0xA2, ackseq, blksize, 0, 0, 0, 0, 0]
            }
            Response::BlockUploadInitiate {
                index,
                sub,
                crc,
                size,
            } => {
                let (s, tail) = size_bits(size);
                with_mux(0xC0 | (crc as u8) << 2 | s, index, sub, tail)
            }
            Response::BlockUploadEnd { unused, crc } => {
                let c = crc.to_le_bytes();
                [0xC1 | (unused & 0b111) << 2, c[0], c[1], 0, 0, 0, 0, 0]
            }
        }
    }
}

/// A segment of a block transfer: `c | seqno` and seven bytes. How many bytes of the last
/// segment are data is only known from the end frame that follows it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockSegment {
    /// Sequence number in the sub-block, 1–127 (0 is invalid on the wire but decodable).
    pub seqno: u8,
    /// No more segments: this is the last one of the transfer.
    pub last: bool,
    /// Seven bytes.
    pub data: [u8; SEGMENT_DATA],
}

impl BlockSegment {
    /// Decodes any 8 bytes as a segment.
    #[must_use]
    pub fn decode(d: &[u8; 8]) -> BlockSegment {
        let mut data = [0u8; SEGMENT_DATA];
        data.copy_from_slice(&d[1..8]);
        BlockSegment {
            seqno: d[0] & 0x7F,
            last: d[0] & 0x80 != 0,
            data,
        }
    }
    /// The 8 bytes of the frame.
    pub fn encode(&self) -> [u8; 8] {
        let mut out = [
            (self.last as u8) << 7 | (self.seqno & 0x7F),
            0,
            0,
            0,
            0,
            0,
            0,
            0,
        ];
        out[1..8].copy_from_slice(&self.data);
        out
    }
}

/// The abort frame either side sends: `0x80`, index, sub-index, code.
pub fn abort_frame(index: u16, sub: u8, code: AbortCode) -> [u8; 8] {
    abort(index, sub, code)
}

/// True if `d` is an abort frame in a state where byte 0 could also be a block segment: only
/// `0x80` exactly (sequence number 0 is no segment).
pub fn is_abort_in_block(d: &[u8; 8]) -> bool {
    d[0] == 0x80
}

/// The code of an abort frame (bytes 4–7).
pub fn abort_code(d: &[u8; 8]) -> AbortCode {
    AbortCode(u32::from_le_bytes([d[4], d[5], d[6], d[7]]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn known_frames_byte_for_byte() {
        // Expedited download of four bytes to 0x2000 sub 1.
        let r = Request::InitiateDownload {
            index: 0x2000,
            sub: 1,
            init: Init::expedited(&[0x78, 0x56, 0x34, 0x12]).unwrap(),
        };
        assert_eq!(r.encode(), [0x23, 0x00, 0x20, 0x01, 0x78, 0x56, 0x34, 0x12]);
        // One byte: n = 3.
        let r = Request::InitiateDownload {
            index: 0x1017,
            sub: 0,
            init: Init::expedited(&[5]).unwrap(),
        };
        assert_eq!(r.encode(), [0x2F, 0x17, 0x10, 0x00, 5, 0, 0, 0]);
        assert_eq!(
            Response::InitiateDownload {
                index: 0x1017,
                sub: 0
            }
            .encode(),
            [0x60, 0x17, 0x10, 0, 0, 0, 0, 0]
        );
        // Last download segment with 3 data bytes, toggle set: 0001 1001.
        let r = Request::DownloadSegment {
            toggle: true,
            data: SegmentData::from_slice(&[1, 2, 3]),
            last: true,
        };
        assert_eq!(r.encode(), [0x19, 1, 2, 3, 0, 0, 0, 0]);
        assert_eq!(
            Request::BlockDownloadEnd {
                unused: 5,
                crc: 0x1234
            }
            .encode(),
            [0xD5, 0x34, 0x12, 0, 0, 0, 0, 0]
        );
        assert_eq!(
            Request::Abort {
                index: 0x2000,
                sub: 0,
                code: AbortCode::TIMEOUT
            }
            .encode(),
            [0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x04, 0x05]
        );
    }

    #[test]
    fn unknown_command_specifiers_are_refused() {
        assert_eq!(
            Request::decode(&[0xE0, 0, 0, 0, 0, 0, 0, 0]),
            Err(AbortCode::COMMAND_SPECIFIER)
        );
        assert_eq!(
            Response::decode(&[0xA3, 0, 0, 0, 0, 0, 0, 0]),
            Err(AbortCode::COMMAND_SPECIFIER)
        );
        assert_eq!(
            Response::decode(&[0xE0, 0, 0, 0, 0, 0, 0, 0]),
            Err(AbortCode::COMMAND_SPECIFIER)
        );
    }

    fn any_init() -> impl Strategy<Value = Init> {
        prop_oneof![
            proptest::collection::vec(any::<u8>(), 1..=4)
                .prop_map(|v| Init::expedited(&v).unwrap()),
            any::<[u8; 4]>().prop_map(|data| Init::Expedited { data, len: None }),
            proptest::option::of(any::<u32>()).prop_map(|size| Init::Segmented { size }),
        ]
    }

    fn any_seg() -> impl Strategy<Value = SegmentData> {
        proptest::collection::vec(any::<u8>(), 0..=7).prop_map(|v| SegmentData::from_slice(&v))
    }

    fn any_request() -> impl Strategy<Value = Request> {
        let m = (any::<u16>(), any::<u8>());
        prop_oneof![
            (m, any_init()).prop_map(|((index, sub), init)| Request::InitiateDownload {
                index,
                sub,
                init
            }),
            (any::<bool>(), any_seg(), any::<bool>()).prop_map(|(toggle, data, last)| {
                Request::DownloadSegment { toggle, data, last }
            }),
            m.prop_map(|(index, sub)| Request::InitiateUpload { index, sub }),
            any::<bool>().prop_map(|toggle| Request::UploadSegment { toggle }),
            (m, any::<u32>()).prop_map(|((index, sub), c)| Request::Abort {
                index,
                sub,
                code: AbortCode(c)
            }),
            (m, any::<bool>(), any::<u8>(), any::<u8>()).prop_map(
                |((index, sub), crc, blksize, pst)| Request::BlockUploadInitiate {
                    index,
                    sub,
                    crc,
                    blksize,
                    pst
                }
            ),
            Just(Request::BlockUploadEnd),
            Just(Request::BlockUploadStart),
            (any::<u8>(), any::<u8>())
                .prop_map(|(ackseq, blksize)| Request::BlockUploadAck { ackseq, blksize }),
            (m, any::<bool>(), proptest::option::of(any::<u32>())).prop_map(
                |((index, sub), crc, size)| Request::BlockDownloadInitiate {
                    index,
                    sub,
                    crc,
                    size
                }
            ),
            (0u8..8, any::<u16>())
                .prop_map(|(unused, crc)| Request::BlockDownloadEnd { unused, crc }),
        ]
    }

    fn any_response() -> impl Strategy<Value = Response> {
        let m = (any::<u16>(), any::<u8>());
        prop_oneof![
            (any::<bool>(), any_seg(), any::<bool>()).prop_map(|(toggle, data, last)| {
                Response::UploadSegment { toggle, data, last }
            }),
            any::<bool>().prop_map(|toggle| Response::DownloadSegment { toggle }),
            (m, any_init()).prop_map(|((index, sub), init)| Response::InitiateUpload {
                index,
                sub,
                init
            }),
            m.prop_map(|(index, sub)| Response::InitiateDownload { index, sub }),
            (m, any::<u32>()).prop_map(|((index, sub), c)| Response::Abort {
                index,
                sub,
                code: AbortCode(c)
            }),
            (m, any::<bool>(), any::<u8>()).prop_map(|((index, sub), crc, blksize)| {
                Response::BlockDownloadInitiate {
                    index,
                    sub,
                    crc,
                    blksize,
                }
            }),
            Just(Response::BlockDownloadEnd),
            (any::<u8>(), any::<u8>())
                .prop_map(|(ackseq, blksize)| Response::BlockDownloadAck { ackseq, blksize }),
            (m, any::<bool>(), proptest::option::of(any::<u32>())).prop_map(
                |((index, sub), crc, size)| Response::BlockUploadInitiate {
                    index,
                    sub,
                    crc,
                    size
                }
            ),
            (0u8..8, any::<u16>())
                .prop_map(|(unused, crc)| Response::BlockUploadEnd { unused, crc }),
        ]
    }

    proptest! {
        #[test]
        fn requests_round_trip(r in any_request()) {
            prop_assert_eq!(Request::decode(&r.encode()), Ok(r));
        }

        #[test]
        fn responses_round_trip(r in any_response()) {
            prop_assert_eq!(Response::decode(&r.encode()), Ok(r));
        }

        #[test]
        fn decoding_any_bytes_never_panics_and_re_encodes_stably(d in any::<[u8; 8]>()) {
            // Decoding normalises reserved bits; a second round is then exact.
            if let Ok(r) = Request::decode(&d) {
                prop_assert_eq!(Request::decode(&r.encode()), Ok(r));
            }
            if let Ok(r) = Response::decode(&d) {
                prop_assert_eq!(Response::decode(&r.encode()), Ok(r));
            }
            let s = BlockSegment::decode(&d);
            prop_assert_eq!(BlockSegment::decode(&s.encode()), s);
        }
    }
}
