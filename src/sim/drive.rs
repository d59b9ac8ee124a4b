//! Driving one device: reporting to it, draining it into the port controllers, tracking its
//! deadline, and keeping each port's place in its segment's arbitration.

use super::bus::{stand_in, FD_SERIAL};
use super::SimNetwork;
use crate::frame::instant::{Duration, Instant};
use crate::frame::{FdFrame, Frame};
use crate::machine::{ErrorCause, PortRequest, PortStatus};
use core::cmp::Reverse;

/// `handle_timeout` calls one device may need at one instant before the simulator assumes it
/// will never be satisfied and moves its deadline 1 µs on.
const SPIN_LIMIT: u32 = 64;
/// Rounds of "deliver the statuses a drain produced, drain again" before the rest are dropped:
/// a device that answers every `TxFailed` by resending to the same full queue would loop.
const STATUS_ROUNDS: u32 = 16;

impl SimNetwork {
    /// Reports `status` on port `p` to its device now, if it has power.
    pub(super) fn port_status(&mut self, p: usize, status: PortStatus) {
        let (d, local) = (self.ports[p].dev as usize, self.ports[p].local as usize);
        if self.devices[d].powered {
            self.devices[d]
                .dev
                .handle_port_status(self.now, local, status);
            self.flush(d);
        }
    }

    /// Drains what the device has for the simulator after an input: frames into port queues,
    /// port requests, events into its log, and its new deadline.
    pub(super) fn flush(&mut self, d: usize) {
        let now = self.now;
        let mut rounds = 0;
        loop {
            if let Some((port, frame, serial)) = self.devices[d].held.take() {
                let fd = self.devices[d].held_fd.take();
                if !self.enqueue_tx(d, port, frame, serial, fd.as_ref()) {
                    self.devices[d].held = Some((port, frame, serial));
                    self.devices[d].held_fd = fd;
                }
            }
            if self.devices[d].held.is_none() {
                while let Some((port, frame)) = self.devices[d].dev.poll_transmit() {
                    let serial = self.devices[d].pulled;
                    self.devices[d].pulled += 1;
                    if !self.enqueue_tx(d, port, frame, serial, None) {
                        self.devices[d].held = Some((port, frame, serial));
                        break;
                    }
                }
            }
            // CAN FD frames: asked only of FD-capable devices, after the classic ones.
            if self.devices[d].fd_capable && self.devices[d].held.is_none() {
                self.pull_fd(d);
            }
            while let Some((port, req)) = self.devices[d].dev.poll_port_request() {
                self.port_request(d, port, req);
            }
            if self.statuses.is_empty() {
                break;
            }
            let mut statuses = std::mem::take(&mut self.statuses);
            rounds += 1;
            if rounds <= STATUS_ROUNDS {
                for (port, status) in statuses.drain(..) {
                    self.devices[d].dev.handle_port_status(now, port, status);
                }
            }
            statuses.clear();
            self.statuses = statuses;
            if rounds > STATUS_ROUNDS {
                break;
            }
        }
        // With recording off nobody keeps the whole history: the log is bounded.
        let cap = (!self.recording).then_some(self.event_capacity);
        let dropped = self.devices[d].dev.record_events(now, cap);
        self.devices[d].events_dropped += dropped;
        let deadline = self.devices[d].dev.poll_timeout();
        self.set_deadline(d, deadline);
    }

    /// Takes the device's CAN FD frames into its port queues until one is full.
    fn pull_fd(&mut self, d: usize) {
        while let Some((port, fd)) = self.devices[d].dev.poll_transmit_fd() {
            let serial = self.devices[d].pulled | FD_SERIAL;
            self.devices[d].pulled += 1;
            let frame = stand_in(&fd);
            if !self.enqueue_tx(d, port, frame, serial, Some(&fd)) {
                self.devices[d].held = Some((port, frame, serial));
                self.devices[d].held_fd = Some(fd);
                break;
            }
        }
    }

