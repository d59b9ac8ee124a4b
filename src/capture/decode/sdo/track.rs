//! Per node, the transfer in progress: what names and counts its segments.

use super::{SdoInfo, SdoService, SdoSide, SdoStep};
use crate::capture::decode::frames::DecodedFrame;
use crate::capture::decode::kind::Kind;
use crate::capture::decode::services::{bad, wrong_length};
use crate::cia301::sdo::codec::{self, BlockSegment, Init, Request, Response, SEGMENT_DATA};
use crate::frame::cob_id::NodeId;
use crate::frame::Frame;

/// Where a node's transfer stands.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Phase {
    /// No transfer known.
    #[default]
    Idle,
    /// An expedited or segmented transfer.
    Plain,
    /// A block transfer before its first sub-block.
    BlockInit,
    /// Block segments are on the wire (from the client in a download, the server in an
    /// upload).
    BlockSegments,
    /// The last block segment went; the end frame is next (or a repeat, if acknowledged short).
    BlockLastSent,
}

/// One node's transfer: what its segments need to be named and counted.
#[derive(Clone, Copy, Debug, Default)]
struct Track {
    phase: Phase,
    service: Option<SdoService>,
    object: (u16, u8),
    /// Segments so far (plain), or segments acknowledged (block).
    segments: u32,
    /// Data bytes so far (plain).
    bytes: u32,
    /// The sequence number of the last block segment.
    last_seqno: u8,
}

impl Track {
    fn start(&mut self, service: SdoService, object: (u16, u8), phase: Phase) {
        *self = Track {
            phase,
            service: Some(service),
            object,
            ..Track::default()
        };
    }
    fn object(&self) -> Option<(u16, u8)> {
        (self.phase != Phase::Idle).then_some(self.object)
    }
    /// True when this side's next frame is a block segment (no command specifier).
    fn segment_expected(&self, side: SdoSide) -> bool {
        let sender = match self.service {
            Some(SdoService::BlockDownload) => SdoSide::Client,
            Some(SdoService::BlockUpload) => SdoSide::Server,
            _ => return false,
        };
        self.phase == Phase::BlockSegments && side == sender
    }
}

/// The transfers of nodes 1–127.
#[derive(Clone, Debug)]
pub(in crate::capture::decode) struct Tracks([Track; 127]);

impl Tracks {
    pub(in crate::capture::decode) fn new() -> Self {
        Tracks([Track::default(); 127])
    }

    pub(in crate::capture::decode) fn decode(
        &mut self,
        node: NodeId,
        side: SdoSide,
        frame: &Frame,
    ) -> DecodedFrame {
        match self.info(node, side, frame) {
            Ok(sdo) => DecodedFrame::Sdo { node, sdo },
            Err(problem) => bad(Kind::Sdo, Some(node), problem),
        }
    }

    /// The frame in `node`'s transfer, which it moves on.
    pub(in crate::capture::decode) fn info(
        &mut self,
        node: NodeId,
        side: SdoSide,
        frame: &Frame,
    ) -> Result<SdoInfo, String> {
        let track = &mut self.0[(node.raw() as usize).saturating_sub(1).min(126)];
        step(track, side, frame)
    }
}

/// Decodes an SDO frame without a node's context (a railway SDO frame of a board the table
/// does not name).
pub(in crate::capture::decode) fn without_context(
    side: SdoSide,
    frame: &Frame,
) -> Result<SdoInfo, String> {
    step(&mut Track::default(), side, frame)
}

/// The eight bytes of an SDO frame.
fn bytes(frame: &Frame) -> Result<[u8; 8], String> {
    let d = frame.data();
    match (frame.is_remote(), <[u8; 8]>::try_from(d)) {
        (false, Ok(b)) => Ok(b),
        _ => Err(wrong_length(frame, "an SDO frame", "8")),
    }
}

/// Decodes one frame of `side` in `track`'s transfer and moves the transfer on.
fn step(track: &mut Track, side: SdoSide, frame: &Frame) -> Result<SdoInfo, String> {
    let d = bytes(frame)?;
    let info = |track: &Track, step| SdoInfo {
        side,
        service: track.service,
        object: track.object(),
        step,
    };
    if track.segment_expected(side) && !codec::is_abort_in_block(&d) {
        let s = BlockSegment::decode(&d);
        if s.last {
            track.phase = Phase::BlockLastSent;
        }
        track.last_seqno = s.seqno;
        let number = Some(track.segments + s.seqno as u32);
        return Ok(info(
            track,
            SdoStep::BlockSegment {
                seqno: s.seqno,
                number,
                last: s.last,
            },
        ));
    }
    let step = match side {
        SdoSide::Client => match Request::decode(&d) {
            Ok(r) => client(track, r),
            Err(_) => SdoStep::BadCommand { byte: d[0] },
        },
        SdoSide::Server => match Response::decode(&d) {
            Ok(r) => server(track, r),
            Err(_) => SdoStep::BadCommand { byte: d[0] },
        },
    };
    let out = info(track, step);
    // An abort or a finished block transfer ends the transfer, after its line named it.
    if matches!(
        step,
        SdoStep::Abort { .. } | SdoStep::BlockEndConfirmed | SdoStep::BadCommand { .. }
    ) {
        *track = Track::default();
    }
    Ok(out)
}

/// What an initiate frame says: the value, or a segmented transfer's size.
fn initiated(init: Init) -> SdoStep {
    match init {
        Init::Expedited { data, len } => SdoStep::Value { data, len },
        Init::Segmented { size } => SdoStep::Segmented { size },
    }
}

