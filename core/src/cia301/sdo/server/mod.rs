//! The SDO server: one channel (0x1200), expedited, segmented and block transfer over a node's
//! dictionary, reached through [`ObjectAccess`] so that every bus-side rule applies (access
//! rights, type, length, limits, hooks, the stack's reactions to writes).
//!
//! Segmented and block downloads collect into the transfer buffer and write the entry once, when
//! the whole value arrived: an aborted or timed-out download leaves the dictionary unchanged.
//! An upload copies the value into the buffer when it starts, so the client reads one consistent
//! snapshot even if the entry changes during the transfer.
//!
//! A new initiate request ends any transfer in progress: the channel has one client, and a client
//! that starts over has given up on the old transfer (its abort may have been lost).
//!
//! # Second copies
//!
//! CAN may deliver a frame twice, and on a redundant network the dual-bus layer delivers a twin
//! that arrives later than its merge window as a frame of its own. A request equal to the one
//! before it (across transfers: the last request of a finished transfer counts) that the
//! transfer could not take, such as a segment with the old toggle bit or an end request after
//! the end, is such a copy: it is ignored and counted ([`SdoServerStats::repeats`]), not
//! aborted. A copy that arrives after the client's next frame can no longer be told from a
//! new request; the client's next frame then finds the transfer as the protocol leaves it (an
//! abort, or for block transfer the CRC).

use super::block::Bound;
#[cfg(feature = "sdo-block")]
use super::block::{self, Acked, BlockReceiver, BlockSender};
use super::buffer::{DefaultBuffer, TransferBuffer};
use super::codec::{self, Init, Request, Response, SegmentData};
#[cfg(feature = "sdo-block")]
use super::crc::crc16;
use crate::frame::cob_id::{predefined, CobId, NodeId};
use crate::frame::instant::{earliest, shift_back, Duration, Instant};
use crate::frame::queue::Bounded;
use crate::frame::Malformed;
use crate::frame::{Frame, Id};
use crate::od::abort::AbortCode;
use crate::od::ObjectAccess;
use crate::od::{comm, ObjectDictionary};

#[cfg(feature = "sdo-block")]
mod block_transfer;
mod config;

pub use config::SdoServerConfig;

/// Counters of a server.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SdoServerStats {
    /// Transfers completed.
    pub completed: u32,
    /// Transfers this server aborted (abort frame sent).
    pub aborted: u32,
    /// Transfers the client aborted.
    pub client_aborts: u32,
    /// Frames refused as malformed (wrong length, remote).
    pub malformed: u32,
    /// Frames dropped because the output was not drained.
    pub tx_dropped: u32,
    /// Second copies ignored: a request equal to the one before it that the transfer could not
    /// take (a twin the dual-bus layer delivered late, a frame CAN delivered twice), or a
    /// sub-block acknowledgement after the last one.
    pub repeats: u32,
}

#[derive(Clone, Copy, Debug)]
enum State {
    Idle,
    Download {
        toggle: bool,
        size: Option<u32>,
    },
    Upload {
        toggle: bool,
        offset: usize,
    },
    #[cfg(feature = "sdo-block")]
    BlockDownload {
        rx: BlockReceiver,
        crc: bool,
        size: Option<u32>,
    },
    // Block upload: `crc` is whether the end frame carries the real CRC; it follows the bit
    // the server announced, not the client's request.
    #[cfg(feature = "sdo-block")]
    BlockUploadStart {
        crc: bool,
        blksize: u8,
    },
    #[cfg(feature = "sdo-block")]
    BlockUpload {
        tx: BlockSender,
        crc: bool,
    },
    #[cfg(feature = "sdo-block")]
    BlockUploadEnd,
}

/// A sans-IO SDO server. The node that owns it hands it the frames of its channel and its
/// dictionary; it queues its answers (and paces block-upload segments) for `poll_transmit`.
pub struct SdoServer<B: TransferBuffer = DefaultBuffer> {
    cfg: SdoServerConfig,
    rx: Option<Id>,
    tx: Option<Id>,
    state: State,
    index: u16,
    sub: u8,
    buf: B,
    bound: Bound,
    deadline: Option<Instant>,
    #[cfg(feature = "sdo-block")]
    subblock_deadline: Option<Instant>,
    out: Bounded<[u8; 8], 4>,
    /// The request frame handled last, across transfers: its second copy is recognised.
    last_rx: Option<[u8; 8]>,
    stats: SdoServerStats,
}

