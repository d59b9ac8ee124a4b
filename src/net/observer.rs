//! The core [`Network::open`](super::Network::open) and
//! [`Network::open_link`](super::Network::open_link) build: an observing node and an SDO
//! client on a [`NetLink`], behind a filter on what reaches the wire.

use super::core::{CoreEvent, NetClient, NetCore};
use super::error::NetError;
use super::events::NetEvent;
use super::heard_on::HeardOn;
use super::link::NetLink;
use super::{NetOptions, MAX_TRANSFER, SESSIONS};
use crate::cia301::nmt::{NmtCommand, NmtTarget};
use crate::cia301::sdo::TransferBuffer;
use crate::frame::instant::Instant;
use crate::frame::{FdFrame, Frame, Id};
use crate::machine::{
    BusLink, Composite, CompositeEvent, Device, Machine, PortRequest, PortState, PortStatus,
    Station, StationEvent,
};
use crate::node::{Node, NodeConfig, NodeEventKind};
use crate::od::{comm, DynamicDictionary};
use crate::port::PortInput;
use crate::{NmtState, NodeId};
use std::collections::VecDeque;

/// The observing node: it tracks every node's state and consumes heartbeats and EMCY.
type Observer = Node<DynamicDictionary>;
type Inner = Station<Box<dyn NetLink>, Composite<Observer, NetClient>>;

/// The SYNC identifier the producer uses (0x1005's default).
const SYNC_ID: u16 = 0x80;
/// The node-ID the observer uses internally (it never sends with it, and hears a node 127 on
/// the bus as any other: [`NodeConfig::observer`]).
const OBSERVER_ID: u8 = 127;
/// Frames of the network's own (RPDOs) waiting for the port: a caller that sends faster
/// than the port drains gets [`NetError::QueueFull`].
const OWN_QUEUE: usize = 64;

/// The observer node and SDO client behind a filter. The observer exists to hear
/// the bus (states, heartbeats, EMCY); it must not *be* a node on it: python `canopen`'s
/// network object sends no boot-up, no heartbeat and answers nothing, and neither does this.
/// So of what the observer produces only NMT commands (0x000) and SDO requests (0x601–0x67F)
/// leave, and SYNC (0x080) while the user has the SYNC producer on
/// ([`Network::start_sync`](super::Network::start_sync)). The observer's SYNC service is the
/// producer, and it produces only when told to. RPDOs and LSS requests are not the
/// observer's: the door makes them (from a mapping the user had the network learn, for a
/// node the user named; from the LSS call the user made) and hands them over
/// ([`NetCore::send`]), so they pass. In listen-only mode nothing leaves.
pub(crate) struct ObserverCore {
    inner: Inner,
    listen_only: bool,
    /// The SYNC producer is on: SYNC frames may leave.
    sync_on: bool,
    own: VecDeque<Frame>,
    /// The latest instant an input carried: what the machine's frames are handed to the link
    /// with (as a [`Station`] does).
    now: Instant,
}

impl ObserverCore {
    pub fn new(link: Box<dyn NetLink>, opts: &NetOptions) -> Result<Self, NetError> {
        let id = NodeId::new(OBSERVER_ID).ok_or(NetError::Closed)?;
        let od = comm::standard_dictionary(OBSERVER_ID, comm::Identity::default());
        let mut node = Node::new(NodeConfig::master(id).with_observer(true), od);
        // Booted before the clock starts: its boot-up never leaves (the filter).
        node.boot(Instant::ZERO);
        let client = NetClient::with_sessions(MAX_TRANSFER, SESSIONS);
        Ok(ObserverCore {
            inner: Station::new(link, Composite::new(node, client)),
            listen_only: opts.listen_only,
            sync_on: false,
            own: VecDeque::new(),
            now: Instant::ZERO,
        })
    }
    fn node(&mut self) -> &mut Observer {
        &mut self.inner.machine.a
    }
    fn passes(&self, f: &Frame) -> bool {
        !self.listen_only
            && (matches!(f.id(), Id::Standard(0) | Id::Standard(0x601..=0x67F))
                || (self.sync_on && f.id() == Id::Standard(SYNC_ID)))
    }
    fn sync_refused(code: impl core::fmt::Display) -> NetError {
        NetError::Argument(format!("the SYNC producer refused: {code}"))
    }
}

impl Device for ObserverCore {
    type Event = CoreEvent;

