//! The layer's bounded output queues: frames for the ports, requests for the drivers, events
//! for the application. Overflow is counted, never grown.

use crate::link::events::LinkEvent;
use duocan_core::frame::queue::Bounded;
#[cfg(feature = "fd")]
use duocan_core::frame::FdFrame;
use duocan_core::machine::{LinkRequest, PortRequest};
use duocan_core::Frame;

/// Frames waiting for the driver. The station drains them after every logical frame, so a few
/// suffice (one logical frame fans out to two ports, a channel switch adds an indication).
pub const FRAME_QUEUE: usize = 16;
/// CAN FD frames waiting for the driver, per port (feature `fd`): a queue of their own, so the
/// classic queue keeps its 16-byte frames.
#[cfg(feature = "fd")]
pub const FD_FRAME_QUEUE: usize = 8;
/// Events waiting for the application: room for a reachability change of every node-ID at one
/// instant plus port and channel events.
pub const EVENT_QUEUE: usize = 160;
/// Requests waiting for the driver.
pub const REQUEST_QUEUE: usize = 8;
/// Requests waiting for the machine above (a status change of each kind and a state change).
pub const MACHINE_QUEUE: usize = 8;

/// The output queues a layer's parts (health, reachability, channel policies) write to.
#[derive(Debug, Default)]
pub struct Outbox {
    /// Per port, so that one port's frames can wait for its re-initialisation; each with the
    /// number of the logical frame it is a copy of.
    pub(crate) frames: [Bounded<(Frame, u32), FRAME_QUEUE>; 2],
    /// The same for CAN FD frames (numbered from the same sequence as classic ones).
    #[cfg(feature = "fd")]
    pub(crate) fd_frames: [Bounded<(FdFrame, u32), FD_FRAME_QUEUE>; 2],
    /// The number of the logical frame being sent (see [`Outbox::next_frame`]).
    seq: u32,
    pub(crate) events: Bounded<LinkEvent, EVENT_QUEUE>,
    pub(crate) requests: Bounded<(usize, PortRequest), REQUEST_QUEUE>,
    pub(crate) machine: Bounded<LinkRequest, MACHINE_QUEUE>,
}

impl Outbox {
    /// Empty queues.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }
    /// Queues an event for the application.
    pub fn event(&mut self, e: LinkEvent) {
        self.events.push(e);
    }
    /// The oldest queued event (the layer hands them out through `BusLink::poll_event`).
    pub fn pop_event(&mut self) -> Option<LinkEvent> {
        self.events.pop()
    }
    /// Queues a request for the driver of `port`.
    pub fn request(&mut self, port: usize, r: PortRequest) {
        self.requests.push((port, r));
    }
    /// Queues a request for the machine above the layer.
    pub fn machine(&mut self, r: LinkRequest) {
        self.machine.push(r);
    }
    /// The frames queued from now on are copies of the next logical frame: both ports' copies
    /// of one frame share a number, and a later frame has a later one (see port health's stall
    /// rule).
    pub fn next_frame(&mut self) {
        self.seq = self.seq.wrapping_add(1);
    }
    /// The number of the logical frame being sent (see [`Outbox::next_frame`]).
    pub fn frame_number(&self) -> u32 {
        self.seq
    }
    /// Queues a frame for `port` (0 or 1; others are ignored).
    pub fn frame(&mut self, port: usize, f: Frame) {
        if let Some(q) = self.frames.get_mut(port) {
            q.push((f, self.seq));
        }
    }
    /// The next frame for a driver. A port's frames wait while a request to that port is
    /// pending: a driver may drain frames before requests, and frames handed after a decision
    /// to re-initialise are meant for the re-initialised port, not to be flushed by it.
    #[inline]
    pub fn pop_frame(&mut self) -> Option<(usize, Frame)> {
        self.pop_numbered().map(|(p, f, _)| (p, f))
    }
    /// As [`Outbox::pop_frame`], with the number of the logical frame.
    #[inline]
    pub fn pop_numbered(&mut self) -> Option<(usize, Frame, u32)> {
        if self.requests.is_empty() {
            // The usual case, on every drain: no port waits for a request.
            if let Some((f, n)) = self.frames[0].pop() {
                return Some((0, f, n));
            }
            return self.frames[1].pop().map(|(f, n)| (1, f, n));
        }
        self.pop_frame_past_requests()
    }

    #[inline(never)]
    fn pop_frame_past_requests(&mut self) -> Option<(usize, Frame, u32)> {
        for p in 0..2 {
            if self.requests.iter().any(|(q, _)| *q == p) {
                continue;
            }
            if let Some((f, n)) = self.frames[p].pop() {
                return Some((p, f, n));
            }
        }
        None
    }
    /// Frames dropped because the driver did not drain them (classic and, with `fd`, FD).
    pub fn frames_dropped(&self) -> u32 {
        let classic = self.frames[0]
            .dropped()
            .saturating_add(self.frames[1].dropped());
        #[cfg(feature = "fd")]
        let classic = classic
            .saturating_add(self.fd_frames[0].dropped())
            .saturating_add(self.fd_frames[1].dropped());
        classic
    }

    /// Queues a CAN FD frame for `port` (0 or 1; others are ignored).
    #[cfg(feature = "fd")]
    pub fn fd_frame(&mut self, port: usize, f: FdFrame) {
        if let Some(q) = self.fd_frames.get_mut(port) {
            q.push((f, self.seq));
        }
    }

    /// The next CAN FD frame for a driver, with its logical frame number: as
    /// [`Outbox::pop_numbered`], a port's frames wait while a request to it is pending.
    #[cfg(feature = "fd")]
    pub fn pop_fd_numbered(&mut self) -> Option<(usize, FdFrame, u32)> {
        for p in 0..2 {
            if self.requests.iter().any(|(q, _)| *q == p) {
                continue;
            }
            if let Some((f, n)) = self.fd_frames[p].pop() {
                return Some((p, f, n));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan_core::Id;

    #[test]
    fn a_ports_frames_wait_for_its_pending_request() {
        let mut o = Outbox::new();
        let f = Frame::from_array(Id::Standard(1), []);
        o.request(0, PortRequest::Reinit);
        o.frame(0, f);
        o.frame(1, f);
        assert_eq!(o.pop_frame(), Some((1, f)));
        assert_eq!(o.pop_frame(), None);
        assert_eq!(o.requests.pop(), Some((0, PortRequest::Reinit)));
        assert_eq!(o.pop_frame(), Some((0, f)));
    }
}
