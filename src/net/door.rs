//! The device behind a [`Network`](super::Network): the generic door over a [`NetCore`], with
//! a record of every boot-up, the PDO table and the waits every core shares.

use super::core::{CoreEvent, NetCore, LSS_PLAN};
use super::error::NetError;
use super::events::NetEvent;
use super::link::DriverState;
use super::pdo::table::PdoTable;
use super::pdo::PdoValues;
use super::starts::{Start, Starts};
use super::usdo::{UsdoDoor, UsdoStart};
use crate::cia305::{LssMaster, LssMasterConfig, LssMasterEvent};
use crate::frame::instant::{Duration, Instant};
use crate::frame::{FdFrame, Frame};
use crate::machine::{Device, Machine, PortRequest, PortStatus};
use crate::port::PortInput;
use crate::NodeId;
use std::collections::VecDeque;

/// Decoded PDOs waiting for the runtime's next flush (it flushes after every frame, so one
/// is the usual count): beyond this they are counted and dropped.
const PDO_EVENTS: usize = 256;

/// What waits for the LSS master's results of the request running: true once it has its end.
pub(crate) type LssWatch = Box<dyn FnMut(&LssMasterEvent) -> bool + Send>;

/// The door: the core, and what the door keeps above it for every core.
pub(crate) struct Door {
    /// What sits below: the observer (see [`super::observer`]) or a core the user gave.
    pub core: Box<dyn NetCore>,
    /// When each node's last boot-up arrived (index = node-ID), for the boot-up waits: the
    /// record is kept here, in the runtime, so a boot-up is never missed by a lagging reader.
    pub boot_ups: [Option<Instant>; 128],
    /// The nodes' PDO mappings the network knows.
    pub pdos: PdoTable,
    decoded: VecDeque<NetEvent>,
    /// Decoded PDOs dropped because [`PDO_EVENTS`] were waiting.
    pub pdo_dropped: u64,
    /// SDO transfers started or waiting for the client (see [`super::starts`]).
    starts: Starts,
    /// What each port's driver last reported (index = port).
    pub drivers: [DriverState; 2],
    /// Watched nodes not yet heard since their watch began: (node, since, due). One entry per
    /// node at most, so 127 at most.
    awaited: Vec<(NodeId, Instant, Instant)>,
    /// The network's LSS master (CiA 305), one whatever the core: fed the frames the link
    /// delivers, its requests sent as the network's own frames ([`NetCore::send`]).
    pub lss: LssMaster<LSS_PLAN>,
    /// The caller of the LSS request running (LSS serves one at a time).
    lss_watch: Option<LssWatch>,
    /// LSS requests that could not leave: the core stopped being allowed to send mid-request
    /// (the request then times out), or its queue was full.
    pub lss_dropped: u64,
    /// The latest instant an input, a timeout or a call carried: what LSS requests are handed
    /// to the core with.
    now: Instant,
    /// The USDO client of a CANopen FD network ([`super::usdo`]); `None` on a classic one.
    pub usdo: Option<UsdoDoor>,
}

