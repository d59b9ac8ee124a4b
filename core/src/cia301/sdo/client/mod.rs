//! The SDO client: up to `SESSIONS` transfers at once, to different servers, one per server at a time.
//!
//! A sans-IO [`Machine`] of its own, composed with the master's [`crate::Node`] through
//! [`crate::machine::Composite`]. Requests return a [`RequestId`] at once; the result arrives as an
//! [`SdoEvent`] carrying that id, the node, the object and either the data or an [`SdoError`].
//!
//! ```
//! use duocan_core::sdo::{Channel, SdoClient, SdoOptions, TransferMode};
//! use duocan_core::{Instant, Machine, NodeId};
//!
//! let mut client: SdoClient = SdoClient::new(64 * 1024);
//! let node = NodeId::must(5);
//! let id = client.upload(Instant::ZERO, node, 0x1018, 1, SdoOptions::default()).unwrap();
//! let f = client.poll_transmit().unwrap();
//! assert_eq!(f.id(), Channel::predefined(node).request);
//! assert_eq!(f.data(), [0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
//! // … the server's answer goes to client.handle_frame, the result comes from poll_event.
//! # let _ = (id, TransferMode::Auto);
//! ```
//!
//! # Second copies
//!
//! CAN may deliver a frame twice, and on a redundant network the dual-bus layer delivers a twin
//! that arrives later than its merge window as a frame of its own. An answer equal to the one
//! before it on its channel (across transfers on that channel) that the transfer could not
//! take, such as a segment with the old toggle bit, is such a copy: it is ignored and counted
//! ([`SdoClientStats::repeats`]), not aborted; so is a sub-block acknowledgement after the last
//! one. A copy that arrives after the server's next frame can no longer be told from a new
//! answer; the transfer then ends as the protocol says (an abort, or for block transfer the
//! CRC).
//!
//! # Late answers
//!
//! A bus that starts to lag hands over a run of copies after their window, so the answer to an
//! *earlier* transfer on the channel can come while the next one waits for its first answer.
//! Initiate answers name their object: one that names another object than the transfer's is
//! not its answer. It is ignored and counted ([`SdoClientStats::stale`]), and the transfer
//! waits on for its own. Only when none comes does it end, at its timeout, with 0x06040043
//! (general parameter incompatibility): what a server that names the wrong object gets, only
//! later. An abort ends the transfer whatever object it names: a server that could not read
//! the request may fill in the object of an earlier one.

use super::buffer::{DefaultBuffer, TransferBuffer};
use super::codec::{self, Request, MAX_BLOCK_SIZE};
use super::error::{Direction, SdoError, SdoErrorKind};
use super::request::{Channel, RequestId, SdoClientStats, SdoEvent, SdoOptions, TransferMode};
use super::session::{start_download, Session, State};
use super::stream;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest_of, shift_back, Instant, TimeWatch};
use crate::frame::queue::Fifo;
use crate::frame::storage::{Inline, Storage, Table};
use crate::frame::Frame;
use crate::machine::Machine;
use crate::od::abort::AbortCode;

mod answer;

use answer::upload_ack;

/// A sans-IO SDO client with `SESSIONS` sessions; transfer buffers of type `B`, each bounded by the
/// client's limit.
///
/// `S` is where the session table lives: [`Inline`] (the default) holds `SESSIONS` sessions
/// inside the client; [`Heap`](crate::frame::storage::Heap) (`alloc`) allocates them once when
/// the client is built, as many as [`SdoClient::with_sessions`] asks for (the master's client:
/// its session count is a configuration value).
pub struct SdoClient<
    B: TransferBuffer = DefaultBuffer,
    const SESSIONS: usize = 8,
    S: Storage = Inline,
> {
    pub(super) sessions: Table<Session<B>, SESSIONS, S>,
    limit: usize,
    next_id: u32,
    channels: fn(NodeId) -> Channel,
    events: S::Fifo<SdoEvent<B>, SESSIONS>,
    rr: usize,
    stats: SdoClientStats,
    clock: TimeWatch,
}

impl SdoClient {
    /// A client with the default buffers and 8 sessions whose transfers carry at most `limit`
    /// bytes, on the predefined channels. Other buffer types and session counts:
    /// [`SdoClient::with_limit`].
    #[must_use]
    pub fn new(limit: usize) -> Self {
        Self::with_limit(limit)
    }
}