impl<B: TransferBuffer> SdoServer<B> {
    /// A server without a channel (see [`SdoServer::set_channel`] and
    /// [`SdoServer::configure_from`]).
    #[must_use]
    pub fn new(cfg: SdoServerConfig) -> Self {
        SdoServer {
            cfg,
            rx: None,
            tx: None,
            state: State::Idle,
            index: 0,
            sub: 0,
            buf: B::with_limit(cfg.max_transfer),
            bound: Bound {
                max: 0,
                code: AbortCode::OUT_OF_MEMORY,
            },
            deadline: None,
            #[cfg(feature = "sdo-block")]
            subblock_deadline: None,
            out: Bounded::new(),
            last_rx: None,
            stats: SdoServerStats::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SdoServerConfig {
        &self.cfg
    }
    /// Changes the configuration; a transfer in progress is dropped.
    pub fn set_config(&mut self, cfg: SdoServerConfig) {
        self.cancel();
        self.cfg = cfg;
        self.buf.set_limit(cfg.max_transfer);
    }
    /// Counters.
    pub fn stats(&self) -> SdoServerStats {
        SdoServerStats {
            tx_dropped: self.out.dropped(),
            ..self.stats
        }
    }
    /// The identifier requests arrive on, if the channel is valid.
    pub fn rx_id(&self) -> Option<Id> {
        self.rx
    }
    /// The identifier answers go out on.
    pub fn tx_id(&self) -> Option<Id> {
        self.tx
    }
    /// True when no transfer is in progress.
    pub fn is_idle(&self) -> bool {
        matches!(self.state, State::Idle)
    }
    /// Bytes in the transfer buffer (never above [`SdoServer::buffer_limit`]).
    pub fn buffer_len(&self) -> usize {
        self.buf.len()
    }
    /// The transfer buffer's limit.
    pub fn buffer_limit(&self) -> usize {
        self.buf.limit()
    }

    /// Sets the channel: requests on `rx`, answers on `tx` (`None`: no server).
    pub fn set_channel(&mut self, rx: Option<Id>, tx: Option<Id>) {
        self.cancel();
        let both = rx.is_some() && tx.is_some();
        self.rx = rx.filter(|_| both);
        self.tx = tx.filter(|_| both);
    }

    /// Reads the channel from the SDO server parameter 0x1200 (sub 1: client → server, sub 2:
    /// server → client). A dictionary without 0x1200 gets the predefined 0x600/0x580 + node-ID;
    /// an invalid COB-ID (bit 31) disables the server.
    pub fn configure_from<D: ObjectDictionary>(&mut self, od: &D, node: NodeId) {
        let id = |sub: u8, default: Id| match od.get_u32(comm::SDO_SERVER, sub) {
            Some(v) if CobId(v).is_valid() => CobId(v).can_id(),
            Some(_) => None,
            None => Some(default),
        };
        let rx = id(1, predefined::sdo_rx(node));
        let tx = id(2, predefined::sdo_tx(node));
        self.set_channel(rx, tx);
    }

    /// Drops the transfer in progress without a word (the node left the states with SDO, or was
    /// reset), and whatever was waiting to be sent.
    pub fn cancel(&mut self) {
        self.reset();
        self.out.clear();
    }

    fn reset(&mut self) {
        self.state = State::Idle;
        self.index = 0;
        self.sub = 0;
        self.buf.clear();
        self.deadline = None;
        #[cfg(feature = "sdo-block")]
        {
            self.subblock_deadline = None;
        }
    }

    fn respond(&mut self, r: Response) {
        self.out.push(r.encode());
    }

    fn abort(&mut self, code: AbortCode) {
        self.out
            .push(codec::abort_frame(self.index, self.sub, code));
        self.stats.aborted += 1;
        self.reset();
    }

    /// Refuses a request: with an abort, unless it is a second copy of the request before it
    /// (see the module docs), which is only counted.
    fn refuse(&mut self, repeat: bool, code: AbortCode) {
        if repeat {
            self.stats.repeats += 1;
        } else {
            self.abort(code);
        }
    }

    fn complete(&mut self) {
        self.stats.completed += 1;
        self.reset();
    }

    /// Starts a new transfer on (index, sub), ending any other.
    fn begin(&mut self, now: Instant, index: u16, sub: u8) {
        self.reset();
        self.index = index;
        self.sub = sub;
        self.deadline = Some(now + self.cfg.timeout);
    }

    fn touch(&mut self, now: Instant) {
        self.deadline = Some(now + self.cfg.timeout);
    }

    /// A frame on the server's channel. Frames that are not SDO frames at all (remote, not 8
    /// bytes) are refused without an answer; every other frame is answered as CiA 301 says.
    pub fn handle_frame<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        frame: &Frame,
        od: &mut A,
    ) -> Result<(), Malformed> {
        if frame.is_remote() {
            self.stats.malformed += 1;
            return Err(Malformed::UnexpectedRemote);
        }
        let Ok(d) = <[u8; 8]>::try_from(frame.data()) else {
            self.stats.malformed += 1;
            return Err(Malformed::WrongLength {
                expected: 8,
                got: frame.dlc(),
            });
        };
        let repeat = self.last_rx.replace(d) == Some(d);
        #[cfg(feature = "sdo-block")]
        if let State::BlockDownload { rx, .. } = self.state {
            if rx.is_repeat(&d) {
                return Ok(());
            }
            if repeat {
                // Two segments in a row are never equal (sequence numbers count up, and a
                // sub-block of one is `is_repeat`); the initiate's copy would read as a segment.
                self.stats.repeats += 1;
                return Ok(());
            }
            if !rx.complete() {
                if codec::is_abort_in_block(&d) {
                    self.client_abort();
                } else {
                    self.block_segment(now, &d);
                }
                return Ok(());
            }
        }
        match Request::decode(&d) {
            Ok(r) => self.request(now, r, repeat, od),
            Err(code) => {
                if self.is_idle() {
                    self.index = u16::from_le_bytes([d[1], d[2]]);
                    self.sub = d[3];
                }
                self.abort(code);
            }
        }
        Ok(())
    }

    fn client_abort(&mut self) {
        if !self.is_idle() {
            self.stats.client_aborts += 1;
        }
        self.reset();
    }

    fn request<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        r: Request,
        repeat: bool,
        od: &mut A,
    ) {
        match (r, self.state) {
            (Request::Abort { .. }, _) => self.client_abort(),
            (Request::InitiateDownload { index, sub, init }, _) => {
                self.initiate_download(now, index, sub, init, od)
            }
            (Request::InitiateUpload { index, sub }, _) => {
                self.begin(now, index, sub);
                if let Err(c) = self.snapshot(od) {
                    return self.abort(c);
                }
                self.start_upload();
            }
            #[cfg(feature = "sdo-block")]
            (
                Request::BlockDownloadInitiate {
                    index,
                    sub,
                    crc,
                    size,
                },
                _,
            ) => self.initiate_block_download(now, index, sub, crc, size, od),
            #[cfg(feature = "sdo-block")]
            (
                Request::BlockUploadInitiate {
                    index,
                    sub,
                    blksize,
                    pst,
                    ..
                },
                _,
            ) => self.initiate_block_upload(now, index, sub, blksize, pst, od),
            // Without block transfer: what a server configured without it answers (the
            // command specifier is unknown to it), naming the entry asked for.
            #[cfg(not(feature = "sdo-block"))]
            (
                Request::BlockDownloadInitiate { index, sub, .. }
                | Request::BlockUploadInitiate { index, sub, .. },
                _,
            ) => {
                self.begin(now, index, sub);
                self.abort(AbortCode::COMMAND_SPECIFIER)
            }
            (
                Request::DownloadSegment { toggle, data, last },
                State::Download { toggle: t, size },
            ) => {
                if toggle != t {
                    return self.refuse(repeat, AbortCode::TOGGLE_BIT);
                }
                self.download_segment(now, toggle, data, last, size, od)
            }
            (Request::UploadSegment { toggle }, State::Upload { toggle: t, offset }) => {
                if toggle != t {
                    return self.refuse(repeat, AbortCode::TOGGLE_BIT);
                }
                let len = self.buf.len();
                let end = (offset + codec::SEGMENT_DATA).min(len);
                let data = SegmentData::from_slice(&self.buf.as_slice()[offset..end]);
                let last = end == len;
                self.respond(Response::UploadSegment { toggle, data, last });
                if last {
                    self.complete();
                } else {
                    self.state = State::Upload {
                        toggle: !toggle,
                        offset: end,
                    };
                    self.touch(now);
                }
            }
            #[cfg(feature = "sdo-block")]
            (
                Request::BlockDownloadEnd { unused, crc },
                State::BlockDownload {
                    rx,
                    crc: use_crc,
                    size,
                },
            ) => self.block_download_end(now, rx, unused, crc, use_crc, size, od),
            #[cfg(feature = "sdo-block")]
            (Request::BlockUploadStart, State::BlockUploadStart { crc, blksize }) => {
                self.state = State::BlockUpload {
                    tx: BlockSender::new(self.buf.len(), blksize),
                    crc,
                };
                self.touch(now);
            }
            #[cfg(feature = "sdo-block")]
            (Request::BlockUploadAck { ackseq, blksize }, State::BlockUpload { mut tx, crc }) => {
                match tx.ack(ackseq, blksize) {
                    Err(c) => self.refuse(repeat, c),
                    Ok(None) => {}
                    Ok(Some(Acked::More)) => {
                        self.state = State::BlockUpload { tx, crc };
                        self.touch(now);
                    }
                    Ok(Some(Acked::Done)) => {
                        let len = self.buf.len();
                        let crc = if crc { crc16(self.buf.as_slice()) } else { 0 };
                        self.respond(Response::BlockUploadEnd {
                            unused: block::unused(len),
                            crc,
                        });
                        self.state = State::BlockUploadEnd;
                        self.touch(now);
                    }
                }
            }
            #[cfg(feature = "sdo-block")]
            (Request::BlockUploadEnd, State::BlockUploadEnd) => self.complete(),
            // The end frame answered the last acknowledgement; one more comes only late (a
            // second copy of an earlier one taken for the last): the end request follows it.
            #[cfg(feature = "sdo-block")]
            (Request::BlockUploadAck { .. }, State::BlockUploadEnd) => self.stats.repeats += 1,
            _ => self.refuse(repeat, AbortCode::COMMAND_SPECIFIER),
        }
    }

