//! The USDO client: reads and writes another node's dictionary, one transfer at a time, each
//! numbered by a session byte of its own so that a late answer to an earlier transfer is never
//! taken for the current one's.
//!
//! Requests go out on 0x600 + this node-ID, naming the server in their destination byte; the
//! server's answers come on 0x580 + its node-ID, naming this node. The rules, the memory and
//! the order are in the [module documentation](super).

use super::abort::UsdoAbort;
use super::codec::{Msg, Usdo, UsdoPayload, EXPEDITED_MAX, SEGMENT_MAX};
use super::event::{UsdoClientStats, UsdoError, UsdoErrorKind, UsdoEvent};
use super::request_id;
use crate::cia301::sdo::{DefaultBuffer, Direction, TransferBuffer};
use crate::frame::cob_id::NodeId;
use crate::frame::fd::FdFrame;
use crate::frame::instant::{shift_back, Duration, Instant};
use crate::frame::queue::Bounded;
use crate::od::abort::AbortCode;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    DownloadExpedited,
    DownloadInit,
    /// Segment `[offset, end)` of the buffer sent, toggle `toggle`.
    Download {
        toggle: bool,
        offset: usize,
        end: usize,
    },
    UploadInit,
    Upload {
        toggle: bool,
        size: usize,
    },
}

#[derive(Clone, Copy, Debug)]
struct Transfer {
    server: NodeId,
    session: u8,
    index: u16,
    sub: u8,
    direction: Direction,
    state: State,
    timeout: Duration,
    deadline: Instant,
}

/// A sans-IO USDO client of node `node`: one transfer at a time, buffered in a `B` bounded by
/// the client's limit.
pub struct UsdoClient<B: TransferBuffer = DefaultBuffer> {
    node: NodeId,
    limit: usize,
    next_session: u8,
    t: Option<Transfer>,
    /// The last segment answer taken in this transfer: its second copy is recognised.
    last: Option<FdFrame>,
    buf: B,
    out: Bounded<FdFrame, 2>,
    event: Option<UsdoEvent<B>>,
    stats: UsdoClientStats,
}

mod answer;

impl<B: TransferBuffer> UsdoClient<B> {
    /// The client of node `node` (its requests go out on 0x600 + `node`), for values of at most
    /// `limit` bytes.
    #[must_use]
    pub fn new(node: NodeId, limit: usize) -> Self {
        UsdoClient {
            node,
            limit,
            next_session: 1,
            t: None,
            last: None,
            buf: B::with_limit(limit),
            out: Bounded::new(),
            event: None,
            stats: UsdoClientStats::default(),
        }
    }

    /// Counters.
    pub fn stats(&self) -> UsdoClientStats {
        self.stats
    }
    /// True while a transfer runs.
    pub fn is_busy(&self) -> bool {
        self.t.is_some()
    }

    fn start(
        &mut self,
        now: Instant,
        server: NodeId,
        index: u16,
        sub: u8,
        direction: Direction,
        timeout: Duration,
    ) -> Result<u8, UsdoError> {
        if self.t.is_some() || self.event.is_some() {
            let kind = UsdoErrorKind::Busy;
            return Err(UsdoError {
                server,
                index,
                sub,
                direction,
                kind,
            });
        }
        let session = self.next_session;
        self.next_session = self.next_session.wrapping_add(1);
        let state = State::UploadInit;
        let deadline = now + timeout;
        self.t = Some(Transfer {
            server,
            session,
            index,
            sub,
            direction,
            state,
            timeout,
            deadline,
        });
        self.buf.clear();
        self.last = None;
        Ok(session)
    }

    /// Reads (index, sub) of `server`; the result comes as an event, or by `timeout` at the
    /// latest. Returns the transfer's session byte.
    pub fn upload(
        &mut self,
        now: Instant,
        server: NodeId,
        index: u16,
        sub: u8,
        timeout: Duration,
    ) -> Result<u8, UsdoError> {
        let session = self.start(now, server, index, sub, Direction::Upload, timeout)?;
        self.send(Msg::UploadInitiate { index, sub });
        Ok(session)
    }

