//! The server's answers to a session: each frame on the session's channel, checked against
//! the state it finds the transfer in, the next request queued or the result given; second
//! copies recognised as the client's module docs say.

use super::SdoClient;
use crate::cia301::sdo::block::{self, Acked, BlockReceiver, BlockSender, Received};
use crate::cia301::sdo::buffer::TransferBuffer;
use crate::cia301::sdo::codec::{self, Init, Request, Response, MAX_BLOCK_SIZE};
use crate::cia301::sdo::error::SdoErrorKind;
use crate::cia301::sdo::request::TransferMode;
use crate::cia301::sdo::session::{
    next_download_segment, prepare_upload, start_download, upload_segment, Session, State,
};
use crate::cia301::sdo::stream;
use crate::frame::instant::Instant;
use crate::frame::storage::Storage;
use crate::frame::Frame;
use crate::od::abort::AbortCode;

impl<B: TransferBuffer, const SESSIONS: usize, S: Storage> SdoClient<B, SESSIONS, S> {
    pub(super) fn session_frame(&mut self, i: usize, now: Instant, frame: &Frame) {
        let Some(d) = (!frame.is_remote())
            .then(|| <[u8; 8]>::try_from(frame.data()).ok())
            .flatten()
        else {
            self.stats.malformed += 1;
            return;
        };
        let s = &mut self.sessions[i];
        let repeat = s.last_rx.replace(d) == Some(d);
        if let State::BlockUpload { mut rx, crc, size } = s.state {
            if rx.is_repeat(&d) {
                return;
            }
            if repeat {
                // As in the server: two segments in a row are never equal, and the initiate
                // answer's copy would read as a segment.
                self.stats.repeats += 1;
                return;
            }
            if !rx.complete() {
                if codec::is_abort_in_block(&d) {
                    return self.finish(i, now, Err(SdoErrorKind::Server(codec::abort_code(&d))));
                }
                return match rx.segment(&d, &mut s.buf, s.bound) {
                    Err(c) => self.abort_session(i, now, c),
                    // More than the server announced is an error at once, not at the end: a
                    // streamed upload would otherwise hand the excess to its reader.
                    Ok(_) if size.is_some_and(|n| stream::received(s) > n as usize) => {
                        self.abort_session(i, now, AbortCode::LENGTH_TOO_HIGH)
                    }
                    Ok(r) => {
                        s.state = State::BlockUpload { rx, crc, size };
                        s.touch(now);
                        match r {
                            Received::Duplicate => {}
                            Received::Continue => {
                                s.subblock_deadline = Some(now + s.opts.subblock_timeout)
                            }
                            Received::Ack(ackseq) => {
                                s.subblock_deadline = None;
                                upload_ack(s, ackseq, rx.blksize());
                            }
                        }
                    }
                };
            }
        }
        match Response::decode(&d) {
            Ok(r) => self.response(i, now, r, repeat),
            Err(c) => self.abort_session(i, now, c),
        }
    }