#[cfg(feature = "alloc")]
impl<B: TransferBuffer, const SESSIONS: usize> SdoClient<B, SESSIONS, crate::frame::storage::Heap> {
    /// A client whose `sessions` sessions (at least one) are allocated now, never grown; its
    /// transfers carry at most `limit` bytes, on the predefined channels.
    #[must_use]
    pub fn with_sessions(limit: usize, sessions: usize) -> Self {
        Self::build(limit, sessions.max(1))
    }

    /// The channel function (the profile's SDO identifiers).
    pub(crate) fn channels(&self) -> fn(NodeId) -> Channel {
        self.channels
    }
}

impl<B: TransferBuffer, const SESSIONS: usize, S: Storage> SdoClient<B, SESSIONS, S> {
    /// A client with `SESSIONS` sessions whose transfers carry at most `limit` bytes, on the predefined
    /// channels.
    #[must_use]
    pub fn with_limit(limit: usize) -> Self {
        Self::build(limit, SESSIONS)
    }

    fn build(limit: usize, sessions: usize) -> Self {
        SdoClient {
            sessions: Table::new(sessions, || Session::new(limit)),
            limit,
            next_id: 1,
            channels: Channel::predefined,
            events: S::fifo(sessions),
            rr: 0,
            stats: SdoClientStats::default(),
            clock: TimeWatch::new(),
        }
    }

    /// The clock contract ([`crate::frame::instant`]): when the caller's clock stepped back,
    /// each transfer's timeouts move back with it. Public for an owner that watches the clock
    /// itself and must have the client measure the same step without anything else happening.
    pub fn watch_clock(&mut self, now: Instant) {
        if let Some(by) = self.clock.step_back(now) {
            for s in self.sessions.iter_mut() {
                shift_back(&mut s.deadline, by);
                shift_back(&mut s.subblock_deadline, by);
            }
        }
    }

    /// Transfers the client can run at once: its session count (`SESSIONS`, or what the heap
    /// storage was built with). It never changes.
    pub fn sessions(&self) -> usize {
        self.sessions.len()
    }

    /// Uses `f` to find the channel of a node (a custom identifier profile); a request's
    /// [`SdoOptions::channel`] still takes precedence.
    pub fn with_channels(mut self, f: fn(NodeId) -> Channel) -> Self {
        self.channels = f;
        self
    }

    /// Counters.
    pub fn stats(&self) -> SdoClientStats {
        let tx_dropped = self.sessions.iter().map(|s| s.out.dropped()).sum();
        SdoClientStats {
            tx_dropped,
            events_dropped: self.events.dropped(),
            ..self.stats
        }
    }
    /// The channel a request to `node` goes on unless its options name another.
    pub fn channel(&self, node: NodeId) -> Channel {
        (self.channels)(node)
    }
    /// The transfer limit.
    pub fn limit(&self) -> usize {
        self.limit
    }
    /// Transfers running.
    pub fn in_flight(&self) -> usize {
        self.sessions.iter().filter(|s| s.active()).count()
    }
    /// True if a transfer to `node` is running.
    pub fn is_busy(&self, node: NodeId) -> bool {
        self.sessions.iter().any(|s| s.active() && s.node == node)
    }
    /// How far a download in flight is: (bytes the server confirmed, bytes in all); `None` when
    /// `request` is not a download running now. Block transfer confirms a sub-block at a time,
    /// segmented transfer each segment; an expedited download is all or nothing. A streamed
    /// download answers [`SdoClient::stream_progress`] instead.
    pub fn progress(&self, request: RequestId) -> Option<(usize, usize)> {
        let s = self.sessions.iter().find(|s| {
            s.active()
                && s.request == request
                && s.direction == Direction::Download
                && s.stream.is_none()
        })?;
        let total = s.buf.len();
        let done = match s.state {
            State::DownloadSegment { offset, .. } => offset,
            State::BlockDownload { tx, .. } => tx.acked_bytes(),
            State::BlockDownloadEnd => total,
            _ => 0,
        };
        Some((done.min(total), total))
    }
    /// The largest transfer buffer in use, in bytes (never above [`SdoClient::limit`]).
    pub fn max_buffer_len(&self) -> usize {
        self.sessions.iter().map(|s| s.buf.len()).max().unwrap_or(0)
    }