    /// Writes `data` to (index, sub) of `server`, announced as CiA 301 type `data_type` (0: not
    /// announced; the server checks a type given against the entry's).
    #[allow(clippy::too_many_arguments)]
    pub fn download(
        &mut self,
        now: Instant,
        server: NodeId,
        index: u16,
        sub: u8,
        data_type: u8,
        data: &[u8],
        timeout: Duration,
    ) -> Result<u8, UsdoError> {
        if data.len() > self.limit {
            let kind = UsdoErrorKind::TooLong {
                len: data.len(),
                limit: self.limit,
            };
            return Err(UsdoError {
                server,
                index,
                sub,
                direction: Direction::Download,
                kind,
            });
        }
        let session = self.start(now, server, index, sub, Direction::Download, timeout)?;
        self.buf.reserve(data.len());
        // Cannot fail: the length was checked against the limit.
        let _ = self.buf.extend(data);
        let msg = match UsdoPayload::new(data).filter(|_| data.len() <= EXPEDITED_MAX) {
            Some(data) => {
                self.set_state(State::DownloadExpedited);
                Msg::DownloadExpedited {
                    index,
                    sub,
                    data_type,
                    data,
                }
            }
            None => {
                self.set_state(State::DownloadInit);
                Msg::DownloadInitiate {
                    index,
                    sub,
                    data_type,
                    size: data.len() as u32,
                }
            }
        };
        self.send(msg);
        Ok(session)
    }

    /// Aborts the running transfer with `code` (the server is told); false if none runs.
    pub fn abort(&mut self, now: Instant, code: AbortCode) -> bool {
        if self.t.is_none() {
            return false;
        }
        self.fail(now, code);
        true
    }

    fn set_state(&mut self, state: State) {
        if let Some(t) = &mut self.t {
            t.state = state;
        }
    }

    fn send(&mut self, msg: Msg) {
        if let Some(t) = self.t {
            let u = Usdo {
                dest: t.server.raw(),
                session: t.session,
                msg,
            };
            self.out.push(u.encode(request_id(self.node)));
        }
    }

    /// Aborts on the bus and ends the transfer with `code`.
    fn fail(&mut self, now: Instant, code: AbortCode) {
        if let Some(t) = self.t {
            let abort = UsdoAbort::from_code(code);
            self.send(Msg::Abort {
                index: t.index,
                sub: t.sub,
                code: abort,
            });
        }
        self.end(now, Err(UsdoErrorKind::Client(code)));
    }

    fn end(&mut self, now: Instant, r: Result<(), UsdoErrorKind>) {
        let Some(t) = self.t.take() else { return };
        let result = match r {
            Ok(()) => {
                self.stats.completed += 1;
                let data = core::mem::replace(&mut self.buf, B::with_limit(self.limit));
                Ok(match t.direction {
                    Direction::Upload => data,
                    Direction::Download => B::with_limit(0),
                })
            }
            Err(kind) => {
                self.stats.failed += 1;
                self.buf.clear();
                let (server, index, sub, direction) = (t.server, t.index, t.sub, t.direction);
                Err(UsdoError {
                    server,
                    index,
                    sub,
                    direction,
                    kind,
                })
            }
        };
        self.event = Some(UsdoEvent {
            at: now,
            session: t.session,
            result,
        });
    }

    /// Sends the download segment after `offset`.
    fn next_segment(&mut self, toggle: bool, offset: usize) {
        let end = (offset + SEGMENT_MAX).min(self.buf.len());
        let data = UsdoPayload::new(&self.buf.as_slice()[offset..end]);
        self.set_state(State::Download {
            toggle,
            offset,
            end,
        });
        if let Some(data) = data {
            let last = end == self.buf.len();
            self.send(Msg::DownloadSegment { toggle, last, data });
        }
    }

    /// Time passed: a transfer the server left unanswered for its timeout is aborted.
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.t.is_some_and(|t| t.deadline <= now) {
            self.fail(now, AbortCode::TIMEOUT);
        }
    }

    /// When `handle_timeout` has work.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.t.map(|t| t.deadline)
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        if let Some(t) = &mut self.t {
            let mut d = Some(t.deadline);
            shift_back(&mut d, by);
            t.deadline = d.unwrap_or(t.deadline);
        }
    }

    /// The next frame to send.
    #[must_use]
    pub fn poll_transmit(&mut self) -> Option<FdFrame> {
        self.out.pop()
    }

    /// The end of the last transfer; a new one starts only once it was taken.
    pub fn poll_event(&mut self) -> Option<UsdoEvent<B>> {
        self.event.take()
    }
}
