//! The USDO server: a node's dictionary served to every USDO client on the network, through
//! [`ObjectAccess`] as the SDO server serves it (access rights, types, lengths, limits, hooks,
//! the stack's reactions to writes).
//!
//! Requests arrive on 0x600 + the client's node-ID and name this server (or
//! [`BROADCAST`]) in their destination byte; answers go out on 0x580 + this node-ID to the
//! client, carrying the request's session byte back. The rules, the memory and what is
//! refused are in the [module documentation](super).

use super::abort::UsdoAbort;
use super::codec::{Msg, Usdo, UsdoDecodeError, BROADCAST};
use super::{answer_id, client_of};
use crate::cia301::sdo::{DefaultBuffer, TransferBuffer};
use crate::frame::cob_id::NodeId;
use crate::frame::fd::FdFrame;
use crate::frame::instant::{earliest_of, shift_back, Duration, Instant};
use crate::frame::queue::Bounded;
use crate::frame::Malformed;
use crate::od::abort::AbortCode;
use crate::od::ObjectAccess;

mod transfer;

use transfer::{check_target, check_type};

/// Counters of a USDO server.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UsdoServerStats {
    /// Transfers completed (expedited and segmented).
    pub completed: u32,
    /// Transfers this server aborted (abort sent), busy refusals among them.
    pub aborted: u32,
    /// Requests refused because the client had another session running, or every session of
    /// this server was taken.
    pub busy: u32,
    /// Transfers the client aborted.
    pub client_aborts: u32,
    /// Frames that were no USDO message.
    pub malformed: u32,
    /// Second copies of a segment request ignored (see the module docs).
    pub repeats: u32,
    /// Frames dropped because the output was not drained.
    pub tx_dropped: u32,
}

#[derive(Clone, Copy, Debug)]
enum Phase {
    Download { toggle: bool, size: usize },
    Upload { toggle: bool, offset: usize },
}

/// One segmented transfer with one client.
struct Slot<B> {
    client: u8,
    session: u8,
    index: u16,
    sub: u8,
    /// `None`: the slot is free.
    phase: Option<Phase>,
    deadline: Option<Instant>,
    /// The last segment request taken: its second copy is recognised.
    last: Option<FdFrame>,
    buf: B,
}

/// A sans-IO USDO server with `SESSIONS` segmented transfers at once (expedited ones take
/// none), each buffered in a `B` bounded by the server's limit.
pub struct UsdoServer<B: TransferBuffer = DefaultBuffer, const SESSIONS: usize = 4> {
    node: NodeId,
    timeout: Duration,
    slots: [Slot<B>; SESSIONS],
    out: Bounded<FdFrame, 8>,
    stats: UsdoServerStats,
}

impl<B: TransferBuffer, const SESSIONS: usize> UsdoServer<B, SESSIONS> {
    /// The server of `node`: a segmented transfer the client leaves for `timeout` is aborted;
    /// none carries more than `limit` bytes.
    #[must_use]
    pub fn new(node: NodeId, timeout: Duration, limit: usize) -> Self {
        UsdoServer {
            node,
            timeout,
            slots: core::array::from_fn(|_| Slot {
                client: 0,
                session: 0,
                index: 0,
                sub: 0,
                phase: None,
                deadline: None,
                last: None,
                buf: B::with_limit(limit),
            }),
            out: Bounded::new(),
            stats: UsdoServerStats::default(),
        }
    }

    /// The node this server serves.
    pub fn node(&self) -> NodeId {
        self.node
    }
    /// Counters.
    pub fn stats(&self) -> UsdoServerStats {
        UsdoServerStats {
            tx_dropped: self.out.dropped(),
            ..self.stats
        }
    }
    /// Segmented transfers running.
    pub fn active(&self) -> usize {
        self.slots.iter().filter(|s| s.phase.is_some()).count()
    }

    /// Drops every transfer without a word (the node was reset or left the states with USDO)
    /// and whatever was waiting to be sent.
    pub fn cancel(&mut self) {
        for s in &mut self.slots {
            s.phase = None;
            s.deadline = None;
            s.buf.clear();
        }
        self.out.clear();
    }

