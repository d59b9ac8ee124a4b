//! The device behind a [`Network`](super::Network): an observing node and an SDO client on
//! its link (one port, or two merged), with a filter on what reaches the wire and a record of
//! every boot-up.

use super::error::NetError;
use super::events::NetEvent;
use super::link::{DriverState, NetLink};
use super::pdo::table::PdoTable;
use crate::cia301::sdo::{RequestId, SdoClient, SdoError, TransferBuffer};
use crate::cia305::codec::MASTER_TO_SLAVE;
use crate::cia305::{LssMaster, LssMasterEvent};
use crate::frame::instant::{Duration, Instant};
use crate::frame::{Frame, Id};
use crate::machine::{
    BusLink, Composite, CompositeEvent, Device, Machine, PortRequest, PortStatus, Station,
    StationEvent,
};
use crate::node::{Node, NodeEventKind};
use crate::od::DynamicDictionary;
use crate::port::PortInput;
use crate::NodeId;
use std::collections::VecDeque;
use std::sync::Arc;
use tokio::sync::Notify;

/// The observing node: it tracks every node's state and consumes heartbeats and EMCY.
pub(crate) type Observer = Node<DynamicDictionary>;
/// The SYNC identifier the producer uses (0x1005's default).
pub(crate) const SYNC_ID: u16 = 0x80;
/// Identities a fastscan plan of the network holds ([`Network::lss`](super::Network::lss)).
pub const LSS_PLAN: usize = 32;
/// The network's LSS master.
pub(crate) type NetLssMaster = LssMaster<LSS_PLAN>;
type Inner = Station<Box<dyn NetLink>, Composite<Composite<Observer, SdoClient>, NetLssMaster>>;

/// What the door tells the network handle: a user event, or an SDO transfer's outcome.
#[derive(Clone, Debug)]
pub(crate) enum DoorEvent {
    /// For the user's event stream.
    Net(NetEvent),
    /// An SDO transfer ended: its request and the data read (empty for a write) or the error.
    Sdo(RequestId, Result<Vec<u8>, SdoError>),
    /// What the LSS master reported.
    Lss(LssMasterEvent),
}

/// Frames of the network's own (RPDOs) waiting for the port: a caller that sends faster
/// than the port drains gets [`NetError::QueueFull`].
const OWN_QUEUE: usize = 64;
/// Decoded PDOs waiting for the runtime's next flush (it flushes after every frame, so one
/// is the usual count): beyond this they are counted and dropped.
const PDO_EVENTS: usize = 256;

/// The observer node and SDO client behind a filter. The observer exists to hear the bus
/// (states, heartbeats, EMCY); it must not *be* a node on it: python `canopen`'s network object
/// sends no boot-up, no heartbeat and answers nothing, and neither does this. So of what the
/// observer produces only NMT commands (0x000) and SDO requests (0x601–0x67F) leave, and SYNC
/// (0x080) while the user has the SYNC producer on ([`Network::start_sync`]), and LSS requests
/// (0x7E5), which only the network's LSS master makes, when the user calls it. The observer's
/// SYNC service is the producer, and it produces only when told to. RPDOs are not the
/// observer's: the door makes them itself ([`Door::send_own`]) from a mapping the user had the
/// network learn, for a node the user named, so they pass. In listen-only mode nothing leaves.
///
/// [`Network::start_sync`]: super::Network::start_sync
pub(crate) struct Door {
    pub inner: Inner,
    pub listen_only: bool,
    /// When each node's last boot-up arrived (index = node-ID), for the boot-up waits: the
    /// record is kept here, in the core, so a boot-up is never missed by a lagging reader.
    pub boot_ups: [Option<Instant>; 128],
    /// The nodes' PDO mappings the network knows.
    pub pdos: PdoTable,
    /// The SYNC producer is on: SYNC frames may leave.
    pub sync_on: bool,
    own: VecDeque<Frame>,
    decoded: VecDeque<NetEvent>,
    /// Decoded PDOs dropped because [`PDO_EVENTS`] were waiting.
    pub pdo_dropped: u64,
    /// Streamed transfers and whom to wake when one has room to fill or data to take
    /// (at most one per client session: an entry goes with its transfer's result).
    pub streams: Vec<(RequestId, Arc<Notify>)>,
    /// The latest instant an input carried: what the machine's frames are handed to the link
    /// with (as a [`Station`] does).
    now: Instant,
    /// What each port's driver last reported (index = port).
    pub drivers: [DriverState; 2],
    /// Watched nodes not yet heard since their watch began: (node, since, due). One entry per
    /// node at most, so 127 at most.
    awaited: Vec<(NodeId, Instant, Instant)>,
}