impl Door {
    pub fn new(core: Box<dyn NetCore>, lss: LssMasterConfig) -> Self {
        Door {
            core,
            boot_ups: [None; 128],
            pdos: PdoTable::default(),
            decoded: VecDeque::new(),
            pdo_dropped: 0,
            starts: Starts::default(),
            drivers: [DriverState::default(); 2],
            awaited: Vec::new(),
            lss: LssMaster::new(lss),
            lss_watch: None,
            lss_dropped: 0,
            now: Instant::ZERO,
            usdo: None,
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
            let heard = self
                .core
                .remote(node)
                .is_some_and(|(_, seen)| seen >= since);
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
    /// Starts an SDO transfer, or parks it while the client is busy ([`super::starts`]); an
    /// error if the core has no client now or the client refuses the transfer itself.
    pub fn sdo(&mut self, now: Instant, start: Start) -> Result<(), NetError> {
        self.starts.submit(self.core.client(), now, start)
    }
    /// Starts a whole-value transfer over USDO, or queues it behind the running one
    /// ([`super::usdo`]); an error if the core may not send now, or the network is classic.
    pub fn usdo(&mut self, now: Instant, start: UsdoStart) -> Result<(), NetError> {
        self.now = now;
        if !self.core.may_send(now) {
            return Err(self.core.send_refused());
        }
        let Some(u) = &mut self.usdo else {
            return Err(NetError::Argument("not a CANopen FD network".into()));
        };
        u.submit(now, start);
        Ok(())
    }
    /// After every input and timeout (and a transfer the door aborted): the parked starts try
    /// again.
    pub fn retry(&mut self, now: Instant) {
        self.starts.retry(self.core.client(), now);
    }
    /// Starts an LSS request with `start` if the core may make one now
    /// ([`NetCore::lss_refused`]); `watch` then sees each of the master's results until it
    /// says it has its end.
    pub fn lss_start<T>(
        &mut self,
        now: Instant,
        start: impl FnOnce(&mut LssMaster<LSS_PLAN>, Instant) -> Result<T, NetError>,
        watch: impl FnOnce(&T) -> LssWatch,
    ) -> Result<T, NetError> {
        self.now = now;
        if let Some(e) = self.core.lss_refused(now) {
            return Err(e);
        }
        let t = start(&mut self.lss, now)?;
        self.lss_watch = Some(watch(&t));
        Ok(t)
    }
    /// Queues a frame the network itself sends (an RPDO), if the core may send now; if not,
    /// the core's reason ([`NetCore::send_refused`]).
    pub fn send_own(&mut self, now: Instant, f: Frame) -> Result<(), NetError> {
        if !self.core.may_send(now) {
            return Err(self.core.send_refused());
        }
        self.core.send(now, f)
    }
    /// [`Door::send_own`] of a CAN FD frame (an RPDO on a CANopen FD network), handed to the
    /// core's link as the USDO client's requests are.
    pub fn send_own_fd(&mut self, now: Instant, f: &FdFrame) -> Result<(), NetError> {
        if !self.core.may_send(now) {
            return Err(self.core.send_refused());
        }
        self.core.send_fd(now, f);
        Ok(())
    }
    /// A decoded TPDO for the event stream, or counted as dropped when its queue is full.
    fn decoded(&mut self, now: Instant, (node, pdo, values): (NodeId, u16, PdoValues)) {
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
    /// A frame from `port`, with its receive timestamp if its driver gives one. Process data
    /// is decoded from what the link delivers: over two buses a TPDO's two copies are one.
    fn rx(&mut self, now: Instant, port: usize, frame: &Frame, at: Option<Instant>) {
        let Some(frame) = self.core.rx(now, port, frame, at) else {
            return;
        };
        self.lss.handle_frame(now, &frame);
        if let Some(decoded) = self.pdos.decode(&frame) {
            self.decoded(now, decoded);
        }
    }
    /// A status of `port`'s driver.
    fn port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        if let Some(d) = self.drivers.get_mut(port) {
            d.on(status);
        }
        self.core.handle_port_status(now, port, status);
    }
    /// What the link produced itself, each as it came from its port ([`NetLink::poll_input`]);
    /// then the parked SDO starts try again, as after every input and timeout.
    fn link_inputs(&mut self, now: Instant) {
        while let Some((port, input)) = self.core.poll_input() {
            match input {
                // No later than now: a link's stamp must not run ahead of its input.
                PortInput::Frame(f, at) => self.rx(now, port, &f, at.map(|a| a.min(now))),
                PortInput::Status(s) => self.port_status(now, port, s),
            }
        }
        self.retry(now);
    }
}

impl Device for Door {
    type Event = CoreEvent;

    fn port_count(&self) -> usize {
        self.core.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.now = now;
        self.rx(now, port, frame, None);
        self.link_inputs(now);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.now = now;
        self.rx(now, port, frame, Some(at));
        self.link_inputs(now);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.now = now;
        self.port_status(now, port, status);
        self.link_inputs(now);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.core.handle_timeout(now);
        self.lss.handle_timeout(now);
        if let Some(u) = &mut self.usdo {
            u.handle_timeout(now);
        }
        self.link_inputs(now);
        self.check_awaited(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        // The LSS master's requests are the network's own frames: the core puts them on every
        // bus, if it may send now.
        while let Some(f) = self.lss.poll_transmit() {
            let now = self.now;
            if !self.core.may_send(now) || self.core.send(now, f).is_err() {
                self.lss_dropped += 1;
            }
        }
        self.core.poll_transmit()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.core.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        let awaited = self.awaited.iter().map(|a| a.2).min();
        crate::frame::instant::earliest_of([
            self.core.poll_timeout(),
            awaited,
            self.starts.due(),
            self.lss.poll_timeout(),
            self.usdo.as_ref().and_then(UsdoDoor::poll_timeout),
        ])
    }
    fn poll_event(&mut self) -> Option<CoreEvent> {
        // A wake-up, not an event: a stream's reader or feeder is no business of the
        // subscribers (at a frame each, it would make them lag).
        while let Some(id) = self.core.client().ok().and_then(|c| c.poll_stream()) {
            self.starts.wake(id);
        }
        // The LSS master's results go to the request's caller only.
        while let Some(e) = self.lss.poll_event() {
            if self.lss_watch.as_mut().is_some_and(|w| w(&e)) {
                self.lss_watch = None;
            }
        }
        if let Some(e) = self.decoded.pop_front() {
            return Some(CoreEvent::Net(e));
        }
        let e = self.core.poll_event()?;
        match &e {
            CoreEvent::Net(NetEvent::BootUp { node, at }) => {
                self.boot_ups[usize::from(node.raw())] = Some(*at);
            }
            CoreEvent::Sdo(id, r) => {
                self.starts.ended(*id, r);
                // Its session is free once its result is taken: a start waiting for one goes
                // now, not at the next input (an idle bus may have none).
                let now = self.now;
                self.retry(now);
            }
            _ => {}
        }
        Some(e)
    }
    fn fd_capable(&self) -> bool {
        self.usdo.is_some()
    }
    /// CAN FD frames, as the core's link delivers them (over two buses, once): a learned TPDO
    /// of a node on a CANopen FD network (decoded as a classic one is, up to 64 bytes), else
    /// the USDO client's answers on 0x580 + a node-ID.
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        self.now = now;
        // No later than now, as a classic frame's stamp.
        let Some(f) = self.core.rx_fd(now, port, frame, at.min(now)) else {
            return;
        };
        if let Some(decoded) = self.pdos.decode_fd(&f) {
            self.decoded(now, decoded);
            return;
        }
        if let Some(u) = &mut self.usdo {
            u.handle_frame(now, &f);
        }
    }
    /// The USDO client's requests, handed to the core's link while the core may send, one at
    /// a time (the link's queue stays short); the link gives each back per port.
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        loop {
            if let Some(x) = self.core.poll_transmit_fd() {
                return Some(x);
            }
            let f = self.usdo.as_mut()?.poll_transmit()?;
            if self.core.may_send(self.now) {
                self.core.send_fd(self.now, &f);
            }
        }
    }
}