    fn send(&mut self, client: u8, session: u8, msg: Msg) {
        let u = Usdo {
            dest: client,
            session,
            msg,
        };
        self.out.push(u.encode(answer_id(self.node)));
    }

    fn abort(&mut self, client: u8, session: u8, index: u16, sub: u8, code: AbortCode) {
        let code = UsdoAbort::from_code(code);
        self.send(client, session, Msg::Abort { index, sub, code });
        self.stats.aborted += 1;
    }

    /// Ends slot `i`'s transfer with an abort to its client.
    fn abort_slot(&mut self, i: usize, code: AbortCode) {
        let s = &self.slots[i];
        let (c, session, index, sub) = (s.client, s.session, s.index, s.sub);
        self.free(i);
        self.abort(c, session, index, sub, code);
    }

    fn free(&mut self, i: usize) {
        let s = &mut self.slots[i];
        s.phase = None;
        s.deadline = None;
        s.buf.clear();
    }

    fn slot_of(&self, client: u8) -> Option<usize> {
        self.slots
            .iter()
            .position(|s| s.phase.is_some() && s.client == client)
    }

    /// A frame from the bus. Frames on other identifiers than USDO requests, and requests for
    /// other servers, are ignored; bytes that are no USDO message are refused (answered with
    /// an abort when they name this server).
    pub fn handle_frame<A: ObjectAccess + ?Sized>(
        &mut self,
        now: Instant,
        frame: &FdFrame,
        od: &mut A,
    ) -> Result<(), Malformed> {
        let Some(client) = client_of(frame.id()) else {
            return Ok(());
        };
        let d = frame.data();
        let u = match Usdo::decode(d) {
            Ok(u) => u,
            Err(e) => {
                self.stats.malformed += 1;
                let UsdoDecodeError::Bad {
                    dest,
                    session,
                    code,
                } = e
                else {
                    return Err(Malformed::WrongLength {
                        expected: 3,
                        got: frame.dlc(),
                    });
                };
                if dest == self.node.raw() {
                    let index = match d {
                        [_, _, _, lo, hi, ..] => u16::from_le_bytes([*lo, *hi]),
                        _ => 0,
                    };
                    let sub = d.get(5).copied().unwrap_or(0);
                    if let Some(i) = self
                        .slot_of(client)
                        .filter(|&i| self.slots[i].session == session)
                    {
                        self.abort_slot(i, code);
                        return Ok(());
                    }
                    self.abort(client, session, index, sub, code);
                }
                return Err(Malformed::BadValue { value: d[1] });
            }
        };
        if u.dest != self.node.raw() && u.dest != BROADCAST {
            return Ok(());
        }
        if let (Msg::DownloadSegment { .. } | Msg::UploadSegment { .. }, Some(i)) =
            (u.msg, self.slot_of(client))
        {
            let s = &mut self.slots[i];
            // Two segment requests in a row differ (the toggle alternates): an equal one is
            // a second copy, such as the dual-bus layer's late twin.
            if s.session == u.session && s.last == Some(*frame) {
                self.stats.repeats += 1;
                return Ok(());
            }
            s.last = Some(*frame);
        }
        self.request(now, client, u, od);
        Ok(())
    }

    /// Refuses a new transfer while the client runs another session with this server; a new
    /// transfer in the running session's own number means the client started over.
    fn busy(&mut self, client: u8, session: u8, index: u16, sub: u8) -> bool {
        match self.slot_of(client) {
            Some(i) if self.slots[i].session != session => {
                self.stats.busy += 1;
                self.abort(client, session, index, sub, AbortCode::NO_RESOURCE);
                true
            }
            Some(i) => {
                self.free(i);
                false
            }
            None => false,
        }
    }

