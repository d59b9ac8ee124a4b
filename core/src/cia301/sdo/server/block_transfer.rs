//! The server's block transfers (CiA 301 7.2.4.3.10 ff.): the initiates, the sub-blocks of a
//! download with their acknowledgements and end, and the start of an upload (its sub-blocks are
//! paced out by `poll_transmit` and acknowledged in `request`).

use super::{SdoServer, State};
use crate::cia301::sdo::block::{self, BlockReceiver, Received};
use crate::cia301::sdo::buffer::TransferBuffer;
use crate::cia301::sdo::codec::{Response, MAX_BLOCK_SIZE};
use crate::cia301::sdo::crc::crc16;
use crate::frame::instant::Instant;
use crate::od::abort::AbortCode;
use crate::od::ObjectAccess;

impl<B: TransferBuffer> SdoServer<B> {
    pub(super) fn initiate_block_download<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        crc: bool,
        size: Option<u32>,
        od: &mut A,
    ) {
        self.begin(now, index, sub);
        if !self.cfg.block {
            return self.abort(AbortCode::COMMAND_SPECIFIER);
        }
        if let Err(c) = self.prepare_download(size, od) {
            return self.abort(c);
        }
        let blksize = self.cfg.block_size.clamp(1, MAX_BLOCK_SIZE);
        self.respond(Response::BlockDownloadInitiate {
            index,
            sub,
            crc: self.cfg.crc,
            blksize,
        });
        self.state = State::BlockDownload {
            rx: BlockReceiver::new(blksize),
            crc: crc && self.cfg.crc,
            size,
        };
    }

    pub(super) fn block_segment(&mut self, now: Instant, d: &[u8; 8]) {
        let State::BlockDownload { mut rx, crc, size } = self.state else {
            return;
        };
        match rx.segment(d, &mut self.buf, self.bound) {
            Err(c) => self.abort(c),
            Ok(r) => {
                self.state = State::BlockDownload { rx, crc, size };
                self.touch(now);
                match r {
                    Received::Duplicate => {}
                    Received::Continue => {
                        self.subblock_deadline = Some(now + self.cfg.subblock_timeout)
                    }
                    Received::Ack(ackseq) => self.ack_sub_block(ackseq, rx.blksize()),
                }
            }
        }
    }

    pub(super) fn ack_sub_block(&mut self, ackseq: u8, blksize: u8) {
        self.subblock_deadline = None;
        self.respond(Response::BlockDownloadAck { ackseq, blksize });
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn block_download_end<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        mut rx: BlockReceiver,
        unused: u8,
        crc: u16,
        use_crc: bool,
        size: Option<u32>,
        od: &mut A,
    ) {
        if let Err(c) = rx.finish(unused, &mut self.buf, self.bound) {
            return self.abort(c);
        }
        let len = self.buf.len();
        if let Some(s) = size {
            if len != s as usize {
                return self.abort(if len > s as usize {
                    AbortCode::LENGTH_TOO_HIGH
                } else {
                    AbortCode::LENGTH_TOO_LOW
                });
            }
        }
        if use_crc && crc16(self.buf.as_slice()) != crc {
            return self.abort(AbortCode::CRC_ERROR);
        }
        match od.write(now, self.index, self.sub, self.buf.as_slice()) {
            Ok(()) => {
                self.respond(Response::BlockDownloadEnd);
                self.complete();
            }
            Err(c) => self.abort(c),
        }
    }

    /// The client's CRC bit is not consulted: CiA 301 has the end frame carry a CRC whenever
    /// the server announces support, and clients (python `canopen` among them) check it then
    /// even if they did not ask, so a server that sets the bit sends the real CRC.
    pub(super) fn initiate_block_upload<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        blksize: u8,
        pst: u8,
        od: &mut A,
    ) {
        self.begin(now, index, sub);
        if !self.cfg.block {
            return self.abort(AbortCode::COMMAND_SPECIFIER);
        }
        if !block::valid_block_size(blksize) {
            return self.abort(AbortCode::INVALID_BLOCK_SIZE);
        }
        if let Err(c) = self.snapshot(od) {
            return self.abort(c);
        }
        let len = self.buf.len();
        // Protocol switch: small data goes faster expedited or segmented.
        if pst != 0 && len <= pst as usize {
            return self.start_upload();
        }
        self.respond(Response::BlockUploadInitiate {
            index,
            sub,
            crc: self.cfg.crc,
            size: Some(len as u32),
        });
        self.state = State::BlockUploadStart {
            crc: self.cfg.crc,
            blksize,
        };
    }
}