    /// Checks an announced download size against the entry and the buffer.
    fn check_size(
        &self,
        fixed: Option<usize>,
        entry_max: usize,
        size: u32,
    ) -> Result<(), AbortCode> {
        let size = size as usize;
        match fixed {
            Some(n) if size > n => return Err(AbortCode::LENGTH_TOO_HIGH),
            Some(n) if size < n => return Err(AbortCode::LENGTH_TOO_LOW),
            None if size > entry_max => return Err(AbortCode::LENGTH_TOO_HIGH),
            _ => {}
        }
        if size > self.buf.limit() {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        Ok(())
    }

    /// Looks up a download target: it must exist and be writable from the bus. Returns its
    /// fixed size (if any) and its storage size.
    fn target<A: ObjectAccess + ?Sized>(
        &self,
        od: &A,
    ) -> Result<(Option<usize>, usize), AbortCode> {
        let e = od.entry(self.index, self.sub)?;
        if !e.def.access.writable() {
            return Err(AbortCode::READ_ONLY);
        }
        Ok((e.def.data_type.fixed_size(), e.def.storage_size()))
    }

    /// Prepares a segmented or block download of (at most) `size` bytes.
    fn prepare_download<A: ObjectAccess + ?Sized>(
        &mut self,
        size: Option<u32>,
        od: &A,
    ) -> Result<(), AbortCode> {
        let (fixed, entry_max) = self.target(od)?;
        if let Some(s) = size {
            self.check_size(fixed, entry_max, s)?;
            self.buf.reserve(s as usize);
        }
        let limit = self.buf.limit();
        self.bound = if limit < entry_max {
            Bound {
                max: limit,
                code: AbortCode::OUT_OF_MEMORY,
            }
        } else {
            Bound {
                max: entry_max,
                code: AbortCode::LENGTH_TOO_HIGH,
            }
        };
        if let Some(s) = size {
            // Data past the announced size is too much even where the entry would hold it.
            if (s as usize) < self.bound.max {
                self.bound = Bound {
                    max: s as usize,
                    code: AbortCode::LENGTH_TOO_HIGH,
                };
            }
        }
        Ok(())
    }

    fn initiate_download<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        init: Init,
        od: &mut A,
    ) {
        self.begin(now, index, sub);
        match init {
            Init::Expedited { data, len } => {
                let n = match len {
                    Some(l) => l as usize,
                    // Size not indicated: as many bytes as the entry's type has, up to four.
                    None => match self.target(od) {
                        Ok((Some(n), _)) if n <= 4 => n,
                        Ok(_) => 4,
                        Err(c) => return self.abort(c),
                    },
                };
                match od.write(now, index, sub, &data[..n.min(4)]) {
                    Ok(()) => {
                        self.respond(Response::InitiateDownload { index, sub });
                        self.complete();
                    }
                    Err(c) => self.abort(c),
                }
            }
            Init::Segmented { size } => {
                if let Err(c) = self.prepare_download(size, od) {
                    return self.abort(c);
                }
                self.respond(Response::InitiateDownload { index, sub });
                self.state = State::Download {
                    toggle: false,
                    size,
                };
            }
        }
    }