    /// A free slot for a segmented transfer, taken for (client, session, index, sub).
    fn take(
        &mut self,
        now: Instant,
        client: u8,
        session: u8,
        index: u16,
        sub: u8,
    ) -> Option<usize> {
        let Some(i) = self.slots.iter().position(|s| s.phase.is_none()) else {
            self.stats.busy += 1;
            self.abort(client, session, index, sub, AbortCode::NO_RESOURCE);
            return None;
        };
        let s = &mut self.slots[i];
        (s.client, s.session, s.index, s.sub) = (client, session, index, sub);
        s.deadline = Some(now + self.timeout);
        s.last = None;
        s.buf.clear();
        Some(i)
    }

    fn request<A: ObjectAccess + ?Sized>(&mut self, now: Instant, c: u8, u: Usdo, od: &mut A) {
        let (session, broadcast) = (u.session, u.dest == BROADCAST);
        match u.msg {
            Msg::DownloadExpedited {
                index,
                sub,
                data_type,
                data,
            } => {
                if self.busy(c, session, index, sub) {
                    return;
                }
                let r = check_type(od, index, sub, data_type)
                    .and_then(|()| od.write(now, index, sub, data.bytes()));
                self.finish(c, session, index, sub, r, Msg::DownloadAck { index, sub });
            }
            Msg::UploadInitiate { index, sub } => {
                if !self.busy(c, session, index, sub) {
                    self.upload(now, c, session, index, sub, broadcast, od);
                }
            }
            Msg::DownloadInitiate {
                index,
                sub,
                data_type,
                size,
            } => {
                if broadcast {
                    // Segments cannot be confirmed by every server at once.
                    return self.abort(c, session, index, sub, AbortCode::UNSUPPORTED_ACCESS);
                }
                if self.busy(c, session, index, sub) {
                    return;
                }
                let size = size as usize;
                if let Err(code) = check_type(od, index, sub, data_type)
                    .and_then(|()| check_target(od, index, sub, size))
                {
                    return self.abort(c, session, index, sub, code);
                }
                let Some(i) = self.take(now, c, session, index, sub) else {
                    return;
                };
                if size > self.slots[i].buf.limit() {
                    return self.abort_slot(i, AbortCode::OUT_OF_MEMORY);
                }
                self.slots[i].buf.reserve(size);
                self.slots[i].phase = Some(Phase::Download {
                    toggle: false,
                    size,
                });
                self.send(c, session, Msg::DownloadAck { index, sub });
            }
            Msg::DownloadSegment { toggle, last, data } if !broadcast => {
                self.segment(now, c, session, toggle, Some((last, data)), od)
            }
            Msg::UploadSegment { toggle } if !broadcast => {
                self.segment(now, c, session, toggle, None, od)
            }
            Msg::Abort { .. } => {
                if let Some(i) = self
                    .slot_of(c)
                    .filter(|&i| self.slots[i].session == session)
                {
                    self.stats.client_aborts += 1;
                    self.free(i);
                }
            }
            // Answers a server never takes, and segments sent to every server.
            _ if broadcast => {}
            _ => self.abort(c, session, 0, 0, AbortCode::COMMAND_SPECIFIER),
        }
    }

    fn finish(
        &mut self,
        c: u8,
        session: u8,
        index: u16,
        sub: u8,
        r: Result<(), AbortCode>,
        ok: Msg,
    ) {
        match r {
            Ok(()) => {
                self.stats.completed += 1;
                self.send(c, session, ok);
            }
            Err(code) => self.abort(c, session, index, sub, code),
        }
    }

    /// Time passed: a segmented transfer whose client said nothing for the timeout is aborted.
    pub fn handle_timeout(&mut self, now: Instant) {
        for i in 0..SESSIONS {
            if self.slots[i].deadline.is_some_and(|t| t <= now) {
                self.abort_slot(i, AbortCode::TIMEOUT);
            }
        }
    }

    /// Earliest instant `handle_timeout` has work.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        earliest_of(self.slots.iter().map(|s| s.deadline))
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        for s in &mut self.slots {
            shift_back(&mut s.deadline, by);
        }
    }

    /// The next frame to send.
    #[must_use]
    pub fn poll_transmit(&mut self) -> Option<FdFrame> {
        self.out.pop()
    }
}