impl Door {
    pub fn new(inner: Inner, listen_only: bool) -> Self {
        Door {
            inner,
            listen_only,
            boot_ups: [None; 128],
            pdos: PdoTable::default(),
            sync_on: false,
            own: VecDeque::new(),
            decoded: VecDeque::new(),
            pdo_dropped: 0,
            streams: Vec::new(),
            now: Instant::ZERO,
            drivers: [DriverState::default(); 2],
            awaited: Vec::new(),
        }
    }
    /// Expects a heartbeat or boot-up of `node` within `timeout` from `now` (zero: no longer):
    /// [`NetEvent::NotHeard`] at `now + timeout` if none came.
    pub fn await_first(&mut self, now: Instant, node: NodeId, timeout: Duration) {
        self.awaited.retain(|a| a.0 != node);
        if !timeout.is_zero() {
            self.awaited.push((node, now, now + timeout));
        }
    }
    /// Ends the waits a frame of the node ended, and reports those that ran out by `now`.
    fn check_awaited(&mut self, now: Instant) {
        let mut i = 0;
        while let Some(&(node, since, due)) = self.awaited.get(i) {
            let heard = self.node().remote(node).is_some_and(|v| v.seen >= since);
            if heard || due <= now {
                self.awaited.swap_remove(i);
                if !heard {
                    self.decoded.push_back(NetEvent::NotHeard {
                        node,
                        since,
                        at: due,
                    });
                }
            } else {
                i += 1;
            }
        }
    }
    /// Queues a frame the network itself sends (an RPDO).
    pub fn send_own(&mut self, f: Frame) -> Result<(), NetError> {
        if self.listen_only {
            return Err(NetError::ListenOnly { node: None });
        }
        if self.own.len() >= OWN_QUEUE {
            return Err(NetError::QueueFull);
        }
        self.own.push_back(f);
        Ok(())
    }
    pub fn node(&mut self) -> &mut Observer {
        &mut self.inner.machine.a.a
    }
    pub fn client(&mut self) -> &mut SdoClient {
        &mut self.inner.machine.a.b
    }
    pub fn lss(&mut self) -> &mut NetLssMaster {
        &mut self.inner.machine.b
    }
    /// A frame from `port`, with its receive timestamp if its driver gives one. Process data
    /// is decoded from what the link delivers: over two buses a TPDO's two copies are one.
    fn rx(&mut self, now: Instant, port: usize, frame: &Frame, at: Option<Instant>) {
        self.now = now;
        let Some(frame) = self.inner.handle_rx_delivered(now, port, frame, at) else {
            return;
        };
        if let Some((node, pdo, values)) = self.pdos.decode(&frame) {
            if self.decoded.len() < PDO_EVENTS {
                self.decoded.push_back(NetEvent::Pdo {
                    node,
                    pdo,
                    values,
                    at: now,
                });
            } else {
                self.pdo_dropped += 1;
            }
        }
    }
    /// A status of `port`'s driver.
    fn port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.now = now;
        if let Some(d) = self.drivers.get_mut(port) {
            d.on(status);
        }
        self.inner.handle_port_status(now, port, status);
    }
    /// What the link produced itself, each as it came from its port ([`NetLink::poll_input`]).
    fn link_inputs(&mut self, now: Instant) {
        while let Some((port, input)) = self.inner.link.poll_input() {
            match input {
                // No later than now: a link's stamp must not run ahead of its input.
                PortInput::Frame(f, at) => self.rx(now, port, &f, at.map(|a| a.min(now))),
                PortInput::Status(s) => self.port_status(now, port, s),
            }
        }
    }
    fn may_send(&self, f: &Frame) -> bool {
        !self.listen_only
            && (matches!(f.id(), Id::Standard(0) | Id::Standard(0x601..=0x67F))
                || f.id() == MASTER_TO_SLAVE
                || (self.sync_on && f.id() == Id::Standard(SYNC_ID)))
    }
}

impl Device for Door {
    type Event = DoorEvent;

    fn port_count(&self) -> usize {
        self.inner.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.rx(now, port, frame, None);
        self.link_inputs(now);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.rx(now, port, frame, Some(at));
        self.link_inputs(now);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.port_status(now, port, status);
        self.link_inputs(now);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.inner.handle_timeout(now);
        self.link_inputs(now);
        self.check_awaited(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        // The filter sits between the machine and the link: on two buses a frame is judged
        // once, before the link fans it out.
        loop {
            if let Some(x) = self.inner.link.poll_transmit() {
                return Some(x);
            }
            let f = match self.own.pop_front() {
                Some(f) => f,
                None => loop {
                    let f = self.inner.machine.poll_transmit()?;
                    if self.may_send(&f) {
                        break f;
                    }
                },
            };
            self.inner.link.send(self.now, &f);
        }
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.inner.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        let awaited = self.awaited.iter().map(|a| a.2).min();
        crate::frame::instant::earliest_of([self.inner.poll_timeout(), awaited])
    }
    fn poll_event(&mut self) -> Option<DoorEvent> {
        // A wake-up, not an event: a stream's reader or feeder is no business of the
        // subscribers (at a frame each, it would make them lag).
        while let Some(id) = self.client().poll_stream() {
            if let Some((_, n)) = self.streams.iter().find(|(r, _)| *r == id) {
                n.notify_one();
            }
        }
        if let Some(e) = self.decoded.pop_front() {
            return Some(DoorEvent::Net(e));
        }
        loop {
            let e = match self.inner.poll_event()? {
                StationEvent::Link(e) => return Some(DoorEvent::Net(e)),
                StationEvent::Machine(CompositeEvent::A(CompositeEvent::B(s))) => {
                    self.streams.retain(|(r, _)| *r != s.request);
                    let r = s.result.map(|b| TransferBuffer::as_slice(&b).to_vec());
                    return Some(DoorEvent::Sdo(s.request, r));
                }
                StationEvent::Machine(CompositeEvent::B(l)) => return Some(DoorEvent::Lss(l)),
                StationEvent::Machine(CompositeEvent::A(CompositeEvent::A(n))) => n,
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
