//! The device behind a [`Network`](super::Network): an observing node and an SDO client on
//! one port, with a filter on what reaches the wire and a record of every boot-up.

use super::events::NetEvent;
use crate::cia301::sdo::{RequestId, SdoClient, SdoError, TransferBuffer};
use crate::frame::instant::Instant;
use crate::frame::{Frame, Id};
use crate::machine::{
    Composite, CompositeEvent, Device, PortRequest, PortStatus, SinglePort, Station, StationEvent,
};
use crate::node::{Node, NodeEventKind};
use crate::od::DynamicDictionary;

/// The observing node: it tracks every node's state and consumes heartbeats and EMCY.
pub(crate) type Observer = Node<DynamicDictionary>;
type Inner = Station<SinglePort, Composite<Observer, SdoClient>>;

/// What the door tells the network handle: a user event, or an SDO transfer's outcome.
#[derive(Clone, Debug)]
pub(crate) enum DoorEvent {
    /// For the user's event stream.
    Net(NetEvent),
    /// An SDO transfer ended: its request and the data read (empty for a write) or the error.
    Sdo(RequestId, Result<Vec<u8>, SdoError>),
}

/// The observer node and SDO client behind a filter. The observer exists to hear the bus
/// (states, heartbeats, EMCY); it must not *be* a node on it: python `canopen`'s network object
/// sends no boot-up, no heartbeat and answers nothing, and neither does this. So only NMT
/// commands (0x000) and SDO requests (0x601–0x67F) leave, and in listen-only mode nothing.
pub(crate) struct Door {
    pub inner: Inner,
    pub listen_only: bool,
    /// When each node's last boot-up arrived (index = node-ID), for the boot-up waits: the
    /// record is kept here, in the core, so a boot-up is never missed by a lagging reader.
    pub boot_ups: [Option<Instant>; 128],
}

impl Door {
    pub fn new(inner: Inner, listen_only: bool) -> Self {
        Door {
            inner,
            listen_only,
            boot_ups: [None; 128],
        }
    }
    pub fn node(&mut self) -> &mut Observer {
        &mut self.inner.machine.a
    }
    pub fn client(&mut self) -> &mut SdoClient {
        &mut self.inner.machine.b
    }
    fn may_send(&self, f: &Frame) -> bool {
        !self.listen_only && matches!(f.id(), Id::Standard(0) | Id::Standard(0x601..=0x67F))
    }
}

impl Device for Door {
    type Event = DoorEvent;

    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.inner.handle_rx(now, port, frame);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.inner.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.inner.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        loop {
            let (p, f) = self.inner.poll_transmit()?;
            if self.may_send(&f) {
                return Some((p, f));
            }
        }
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.inner.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.inner.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<DoorEvent> {
        loop {
            let e = match self.inner.poll_event()? {
                StationEvent::Link(never) => match never {},
                StationEvent::Machine(CompositeEvent::B(s)) => {
                    let r = s.result.map(|b| TransferBuffer::as_slice(&b).to_vec());
                    return Some(DoorEvent::Sdo(s.request, r));
                }
                StationEvent::Machine(CompositeEvent::A(n)) => n,
            };
            let at = e.at;
            let ev = match e.kind {
                NodeEventKind::BootUp { node } => {
                    self.boot_ups[usize::from(node.raw())] = Some(at);
                    NetEvent::BootUp { node, at }
                }
                NodeEventKind::RemoteState { node, from, to } => {
                    NetEvent::State { node, from, to, at }
                }
                NodeEventKind::HeartbeatTimeout { node, last } => {
                    NetEvent::HeartbeatLost { node, last, at }
                }
                NodeEventKind::HeartbeatResumed { node } => NetEvent::HeartbeatResumed { node, at },
                NodeEventKind::Emcy { node, msg } => NetEvent::Emcy { node, msg, at },
                // The observer's own state, SYNC, dictionary writes…: not the user's business.
                _ => continue,
            };
            return Some(DoorEvent::Net(ev));
        }
    }
}