    fn port_count(&self) -> usize {
        self.inner.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.rx(now, port, frame, None);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.rx(now, port, frame, Some(at));
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.now = now;
        self.inner.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.inner.handle_timeout(now);
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
                    if self.passes(&f) {
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
    // CAN FD frames are the door's USDO client's only (the observer serves no USDO): they pass
    // through the link, which merges and fans them out (`NetCore::rx_fd`, `NetCore::send_fd`).
    fn fd_capable(&self) -> bool {
        self.inner.link.fd_capable()
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.inner.link.poll_transmit_fd()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.inner.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<CoreEvent> {
        loop {
            let e = match self.inner.poll_event()? {
                StationEvent::Link(e) => return Some(CoreEvent::Net(e)),
                StationEvent::Machine(CompositeEvent::B(s)) => {
                    let r = s.result.map(|b| TransferBuffer::as_slice(&b).to_vec());
                    return Some(CoreEvent::Sdo(s.request, r));
                }
                StationEvent::Machine(CompositeEvent::A(n)) => n,
            };
            let at = e.at;
            let ev = match e.kind {
                NodeEventKind::BootUp { node } => NetEvent::BootUp { node, at },
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
            return Some(CoreEvent::Net(ev));
        }
    }
}

impl NetCore for ObserverCore {
    fn rx(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        at: Option<Instant>,
    ) -> Option<Frame> {
        self.now = now;
        self.inner.handle_rx_delivered(now, port, frame, at)
    }
    fn rx_fd(
        &mut self,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
    ) -> Option<FdFrame> {
        self.now = now;
        self.inner.link.handle_rx_fd(now, port, frame, at)
    }
    /// `now` is not used, as for [`NetCore::send`]: the link is handed frames at the latest
    /// input's instant.
    fn send_fd(&mut self, _now: Instant, frame: &FdFrame) {
        if !self.listen_only {
            self.inner.link.send_fd(self.now, frame);
        }
    }
    fn poll_input(&mut self) -> Option<(usize, PortInput<Instant>)> {
        self.inner.link.poll_input()
    }
    fn client(&mut self) -> Result<&mut NetClient, NetError> {
        Ok(&mut self.inner.machine.b)
    }
    fn nmt(&mut self, now: Instant, cmd: NmtCommand, target: NmtTarget) -> Result<(), NetError> {
        self.node()
            .nmt_command(now, cmd, target)
            .map_err(|_| NetError::QueueFull)
    }
    fn remote(&self, node: NodeId) -> Option<(NmtState, Instant)> {
        let v = self.inner.machine.a.remote(node)?;
        Some((v.state, v.seen))
    }
    fn watch_heartbeat(&mut self, now: Instant, node: NodeId, ms: u16) -> Result<(), NetError> {
        let entry = (u32::from(node.raw()) << 16) | u32::from(ms);
        self.node()
            .write(
                now,
                comm::HEARTBEAT_CONSUMER,
                node.raw(),
                &entry.to_le_bytes(),
            )
            .map_err(|_| NetError::Closed)
    }
    fn set_sync(&mut self, now: Instant, period_us: Option<u32>) -> Result<(), NetError> {
        let cob = u32::from(SYNC_ID);
        let node = self.node();
        let r = match period_us {
            // Off first: a running producer's period and identifier change only while off.
            Some(us) => node
                .write(now, comm::SYNC_COB_ID, 0, &cob.to_le_bytes())
                .and_then(|()| node.write(now, comm::SYNC_PERIOD, 0, &us.to_le_bytes()))
                .and_then(|()| {
                    node.write(now, comm::SYNC_COB_ID, 0, &(cob | 1 << 30).to_le_bytes())
                }),
            None => node.write(now, comm::SYNC_COB_ID, 0, &cob.to_le_bytes()),
        };
        // The filter lets SYNC out only once the producer runs.
        self.sync_on = period_us.is_some() && r.is_ok();
        r.map_err(Self::sync_refused)
    }
    /// `now` is not used: own frames reach the link with the machine's, at the latest
    /// input's instant.
    fn send(&mut self, _now: Instant, frame: Frame) -> Result<(), NetError> {
        if self.own.len() >= OWN_QUEUE {
            return Err(NetError::QueueFull);
        }
        self.own.push_back(frame);
        Ok(())
    }
    fn may_send(&self, _now: Instant) -> bool {
        !self.listen_only
    }
    fn port_state(&self, port: usize) -> Option<PortState> {
        self.inner.link.port_state(port)
    }
    fn heard_on(&self, node: NodeId) -> Option<HeardOn> {
        self.inner.link.heard_on(node)
    }
    fn as_any_mut(&mut self) -> &mut dyn core::any::Any {
        self
    }
}
