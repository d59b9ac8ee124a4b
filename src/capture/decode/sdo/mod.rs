//! SDO frames in their transfer: the command specifiers of CiA 301 §7.2.4.3 (decoded by the
//! stack's own [`codec`](crate::cia301::sdo::codec)), and per node the transfer in progress,
//! which segments and block sub-blocks need.

mod track;

pub(super) use track::{without_context, Tracks};

use crate::od::abort::AbortCode;
use core::fmt;

/// Which side sent an SDO frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SdoSide {
    /// The client (0x600+n: requests).
    Client,
    /// The server (0x580+n: responses).
    Server,
}

/// The transfer a frame belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SdoService {
    /// Upload (read from the server), expedited or segmented.
    Upload,
    /// Download (write to the server), expedited or segmented.
    Download,
    /// Block upload.
    BlockUpload,
    /// Block download.
    BlockDownload,
}

impl fmt::Display for SdoService {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SdoService::Upload => "upload",
            SdoService::Download => "download",
            SdoService::BlockUpload => "block upload",
            SdoService::BlockDownload => "block download",
        })
    }
}

/// What one SDO frame does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SdoStep {
    /// The client asks to upload (initiate upload request).
    Request,
    /// Expedited data: a download request or an upload response.
    Value {
        /// The four data bytes.
        data: [u8; 4],
        /// Valid bytes (1–4), when the frame indicates it.
        len: Option<u8>,
    },
    /// A segmented transfer starts: a download request or an upload response.
    Segmented {
        /// The size, when indicated.
        size: Option<u32>,
    },
    /// The server accepts a download (initiate download response).
    Accepted,
    /// A segment with data (download request, upload response).
    Segment {
        /// 1-based number in the transfer; `None` without context.
        number: Option<u32>,
        /// Data bytes in it.
        len: u8,
        /// No more segments follow.
        last: bool,
        /// The transfer's bytes in all, on the last segment with context.
        total: Option<u32>,
    },
    /// The client asks for the next upload segment, or the server confirms a download segment.
    SegmentAck {
        /// 1-based number of the segment asked for or confirmed; `None` without context.
        number: Option<u32>,
        /// The toggle bit.
        toggle: bool,
    },
    /// A block transfer starts: the client's request or the server's answer.
    BlockInit {
        /// The size, when indicated (download request, upload answer).
        size: Option<u32>,
        /// Segments per sub-block (upload request, download answer).
        blksize: Option<u8>,
        /// The sender supports the CRC.
        crc: bool,
    },
    /// The client starts the block upload's first sub-block.
    BlockStart,
    /// A segment of a sub-block.
    BlockSegment {
        /// Sequence number in the sub-block (1–127).
        seqno: u8,
        /// 1-based number in the transfer (segments acknowledged before + seqno); `None`
        /// without context.
        number: Option<u32>,
        /// The transfer's last segment.
        last: bool,
    },
    /// A sub-block acknowledgement.
    BlockAck {
        /// Last segment received in sequence.
        ackseq: u8,
        /// Block size for the next sub-block.
        blksize: u8,
    },
    /// The end of a block transfer's data.
    BlockEnd {
        /// Bytes of the last segment that carry no data.
        unused: u8,
        /// The CRC of the data.
        crc: u16,
        /// The transfer's bytes in all, with context.
        total: Option<u32>,
    },
    /// The end frame's answer: the block transfer is done.
    BlockEndConfirmed,
    /// Either side aborts.
    Abort {
        /// Why (its Display gives the CiA 301 meaning).
        code: AbortCode,
    },
    /// A command byte that is no CiA 301 command specifier.
    BadCommand {
        /// The byte.
        byte: u8,
    },
}

/// One SDO frame in its transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoInfo {
    /// Who sent it.
    pub side: SdoSide,
    /// The transfer it belongs to, when the command specifier or the context says.
    pub service: Option<SdoService>,
    /// Index and sub-index, from the frame or its transfer.
    pub object: Option<(u16, u8)>,
    /// What it does.
    pub step: SdoStep,
}