    /// Reads (index, sub) of `node`'s dictionary.
    pub fn upload(
        &mut self,
        now: Instant,
        node: NodeId,
        index: u16,
        sub: u8,
        opts: SdoOptions,
    ) -> Result<RequestId, SdoError> {
        // A transfer starts at `now`: a client that sat idle through a step of the clock must
        // not take its first deadline for one of the old time line at its next input.
        self.watch_clock(now);
        let i = self.take_session(node, index, sub, Direction::Upload, &opts)?;
        let s = &mut self.sessions[i];
        s.buf.clear();
        if opts.mode == TransferMode::Block {
            s.mode = TransferMode::Block;
            s.request(Request::BlockUploadInitiate {
                index,
                sub,
                crc: opts.crc,
                blksize: opts.block_size.clamp(1, MAX_BLOCK_SIZE),
                pst: opts.pst,
            });
            s.state = State::BlockUploadInit;
        } else {
            s.mode = TransferMode::Segmented;
            s.request(Request::InitiateUpload { index, sub });
            s.state = State::UploadInit;
        }
        s.touch(now);
        Ok(s.request)
    }

    /// Writes `data` to (index, sub) of `node`'s dictionary.
    pub fn download(
        &mut self,
        now: Instant,
        node: NodeId,
        index: u16,
        sub: u8,
        data: &[u8],
        opts: SdoOptions,
    ) -> Result<RequestId, SdoError> {
        self.watch_clock(now); // as in `upload`
        let err = |kind| SdoError {
            node,
            index,
            sub,
            direction: Direction::Download,
            kind,
        };
        if data.len() > self.limit {
            return Err(err(SdoErrorKind::TooLong {
                len: data.len(),
                limit: self.limit,
            }));
        }
        let small = (1..=4).contains(&data.len());
        let mode = match opts.mode {
            TransferMode::Expedited if !small => return Err(err(SdoErrorKind::TransferMode)),
            TransferMode::Auto if small => TransferMode::Expedited,
            TransferMode::Auto if opts.block_threshold.is_some_and(|t| data.len() >= t) => {
                TransferMode::Block
            }
            TransferMode::Auto => TransferMode::Segmented,
            m => m,
        };
        let i = self.take_session(node, index, sub, Direction::Download, &opts)?;
        let s = &mut self.sessions[i];
        s.buf.clear();
        s.buf.reserve(data.len());
        // Cannot fail: the length was checked against the limit every buffer has.
        let _ = s.buf.extend(data);
        start_download(s, mode);
        s.touch(now);
        Ok(s.request)
    }

    /// Aborts a running request with `code` (the server is told). Returns false if it is not
    /// running.
    pub fn abort(&mut self, now: Instant, request: RequestId, code: AbortCode) -> bool {
        let Some(i) = self
            .sessions
            .iter()
            .position(|s| s.active() && s.request == request)
        else {
            return false;
        };
        self.abort_session(i, now, code);
        true
    }

    /// Aborts the transfer running with `node`, if any, with `code` (the server is told), and
    /// returns its request: for a server that rebooted, whose side of the transfer is gone (it
    /// could only time out).
    pub fn abort_node(&mut self, now: Instant, node: NodeId, code: AbortCode) -> Option<RequestId> {
        let i = self
            .sessions
            .iter()
            .position(|s| s.active() && s.node == node)?;
        let request = self.sessions[i].request;
        self.abort_session(i, now, code);
        Some(request)
    }

    pub(super) fn take_session(
        &mut self,
        node: NodeId,
        index: u16,
        sub: u8,
        direction: Direction,
        opts: &SdoOptions,
    ) -> Result<usize, SdoError> {
        let err = |kind| SdoError {
            node,
            index,
            sub,
            direction,
            kind,
        };
        let channel = opts.channel.unwrap_or((self.channels)(node));
        if self
            .sessions
            .iter()
            .any(|s| s.active() && (s.node == node || s.channel.response == channel.response))
        {
            return Err(err(SdoErrorKind::Busy));
        }
        // A session stays taken until its result is polled, so results are never dropped.
        let sessions = self.sessions.len();
        if self.in_flight() + self.events.len() >= sessions {
            return Err(err(SdoErrorKind::NoSession { sessions }));
        }
        // The session that last served this channel, if idle, so that it still knows the
        // channel's last answer (a late second copy of it must not fail the new transfer), and
        // so that what it still has to send there (the abort of a transfer that timed out)
        // leaves before the new request: from another session, the request could go first
        // and the server take the abort for the new transfer's.
        let free = |s: &Session<B>| !s.active() && s.out.is_empty();
        let Some(i) = self
            .sessions
            .iter()
            .position(|s| !s.active() && s.channel.response == channel.response)
            .or_else(|| self.sessions.iter().position(free))
            .or_else(|| self.sessions.iter().position(|s| !s.active()))
        else {
            return Err(err(SdoErrorKind::NoSession { sessions }));
        };
        let request = RequestId(self.next_id);
        self.next_id = self.next_id.wrapping_add(1);
        self.stats.started += 1;
        let s = &mut self.sessions[i];
        if s.channel.response != channel.response {
            s.last_rx = None;
        }
        s.request = request;
        s.node = node;
        s.index = index;
        s.sub = sub;
        s.channel = channel;
        s.opts = *opts;
        s.direction = direction;
        s.subblock_deadline = None;
        s.stale = false;
        s.buf.set_limit(self.limit);
        s.stream = None;
        Ok(i)
    }

