//! Whole-value transfers over USDO (CiA 1301) on a CANopen FD network: what
//! [`RemoteSdo`](super::RemoteSdo)'s typed reads and writes, strings and byte transfers run on
//! when the network was opened with [`NetOptions::with_fd`](super::NetOptions::with_fd).
//!
//! **Why in the door.** CANopen FD has no SDO: its nodes serve USDO, from any client, on
//! identifiers that name the client (0x600 + the client's node-ID). So the client is the
//! network's own, whatever core runs below (the observer, a master): the door keeps it, as it
//! keeps the LSS master, and hands its CAN FD frames to the core's link (on two buses, the
//! dual-bus layer sends each request on both and merges the answers' copies).
//!
//! **The rule.** The caller sees no difference: the same calls, the same values, and a failure
//! is the same [`NetError::Sdo`] (node, object, direction, the CiA 301 abort code the USDO
//! abort byte stands for). The USDO client runs one transfer at a time; transfers to one node
//! already take turns (the network's per-node lock), and those to different nodes wait here in
//! order. A transfer still waiting when its own timeout has passed since the call is answered
//! with a timeout (0x05040000), as one that ran and heard nothing.
//!
//! **Memory.** One client with one buffer of at most [`MAX_TRANSFER`](super::MAX_TRANSFER)
//! bytes; at most one waiting transfer per node-ID (the per-node lock), so at most 127.
//! Streams ([`RemoteSdo::read_to`](super::RemoteSdo::read_to),
//! [`RemoteSdo::write_from`](super::RemoteSdo::write_from)) go whole through the same client
//! (see [`super::sdo_stream`]): duocan has no streamed USDO transfer.

use super::error::NetError;
use super::starts::Reply;
use crate::cia1301::usdo::{UsdoClient, UsdoError, UsdoErrorKind};
use crate::cia301::sdo::{Direction, SdoError, SdoErrorKind, TransferBuffer};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest, Duration, Instant};
use crate::frame::FdFrame;
use crate::od::abort::AbortCode;
use std::collections::VecDeque;

/// One whole-value transfer asked of the door's USDO client.
pub(crate) struct UsdoStart {
    pub node: NodeId,
    pub index: u16,
    pub sub: u8,
    /// `None`: a read.
    pub data: Option<Vec<u8>>,
    /// The answer timeout of the transfer once it runs.
    pub timeout: Duration,
    /// When a transfer still waiting is answered with a timeout.
    pub due: Instant,
    pub reply: Reply,
}

/// The door's USDO client and the transfers waiting for it.
pub(crate) struct UsdoDoor {
    client: UsdoClient,
    waiting: VecDeque<UsdoStart>,
    running: Option<Reply>,
}

/// A USDO failure as the caller's error: the SDO error it would have had.
fn net_error(e: UsdoError) -> NetError {
    let kind = match e.kind {
        UsdoErrorKind::Busy => SdoErrorKind::Busy,
        UsdoErrorKind::TooLong { len, limit } => SdoErrorKind::TooLong { len, limit },
        UsdoErrorKind::Server(a) => SdoErrorKind::Server(a.code().unwrap_or(AbortCode::GENERAL)),
        UsdoErrorKind::Client(c) => SdoErrorKind::Client(c),
    };
    NetError::Sdo(SdoError {
        node: e.server,
        index: e.index,
        sub: e.sub,
        direction: e.direction,
        kind,
    })
}

impl UsdoDoor {
    /// The client of node-ID `me`, for values of at most `limit` bytes.
    pub fn new(me: NodeId, limit: usize) -> Self {
        UsdoDoor {
            client: UsdoClient::new(me, limit),
            waiting: VecDeque::new(),
            running: None,
        }
    }

    /// Takes a transfer: it starts now if the client is free, else waits its turn.
    pub fn submit(&mut self, now: Instant, start: UsdoStart) {
        self.waiting.push_back(start);
        self.advance(now);
    }

    /// A CAN FD frame from the bus.
    pub fn handle_frame(&mut self, now: Instant, frame: &FdFrame) {
        self.client.handle_frame(now, frame);
        self.advance(now);
    }

    /// Time passed: the client's deadline, and the waiting transfers whose time ran out.
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.client.poll_timeout().is_some_and(|t| t <= now) {
            self.client.handle_timeout(now);
        }
        self.advance(now);
        let mut i = 0;
        while let Some(due) = self.waiting.get(i).map(|s| s.due) {
            if due > now {
                i += 1;
            } else if let Some(s) = self.waiting.remove(i) {
                let direction = match s.data {
                    None => Direction::Upload,
                    Some(_) => Direction::Download,
                };
                let e = UsdoError {
                    server: s.node,
                    index: s.index,
                    sub: s.sub,
                    direction,
                    kind: UsdoErrorKind::Client(AbortCode::TIMEOUT),
                };
                let _ = s.reply.send(Err(net_error(e)));
            }
        }
    }

    pub fn poll_timeout(&self) -> Option<Instant> {
        let due = self.waiting.iter().map(|s| s.due).min();
        earliest(self.client.poll_timeout(), due)
    }

    pub fn poll_transmit(&mut self) -> Option<FdFrame> {
        self.client.poll_transmit()
    }

    /// The running transfer's end to its caller, then the next waiting one started.
    fn advance(&mut self, now: Instant) {
        if let Some(ev) = self.client.poll_event() {
            let r = ev.result.map(|b| b.as_slice().to_vec()).map_err(net_error);
            if let Some(reply) = self.running.take() {
                let _ = reply.send(r);
            }
        }
        while self.running.is_none() {
            let Some(s) = self.waiting.pop_front() else {
                return;
            };
            let started = match &s.data {
                None => self.client.upload(now, s.node, s.index, s.sub, s.timeout),
                Some(d) => self
                    .client
                    .download(now, s.node, s.index, s.sub, 0, d, s.timeout),
            };
            match started {
                Ok(_) => self.running = Some(s.reply),
                Err(e) => {
                    let _ = s.reply.send(Err(net_error(e)));
                }
            }
        }
    }
}
