//! The layer's bounded output queues: frames for the ports, requests for the drivers, events
//! for the application. Overflow is counted, never grown.

use crate::events::LinkEvent;
use duocan::machine::PortRequest;
use duocan::queue::Bounded;
use duocan::Frame;

/// Frames waiting for the driver. The station drains them after every logical frame, so a few
/// suffice (one logical frame fans out to two ports, a channel switch adds an indication).
pub const FRAME_QUEUE: usize = 16;
/// Events waiting for the application: room for a reachability change of every node-ID at one
/// instant plus port and channel events.
pub const EVENT_QUEUE: usize = 160;
/// Requests waiting for the driver.
pub const REQUEST_QUEUE: usize = 8;

/// The output queues a layer's parts (health, reachability, channel policies) write to.
#[derive(Debug, Default)]
pub struct Outbox {
    pub(crate) frames: Bounded<(usize, Frame), FRAME_QUEUE>,
    pub(crate) events: Bounded<LinkEvent, EVENT_QUEUE>,
    pub(crate) requests: Bounded<(usize, PortRequest), REQUEST_QUEUE>,
}

impl Outbox {
    /// Empty queues.
    pub fn new() -> Self {
        Self::default()
    }
    /// Queues an event for the application.
    pub fn event(&mut self, e: LinkEvent) {
        self.events.push(e);
    }
    /// Queues a request for the driver of `port`.
    pub fn request(&mut self, port: usize, r: PortRequest) {
        self.requests.push((port, r));
    }
    /// Queues a frame for `port`.
    pub fn frame(&mut self, port: usize, f: Frame) {
        self.frames.push((port, f));
    }
}
