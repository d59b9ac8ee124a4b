//! SDO transfers through the door: started on the core's client, or parked until it takes them.
//!
//! **The rule.** A start the client refuses as busy (a transfer of the core's own to that
//! node runs, a master configuring a slave as it boots) or for want of a session is not the
//! caller's problem: the door parks it and tries it again after every input and every timeout
//! of the device, the moments a session or a node can come free. A start still refused as busy
//! when its own SDO timeout has passed since the call is answered with that refusal; the
//! deadline is in the device's [`poll_timeout`](crate::machine::Device::poll_timeout), so
//! nothing polls on a timer and the answer comes at that very instant. One refused for want of
//! a session waits on: every session frees within its own transfer's timeout, and a caller that
//! asked for more transfers at once than there are sessions (a scan of 127 node-IDs through
//! 8) wants each to run, not to fail while others had its turn. Only the start waits: a transfer that ran
//! and failed is the answer. Transfers to one node still take turns above (the network's
//! per-node lock), so a start is refused as busy only for the core's own transfers.
//!
//! **Memory.** Every caller holds one start at most (the per-node lock), so at most one per
//! node waits; beyond [`PARKED`] a start is [`NetError::QueueFull`].

use super::core::NetClient;
use super::error::NetError;
use crate::cia301::sdo::{RequestId, SdoError, SdoErrorKind};
use crate::frame::instant::Instant;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use tokio::sync::{oneshot, Notify};

/// Starts waiting for the client at most: one per node-ID.
const PARKED: usize = 128;

/// How a transfer starts on the client; called again for every try, so it keeps what it needs.
pub(crate) type Begin =
    Box<dyn FnMut(&mut NetClient, Instant) -> Result<RequestId, SdoError> + Send>;

/// Where a transfer's outcome goes: the data read (empty for a write) or the error.
pub(crate) type Reply = oneshot::Sender<Result<Vec<u8>, NetError>>;

/// A streamed transfer's side: where its id goes once it started, and whom to wake when it has
/// room to fill or data to take.
#[derive(Clone, Default)]
pub(crate) struct Stream {
    pub id: Arc<Mutex<Option<RequestId>>>,
    pub wake: Arc<Notify>,
}

/// One transfer asked of the door.
pub(crate) struct Start {
    pub begin: Begin,
    /// When a start still refused is answered with the refusal (the call's SDO timeout).
    pub due: Instant,
    pub reply: Reply,
    pub stream: Option<Stream>,
}

/// The transfers the door started or holds: a ticket (the caller's [`Reply`]) maps to its
/// request once the client took it.
#[derive(Default)]
pub(crate) struct Starts {
    /// Refused so far, oldest first.
    parked: VecDeque<Start>,
    running: Vec<(RequestId, Reply)>,
    /// Streamed transfers and whom to wake (an entry goes with its transfer's result).
    streams: Vec<(RequestId, Arc<Notify>)>,
}

/// A refusal the door waits out rather than answers.
fn waits(e: &SdoError) -> bool {
    matches!(e.kind, SdoErrorKind::Busy | SdoErrorKind::NoSession { .. })
}

impl Starts {
    /// Starts `s` now if the client takes it; parks it if the client is busy; an error if the
    /// core has no client now or refuses the transfer itself.
    pub fn submit(
        &mut self,
        client: Result<&mut NetClient, NetError>,
        now: Instant,
        mut s: Start,
    ) -> Result<(), NetError> {
        match (s.begin)(client?, now) {
            Ok(id) => self.started(id, s),
            Err(e) if waits(&e) => {
                if self.parked.len() >= PARKED {
                    return Err(NetError::QueueFull);
                }
                self.parked.push_back(s);
            }
            Err(e) => return Err(NetError::Sdo(e)),
        }
        Ok(())
    }

    /// Tries every parked start again, oldest first; answers those refused past their due
    /// time, and all of them if the core has no client now (a master gone standby).
    pub fn retry(&mut self, client: Result<&mut NetClient, NetError>, now: Instant) {
        // A caller that gave up: its reply has nowhere to go.
        self.running.retain(|(_, r)| !r.is_closed());
        if self.parked.is_empty() {
            return;
        }
        let client = match client {
            Ok(c) => c,
            Err(e) => {
                for s in self.parked.drain(..) {
                    let _ = s.reply.send(Err(e.clone()));
                }
                return;
            }
        };
        for _ in 0..self.parked.len() {
            let Some(mut s) = self.parked.pop_front() else {
                break;
            };
            if s.reply.is_closed() {
                continue;
            }
            match (s.begin)(client, now) {
                Ok(id) => self.started(id, s),
                Err(e) if waits(&e) && now < s.due => self.parked.push_back(s),
                Err(e) if matches!(e.kind, SdoErrorKind::NoSession { .. }) => {
                    // No deadline while it waits for a session (see "The rule").
                    s.due = Instant::MAX;
                    self.parked.push_back(s);
                }
                // Refused past its due time, or refused for good.
                Err(e) => {
                    let _ = s.reply.send(Err(NetError::Sdo(e)));
                }
            }
        }
    }

    fn started(&mut self, id: RequestId, s: Start) {
        if let Some(st) = s.stream {
            if let Ok(mut g) = st.id.lock() {
                *g = Some(id);
            }
            // The first look: a download has room at once.
            st.wake.notify_one();
            self.streams.push((id, st.wake));
        }
        self.running.push((id, s.reply));
    }

    /// A transfer ended: its caller gets the outcome.
    pub fn ended(&mut self, id: RequestId, r: &Result<Vec<u8>, SdoError>) {
        self.streams.retain(|(s, _)| *s != id);
        if let Some(i) = self.running.iter().position(|(r, _)| *r == id) {
            let (_, reply) = self.running.swap_remove(i);
            let r = r.clone().map_err(NetError::Sdo);
            // The caller is woken once the runtime gives its lock back: its next call does not
            // find the lock held by the thread that woke it.
            crate::runtime::after_unlock(move || {
                let _ = reply.send(r);
            });
        }
    }

    /// Wakes the reader or feeder of streamed transfer `id`.
    pub fn wake(&self, id: RequestId) {
        if let Some((_, n)) = self.streams.iter().find(|(r, _)| *r == id) {
            n.notify_one();
        }
    }

    /// The earliest instant a parked start is answered.
    pub fn due(&self) -> Option<Instant> {
        self.parked.iter().map(|s| s.due).min()
    }
}