    fn set_deadline(&mut self, d: usize, deadline: Option<Instant>) {
        let now = self.now;
        let dev = &mut self.devices[d];
        let mut due = deadline.map(|t| t.max(now));
        if due == Some(now) && dev.spin_at == now && dev.spins >= SPIN_LIMIT {
            due = Some(now + Duration::from_micros(1));
        }
        if due != dev.deadline {
            dev.deadline = due;
            if let Some(t) = due {
                self.deadlines.push(Reverse((t, d as u32)));
            }
        }
    }

    /// Hands a frame to a port controller (a CAN FD one: `frame` its stand-in, `serial` with
    /// [`FD_SERIAL`]). False when the queue is full: the caller holds the frame and stops
    /// pulling until a slot frees.
    fn enqueue_tx(
        &mut self,
        d: usize,
        local: usize,
        frame: Frame,
        serial: u64,
        fd: Option<&FdFrame>,
    ) -> bool {
        let dev = &mut self.devices[d];
        if local >= dev.ports as usize {
            dev.misaddressed += 1;
            return true;
        }
        let p = dev.first_port as usize + local;
        let port = &mut self.ports[p];
        if !port.iface_up {
            port.stats.tx_failed += 1;
            self.statuses
                .push((local, PortStatus::TxFailed(ErrorCause::InterfaceDown)));
            return true;
        }
        if port.queue.len() >= port.capacity {
            port.stats.tx_blocked += 1;
            return false;
        }
        let due = self.now + port.tx_latency;
        if due > self.now {
            port.stats.tx_waited += 1;
        }
        if let Some(fd) = fd {
            port.fd_queue.push_back(*fd);
        }
        port.queue.push_back((frame, serial, due));
        if port.queue.len() == 1 {
            self.refresh_port(p);
        }
        true
    }

    fn port_request(&mut self, d: usize, local: usize, req: PortRequest) {
        let dev = &mut self.devices[d];
        if local >= dev.ports as usize {
            dev.misaddressed += 1;
            return;
        }
        let p = dev.first_port as usize + local;
        match req {
            PortRequest::Reinit => {
                self.restart_now(p);
                self.ports[p].queue.clear();
                self.ports[p].fd_queue.clear();
                self.ports[p].flushed = self.ports[p].transmitting;
                self.refresh_port(p);
                let port = &self.ports[p];
                if !port.iface_up {
                    self.statuses
                        .push((local, PortStatus::Down(ErrorCause::InterfaceDown)));
                } else if port.connected {
                    self.statuses.push((local, PortStatus::Up));
                }
            }
        }
    }

    /// Puts port `p`'s entry in its segment's ready set in line with its state.
    pub(super) fn refresh_port(&mut self, p: usize) {
        let port = &self.ports[p];
        let live = self.devices[port.dev as usize].powered
            && port.iface_up
            && !port.transmitting
            && port.bus_off.is_none()
            && !self.is_suspended(p);
        // A dead transmitter never reaches the wire: its attempts fail on their own.
        if live && port.tx_dead && matches!(port.head(self.now), Ok(Some(_))) {
            self.arm_dead_attempt(p);
        }
        let port = &self.ports[p];
        let want = match port.head(self.now) {
            Ok(head) if live && !port.tx_dead => head.map(|f| (port.seg, f.arbitration_key())),
            Err(due) if live && port.wake != Some(due) => {
                self.ports[p].wake = Some(due);
                self.at(due, move |s| {
                    s.ports[p].wake = None;
                    s.refresh_port(p);
                });
                None
            }
            _ => None,
        };
        let port = &self.ports[p];
        if want == port.ready {
            return;
        }
        let bus = &mut self.buses[port.bus as usize];
        if let Some((s, key)) = port.ready {
            bus.segments[s as usize].ready.remove(&(key, p as u32));
        }
        if let Some((s, key)) = want {
            bus.segments[s as usize].ready.insert((key, p as u32));
        }
        self.ports[p].ready = want;
    }
}