    fn download_segment<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        toggle: bool,
        data: SegmentData,
        last: bool,
        size: Option<u32>,
        od: &mut A,
    ) {
        let bytes = data.bytes();
        if self.buf.len() + bytes.len() > self.bound.max || !self.buf.extend(bytes) {
            return self.abort(self.bound.code);
        }
        if !last {
            self.respond(Response::DownloadSegment { toggle });
            self.state = State::Download {
                toggle: !toggle,
                size,
            };
            return self.touch(now);
        }
        if size.is_some_and(|s| self.buf.len() < s as usize) {
            return self.abort(AbortCode::LENGTH_TOO_LOW);
        }
        match od.write(now, self.index, self.sub, self.buf.as_slice()) {
            Ok(()) => {
                self.respond(Response::DownloadSegment { toggle });
                self.complete();
            }
            Err(c) => self.abort(c),
        }
    }

    /// Copies the value into the buffer: the upload reads this snapshot.
    fn snapshot<A: ObjectAccess + ?Sized>(&mut self, od: &A) -> Result<(), AbortCode> {
        let data = od.read(self.index, self.sub)?;
        if data.len() > self.buf.limit() {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        self.buf.clear();
        self.buf.reserve(data.len());
        if !self.buf.extend(data) {
            return Err(AbortCode::OUT_OF_MEMORY);
        }
        Ok(())
    }

    /// Answers an upload initiate from the snapshot: expedited for 1–4 bytes, else segmented.
    fn start_upload(&mut self) {
        let (index, sub) = (self.index, self.sub);
        let len = self.buf.len();
        if let Some(init) = Init::expedited(self.buf.as_slice()) {
            self.respond(Response::InitiateUpload { index, sub, init });
            return self.complete();
        }
        self.respond(Response::InitiateUpload {
            index,
            sub,
            init: Init::Segmented {
                size: Some(len as u32),
            },
        });
        self.state = State::Upload {
            toggle: false,
            offset: 0,
        };
    }

    /// Time passed: acknowledge an incomplete sub-block, or abort a transfer the client left.
    pub fn handle_timeout(&mut self, now: Instant) {
        #[cfg(feature = "sdo-block")]
        if self.subblock_deadline.is_some_and(|t| t <= now) {
            self.subblock_deadline = None;
            if let State::BlockDownload { mut rx, crc, size } = self.state {
                if rx.in_sub_block() {
                    let ack = rx.timeout();
                    self.state = State::BlockDownload { rx, crc, size };
                    self.ack_sub_block(ack, rx.blksize());
                }
            }
        }
        if self.deadline.is_some_and(|t| t <= now) {
            #[cfg(feature = "sdo-block")]
            if matches!(self.state, State::BlockUpload { tx, .. } if tx.is_sending()) {
                // The driver has not taken the whole sub-block yet (a slow bus): the client
                // cannot have answered, so the wait starts over.
                return self.touch(now);
            }
            self.abort(AbortCode::TIMEOUT);
        }
    }

    /// Earliest instant `handle_timeout` has work.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        earliest(self.deadline, self.subblock_deadline())
    }

    /// When an incomplete sub-block is acknowledged.
    #[cfg(feature = "sdo-block")]
    fn subblock_deadline(&self) -> Option<Instant> {
        self.subblock_deadline
    }
    /// Never: no block transfer.
    #[cfg(not(feature = "sdo-block"))]
    fn subblock_deadline(&self) -> Option<Instant> {
        None
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.deadline, by);
        #[cfg(feature = "sdo-block")]
        shift_back(&mut self.subblock_deadline, by);
    }

    /// The next frame to send: an answer, or the next segment of a block upload.
    #[must_use]
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        let id = self.tx?;
        if let Some(d) = self.out.pop() {
            return Some(Frame::from_array(id, d));
        }
        #[cfg(feature = "sdo-block")]
        if let State::BlockUpload { ref mut tx, .. } = self.state {
            return tx
                .next_segment(self.buf.as_slice())
                .map(|d| Frame::from_array(id, d));
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia301::sdo::buffer::{InlineBuffer, INLINE_CAPACITY};

    #[test]
    fn a_no_std_server_costs_its_buffer_and_little_more() {
        let inline = core::mem::size_of::<SdoServer<InlineBuffer<INLINE_CAPACITY>>>();
        let heap = core::mem::size_of::<SdoServer>();
        println!("SDO server: {inline} bytes with an inline buffer of {INLINE_CAPACITY}, {heap} bytes with the default buffer");
        assert!(inline <= INLINE_CAPACITY + 256, "{inline}");
    }
}