    /// An answer to session `i`; `repeat`: it equals the answer before it on the channel.
    fn response(&mut self, i: usize, now: Instant, r: Response, repeat: bool) {
        let s = &mut self.sessions[i];
        if named_object(&r).is_some_and(|o| o != (s.index, s.sub)) {
            // An initiate answer about another object answers an earlier request on the
            // channel (see the client's module docs): not this transfer's business.
            s.stale = true;
            self.stats.stale += 1;
            return;
        }
        let step: Result<Option<()>, AbortCode> = match (r, s.state) {
            (Response::Abort { code, .. }, State::BlockDownloadInit)
                if code == AbortCode::COMMAND_SPECIFIER =>
            {
                // The server does not know block transfer: fall back.
                self.stats.fallbacks += 1;
                let small = s.stream.is_none() && (1..=4).contains(&s.buf.len());
                start_download(
                    s,
                    if small {
                        TransferMode::Expedited
                    } else {
                        TransferMode::Segmented
                    },
                );
                Ok(None)
            }
            (Response::Abort { code, .. }, State::BlockUploadInit)
                if code == AbortCode::COMMAND_SPECIFIER =>
            {
                self.stats.fallbacks += 1;
                s.mode = TransferMode::Segmented;
                let (index, sub) = (s.index, s.sub);
                s.request(Request::InitiateUpload { index, sub });
                s.state = State::UploadInit;
                Ok(None)
            }
            (Response::Abort { code, .. }, _) => {
                return self.finish(i, now, Err(SdoErrorKind::Server(code)));
            }
            (Response::InitiateDownload { .. }, State::DownloadInit { expedited }) => {
                if expedited {
                    Ok(Some(()))
                } else {
                    next_download_segment(s, false, 0);
                    Ok(None)
                }
            }
            (
                Response::DownloadSegment { toggle },
                State::DownloadSegment {
                    toggle: t,
                    offset,
                    last,
                },
            ) => {
                if toggle != t {
                    Err(AbortCode::TOGGLE_BIT)
                } else if last {
                    Ok(Some(()))
                } else {
                    next_download_segment(s, !t, offset);
                    Ok(None)
                }
            }
            (Response::BlockDownloadInitiate { crc, blksize, .. }, State::BlockDownloadInit) => {
                if !block::valid_block_size(blksize) {
                    Err(AbortCode::INVALID_BLOCK_SIZE)
                } else {
                    s.state = State::BlockDownload {
                        tx: BlockSender::new(stream::send_len(s), blksize),
                        crc: crc && s.opts.crc,
                    };
                    Ok(None)
                }
            }
            (
                Response::BlockDownloadAck { ackseq, blksize },
                State::BlockDownload { mut tx, crc },
            ) => match tx.ack(ackseq, blksize) {
                Err(c) => Err(c),
                Ok(None) => Ok(None),
                Ok(Some(Acked::More)) => {
                    stream::confirmed(s, tx.acked_bytes());
                    s.state = State::BlockDownload { tx, crc };
                    Ok(None)
                }
                Ok(Some(Acked::Done)) => {
                    let (len, sum) = stream::length_and_crc(s);
                    stream::confirmed(s, len);
                    let end = Request::BlockDownloadEnd {
                        unused: block::unused(len),
                        crc: if crc { sum } else { 0 },
                    };
                    s.request(end);
                    s.state = State::BlockDownloadEnd;
                    Ok(None)
                }
            },
            (Response::BlockDownloadEnd, State::BlockDownloadEnd) => Ok(Some(())),
            (Response::BlockDownloadAck { .. }, State::BlockDownloadEnd) => {
                // The end request answered the last acknowledgement; one more comes only late
                // (a second copy of an earlier one taken for the last): the end answer follows.
                self.stats.repeats += 1;
                return;
            }
            (Response::InitiateUpload { init, .. }, State::UploadInit | State::BlockUploadInit) => {
                match init {
                    Init::Expedited { data, len } => {
                        s.mode = TransferMode::Expedited;
                        let n = len.unwrap_or(4) as usize;
                        let _ = s.buf.extend(&data[..n.min(4)]);
                        Ok(Some(()))
                    }
                    Init::Segmented { size } => {
                        s.mode = TransferMode::Segmented;
                        prepare_upload(s, size).map(|()| {
                            s.request(Request::UploadSegment { toggle: false });
                            s.state = State::UploadSegment {
                                toggle: false,
                                size,
                            };
                            None
                        })
                    }
                }
            }
            (
                Response::UploadSegment { toggle, data, last },
                State::UploadSegment { toggle: t, size },
            ) => upload_segment(s, toggle, t, data, last, size),
            (Response::BlockUploadInitiate { crc, size, .. }, State::BlockUploadInit) => {
                prepare_upload(s, size).map(|()| {
                    s.request(Request::BlockUploadStart);
                    s.state = State::BlockUpload {
                        rx: BlockReceiver::new(s.opts.block_size.clamp(1, MAX_BLOCK_SIZE)),
                        crc: crc && s.opts.crc,
                        size,
                    };
                    None
                })
            }
            (
                Response::BlockUploadEnd { unused, crc },
                State::BlockUpload {
                    mut rx,
                    crc: use_crc,
                    size,
                },
            ) => match rx.finish(unused, &mut s.buf, s.bound) {
                Err(c) => Err(c),
                Ok(()) => {
                    let (len, sum) = stream::length_and_crc(s);
                    match size {
                        Some(n) if len > n as usize => Err(AbortCode::LENGTH_TOO_HIGH),
                        Some(n) if len < n as usize => Err(AbortCode::LENGTH_TOO_LOW),
                        _ if use_crc && sum != crc => Err(AbortCode::CRC_ERROR),
                        _ => {
                            s.request(Request::BlockUploadEnd);
                            Ok(Some(()))
                        }
                    }
                }
            },
            _ => Err(AbortCode::COMMAND_SPECIFIER),
        };
        match step {
            // A second copy the transfer cannot take: the first was handled, nothing changed.
            Err(_) if repeat => self.stats.repeats += 1,
            Err(c) => self.abort_session(i, now, c),
            Ok(Some(())) => self.finish(i, now, Ok(())),
            Ok(None) => self.sessions[i].touch(now),
        }
    }
}

/// The object an initiate answer names; other answers name none (an abort does, but a server
/// may fill it from an earlier transfer when it could not read the request, so an abort is
/// always the transfer's).
fn named_object(r: &Response) -> Option<(u16, u8)> {
    match *r {
        Response::InitiateUpload { index, sub, .. }
        | Response::InitiateDownload { index, sub }
        | Response::BlockDownloadInitiate { index, sub, .. }
        | Response::BlockUploadInitiate { index, sub, .. } => Some((index, sub)),
        _ => None,
    }
}

/// Acknowledges a sub-block of a block upload; a streamed one waits for room for the next
/// sub-block and the held-back last segment.
pub(super) fn upload_ack<B: TransferBuffer>(s: &mut Session<B>, ackseq: u8, blksize: u8) {
    let room = (usize::from(blksize) + 1) * codec::SEGMENT_DATA;
    stream::request_room(s, Request::BlockUploadAck { ackseq, blksize }, room);
}