/// A data segment of a plain transfer of `service` (context or not).
fn segment(track: &mut Track, service: SdoService, len: u8, last: bool) -> SdoStep {
    if track.phase != Phase::Plain || track.service != Some(service) {
        *track = Track {
            service: Some(service),
            ..Track::default()
        };
        return SdoStep::Segment {
            number: None,
            len,
            last,
            total: None,
        };
    }
    track.segments += 1;
    track.bytes += len as u32;
    SdoStep::Segment {
        number: Some(track.segments),
        len,
        last,
        total: last.then_some(track.bytes),
    }
}

/// The number of the segment a request asks for or a confirmation confirms.
fn ack_number(track: &Track, service: SdoService, next: bool) -> Option<u32> {
    (track.phase == Phase::Plain && track.service == Some(service))
        .then_some(track.segments + next as u32)
}

/// A sub-block acknowledged: the segments count, and a short one makes the sender repeat.
fn block_ack(track: &mut Track, ackseq: u8) {
    if matches!(track.phase, Phase::BlockSegments | Phase::BlockLastSent) {
        track.segments += ackseq as u32;
        if track.phase == Phase::BlockLastSent && ackseq < track.last_seqno {
            track.phase = Phase::BlockSegments;
        }
    }
}

fn block_total(track: &Track, service: SdoService, unused: u8) -> Option<u32> {
    (track.service == Some(service) && track.phase == Phase::BlockLastSent)
        .then(|| (track.segments * SEGMENT_DATA as u32).saturating_sub(unused as u32))
}

fn client(t: &mut Track, r: Request) -> SdoStep {
    use SdoService::*;
    match r {
        Request::InitiateDownload { index, sub, init } => {
            t.start(Download, (index, sub), Phase::Plain);
            initiated(init)
        }
        Request::DownloadSegment { data, last, .. } => segment(t, Download, data.len, last),
        Request::InitiateUpload { index, sub } => {
            t.start(Upload, (index, sub), Phase::Plain);
            SdoStep::Request
        }
        Request::UploadSegment { toggle } => {
            let number = ack_number(t, Upload, true);
            if number.is_none() {
                t.service = Some(Upload);
            }
            SdoStep::SegmentAck { number, toggle }
        }
        Request::Abort { index, sub, code } => {
            t.object = (index, sub);
            t.phase = Phase::Plain;
            SdoStep::Abort { code }
        }
        Request::BlockUploadInitiate {
            index,
            sub,
            crc,
            blksize,
            ..
        } => {
            t.start(BlockUpload, (index, sub), Phase::BlockInit);
            SdoStep::BlockInit {
                size: None,
                blksize: Some(blksize),
                crc,
            }
        }
        Request::BlockUploadStart => {
            if t.service == Some(BlockUpload) {
                t.phase = Phase::BlockSegments;
            } else {
                t.service = Some(BlockUpload);
            }
            SdoStep::BlockStart
        }
        Request::BlockUploadAck { ackseq, blksize } => {
            t.service = Some(BlockUpload);
            block_ack(t, ackseq);
            SdoStep::BlockAck { ackseq, blksize }
        }
        Request::BlockUploadEnd => {
            t.service = Some(BlockUpload);
            SdoStep::BlockEndConfirmed
        }
        Request::BlockDownloadInitiate {
            index,
            sub,
            crc,
            size,
        } => {
            t.start(BlockDownload, (index, sub), Phase::BlockInit);
            SdoStep::BlockInit {
                size,
                blksize: None,
                crc,
            }
        }
        Request::BlockDownloadEnd { unused, crc } => {
            let total = block_total(t, BlockDownload, unused);
            t.service = Some(BlockDownload);
            SdoStep::BlockEnd { unused, crc, total }
        }
    }
}

fn server(t: &mut Track, r: Response) -> SdoStep {
    use SdoService::*;
    match r {
        Response::UploadSegment { data, last, .. } => segment(t, Upload, data.len, last),
        Response::DownloadSegment { toggle } => {
            let number = ack_number(t, Download, false);
            if number.is_none() {
                t.service = Some(Download);
            }
            SdoStep::SegmentAck { number, toggle }
        }
        Response::InitiateUpload { index, sub, init } => {
            // Also the answer to a block upload request under the protocol switch threshold.
            t.start(Upload, (index, sub), Phase::Plain);
            initiated(init)
        }
        Response::InitiateDownload { index, sub } => {
            t.start(Download, (index, sub), Phase::Plain);
            SdoStep::Accepted
        }
        Response::Abort { index, sub, code } => {
            t.object = (index, sub);
            t.phase = Phase::Plain;
            SdoStep::Abort { code }
        }
        Response::BlockDownloadInitiate {
            index,
            sub,
            crc,
            blksize,
        } => {
            t.start(BlockDownload, (index, sub), Phase::BlockSegments);
            SdoStep::BlockInit {
                size: None,
                blksize: Some(blksize),
                crc,
            }
        }
        Response::BlockDownloadAck { ackseq, blksize } => {
            t.service = Some(BlockDownload);
            block_ack(t, ackseq);
            SdoStep::BlockAck { ackseq, blksize }
        }
        Response::BlockDownloadEnd => {
            t.service = Some(BlockDownload);
            SdoStep::BlockEndConfirmed
        }
        Response::BlockUploadInitiate {
            index,
            sub,
            crc,
            size,
        } => {
            // The segments start with the client's start frame.
            t.start(BlockUpload, (index, sub), Phase::BlockInit);
            SdoStep::BlockInit {
                size,
                blksize: None,
                crc,
            }
        }
        Response::BlockUploadEnd { unused, crc } => {
            let total = block_total(t, BlockUpload, unused);
            t.service = Some(BlockUpload);
            SdoStep::BlockEnd { unused, crc, total }
        }
    }
}