    fn finish(&mut self, i: usize, now: Instant, result: Result<(), SdoErrorKind>) {
        let limit = self.limit;
        let s = &mut self.sessions[i];
        let result = match result {
            Ok(()) => {
                self.stats.completed += 1;
                Ok(match s.direction {
                    Direction::Upload => core::mem::replace(&mut s.buf, B::with_limit(limit)),
                    Direction::Download => {
                        s.buf.clear();
                        B::with_limit(0)
                    }
                })
            }
            Err(kind) => {
                self.stats.failed += 1;
                s.buf.clear();
                Err(SdoError {
                    node: s.node,
                    index: s.index,
                    sub: s.sub,
                    direction: s.direction,
                    kind,
                })
            }
        };
        s.state = State::Idle;
        s.stream = None;
        s.deadline = None;
        s.subblock_deadline = None;
        self.events.push(SdoEvent {
            at: now,
            request: s.request,
            node: s.node,
            index: s.index,
            sub: s.sub,
            direction: s.direction,
            mode: s.mode,
            result,
        });
    }

    pub(super) fn abort_session(&mut self, i: usize, now: Instant, code: AbortCode) {
        let s = &mut self.sessions[i];
        let (index, sub) = (s.index, s.sub);
        s.send(codec::abort_frame(index, sub, code));
        self.finish(i, now, Err(SdoErrorKind::Client(code)));
    }
}

impl<B: TransferBuffer, const SESSIONS: usize, S: Storage> Machine for SdoClient<B, SESSIONS, S> {
    type Event = SdoEvent<B>;
    type LinkCommand = core::convert::Infallible;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.watch_clock(now);
        if let Some(i) = self
            .sessions
            .iter()
            .position(|s| s.active() && s.channel.response == frame.id())
        {
            self.session_frame(i, now, frame);
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.watch_clock(now);
        for i in 0..self.sessions.len() {
            let s = &mut self.sessions[i];
            if s.subblock_deadline.is_some_and(|t| t <= now) {
                s.subblock_deadline = None;
                if let State::BlockUpload { mut rx, crc, size } = s.state {
                    if rx.in_sub_block() {
                        let ackseq = rx.timeout();
                        s.state = State::BlockUpload { rx, crc, size };
                        upload_ack(s, ackseq, rx.blksize());
                    }
                }
            }
            if s.deadline.is_some_and(|t| t <= now) {
                if matches!(s.state, State::BlockDownload { tx, .. } if tx.is_sending())
                    && !stream::starved(s)
                {
                    // The driver has not taken the whole sub-block yet (a slow bus): the server
                    // cannot have answered, so the wait starts over.
                    s.touch(now);
                    continue;
                }
                let code = if s.stale {
                    AbortCode::PARAMETER_INCOMPATIBLE
                } else {
                    AbortCode::TIMEOUT
                };
                self.abort_session(i, now, code);
            }
        }
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        // Round robin, so one block transfer does not starve the other sessions.
        let n = self.sessions.len();
        for k in 0..n {
            let i = (self.rr + k) % n;
            let s = &mut self.sessions[i];
            let f = s.out.pop().or_else(|| match s.state {
                State::BlockDownload { ref mut tx, .. } => {
                    stream::block_segment(tx, s.buf.as_slice(), s.stream.as_ref())
                        .map(|d| Frame::from_array(s.channel.request, d))
                }
                _ => None,
            });
            if f.is_some() {
                self.rr = (i + 1) % n;
                return f;
            }
        }
        None
    }

    fn poll_timeout(&self) -> Option<Instant> {
        earliest_of(
            self.sessions
                .iter()
                .flat_map(|s| [s.deadline, s.subblock_deadline]),
        )
    }

    fn poll_event(&mut self) -> Option<SdoEvent<B>> {
        self.events.pop()
    }
}