/// `0x00000123` for four bytes, `0x0123` for two: the little-endian value as a hex number.
struct Value<'a>(&'a [u8]);

impl fmt::Display for Value<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("0x")?;
        for b in self.0.iter().rev() {
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Display for SdoInfo {
    /// `SDO upload 0x1018:01 = 0x00000123` (the node is the caller's).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let from = match self.side {
            SdoSide::Client => "client",
            SdoSide::Server => "server",
        };
        if let SdoStep::Abort { code } = self.step {
            f.write_str("SDO abort")?;
            if let Some((i, s)) = self.object {
                write!(f, " {i:#06x}:{s:02x}")?;
            }
            return write!(f, " by {from}: {code}");
        }
        if let SdoStep::BadCommand { byte } = self.step {
            return write!(
                f,
                "SDO from {from}: command byte {byte:#04x} is no CiA 301 command specifier"
            );
        }
        f.write_str("SDO")?;
        if let Some(service) = self.service {
            write!(f, " {service}")?;
        }
        match self.object {
            Some((i, s)) => write!(f, " {i:#06x}:{s:02x}")?,
            None => f.write_str(" (transfer unknown)")?,
        }
        let answer = if self.side == SdoSide::Client {
            "request"
        } else {
            "accepted"
        };
        match self.step {
            SdoStep::Request => f.write_str(" request"),
            SdoStep::Value { data, len } => match len {
                Some(n) => write!(f, " = {}", Value(&data[..(n as usize).clamp(1, 4)])),
                None => write!(f, " = {} (size not indicated)", Value(&data)),
            },
            SdoStep::Segmented { size } => match size {
                Some(s) => write!(f, " segmented, {s} bytes"),
                None => f.write_str(" segmented, size not indicated"),
            },
            SdoStep::Accepted => f.write_str(" accepted"),
            SdoStep::Segment {
                number,
                len,
                last,
                total,
            } => {
                f.write_str(" segment")?;
                if let Some(n) = number {
                    write!(f, " {n}")?;
                }
                write!(f, " ({len} bytes)")?;
                match (last, total) {
                    (true, Some(t)) => write!(f, ", last: {t} bytes in all"),
                    (true, None) => f.write_str(", last"),
                    _ => Ok(()),
                }
            }
            SdoStep::SegmentAck { number, toggle } => {
                f.write_str(" segment")?;
                match number {
                    Some(n) => write!(f, " {n}")?,
                    None => write!(f, " (toggle {})", toggle as u8)?,
                }
                match self.side {
                    SdoSide::Client => f.write_str(" request"),
                    SdoSide::Server => f.write_str(" confirmed"),
                }
            }
            SdoStep::BlockInit { size, blksize, crc } => {
                write!(f, " {answer}")?;
                if let Some(s) = size {
                    write!(f, ", {s} bytes")?;
                }
                if let Some(b) = blksize {
                    write!(f, ", block size {b}")?;
                }
                if crc {
                    f.write_str(", CRC")?;
                }
                Ok(())
            }
            SdoStep::BlockStart => f.write_str(" start"),
            SdoStep::BlockSegment {
                seqno,
                number,
                last,
            } => {
                f.write_str(" segment")?;
                if let Some(n) = number {
                    write!(f, " {n}")?;
                }
                write!(f, " (sequence {seqno})")?;
                if last {
                    f.write_str(", last")?;
                }
                Ok(())
            }
            SdoStep::BlockAck { ackseq, blksize } => {
                write!(f, " ack sequence {ackseq}, next block size {blksize}")
            }
            SdoStep::BlockEnd { unused, crc, total } => {
                f.write_str(" end")?;
                match total {
                    Some(t) => write!(f, ", {t} bytes in all")?,
                    None => write!(f, ", {unused} bytes of the last segment unused")?,
                }
                write!(f, ", CRC {crc:#06x}")
            }
            SdoStep::BlockEndConfirmed => f.write_str(" end confirmed"),
            SdoStep::Abort { .. } | SdoStep::BadCommand { .. } => Ok(()),
        }
    }
}
