//! The one shape the timed services share: `poll_timeout()` says when a service has work,
//! `handle_timeout(now, &mut out)` does it and writes what it produces into a
//! [`ServiceOutput`].
//!
//! The services own this contract and know nothing of whoever composes them: a
//! [node](crate::node) implements the output over its own transmit and event queues, a test
//! records into vectors. Frames whose identifier the composer decides (its heartbeat, a
//! guarding request, both set by its identifier profile) are asked for as
//! [`ServiceEvent::HeartbeatDue`] and [`ServiceEvent::GuardRequest`] rather than built here.

use crate::cia301::guarding::{GuardEvent, LifeEvent};
use crate::cia301::heartbeat::ConsumerEvent;
use crate::cia301::nmt::NmtState;
use crate::cia301::pdo::PdoEvent;
use crate::cia301::sync::SyncTick;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
#[cfg(feature = "fd")]
use crate::frame::FdFrame;
use crate::frame::Frame;

/// What a service produced besides ready frames, in the order it produced it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ServiceEvent {
    /// The heartbeat producer is due (and the NMT state allows error control): the composer
    /// sends its heartbeat on the identifier its profile gives.
    HeartbeatDue,
    /// A node-guarding request to `node` is due: the composer sends the remote frame on the
    /// identifier its profile gives.
    GuardRequest {
        /// The guarded node.
        node: NodeId,
    },
    /// The heartbeat consumer reports.
    Consumer(ConsumerEvent),
    /// Node guarding (master side) reports.
    Guard(GuardEvent),
    /// Life guarding (slave side) reports.
    Life(LifeEvent),
    /// A SYNC was produced (its frame was sent just before): synchronous PDOs follow it.
    SyncProduced(SyncTick),
    /// The PDO engine reports.
    Pdo(PdoEvent),
}

/// Where the services put what they produce.
pub trait ServiceOutput {
    /// The NMT state of the composing device: a service sends only what the state allows
    /// (CiA 301 table of services per state), and keeps its schedule either way.
    fn nmt_state(&self) -> NmtState;
    /// A frame to send (a full queue is the implementor's to count).
    fn send(&mut self, frame: Frame);
    /// Something that happened at `at`.
    fn event(&mut self, at: Instant, e: ServiceEvent);
    /// The composing device is on a CANopen FD network (feature `fd`): the services that have a
    /// CAN FD form (PDO, EMCY) send it. The default, for an output that has no CAN FD queue:
    /// no.
    #[cfg(feature = "fd")]
    fn fd_network(&self) -> bool {
        false
    }
    /// A CAN FD frame to send (feature `fd`; a full queue is the implementor's to count). The
    /// default drops it: only an output whose [`ServiceOutput::fd_network`] is true is given
    /// any.
    #[cfg(feature = "fd")]
    fn send_fd(&mut self, frame: FdFrame) {
        let _ = frame;
    }
}

/// An output that records everything, for the services' own tests.
#[cfg(test)]
pub(crate) struct Recorder {
    pub state: NmtState,
    pub frames: std::vec::Vec<Frame>,
    /// CAN FD frames; only an FD recorder ([`Recorder::fd`]) is given any.
    #[cfg(feature = "fd")]
    pub fd_frames: std::vec::Vec<FdFrame>,
    #[cfg(feature = "fd")]
    pub fd: bool,
    pub events: std::vec::Vec<(Instant, ServiceEvent)>,
}

#[cfg(test)]
impl Recorder {
    pub fn new(state: NmtState) -> Self {
        Recorder {
            state,
            frames: std::vec::Vec::new(),
            #[cfg(feature = "fd")]
            fd_frames: std::vec::Vec::new(),
            #[cfg(feature = "fd")]
            fd: false,
            events: std::vec::Vec::new(),
        }
    }
    /// The events alone, without their instants.
    pub fn kinds(&self) -> std::vec::Vec<ServiceEvent> {
        self.events.iter().map(|(_, e)| *e).collect()
    }
}

#[cfg(test)]
impl ServiceOutput for Recorder {
    fn nmt_state(&self) -> NmtState {
        self.state
    }
    fn send(&mut self, frame: Frame) {
        self.frames.push(frame);
    }
    fn event(&mut self, at: Instant, e: ServiceEvent) {
        self.events.push((at, e));
    }
    #[cfg(feature = "fd")]
    fn fd_network(&self) -> bool {
        self.fd
    }
    #[cfg(feature = "fd")]
    fn send_fd(&mut self, frame: FdFrame) {
        self.fd_frames.push(frame);
    }
}
