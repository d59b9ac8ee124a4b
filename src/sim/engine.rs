//! The event loop: what happens at one instant, in which order.

use super::bus::{InFlight, FD_SERIAL};
use super::fault::{chance, flip_bit, nth};
use super::ids::BusId;
use super::timing;
use super::trace::{RxFault, TraceRecord, TxOutcome, TxRecord};
use super::tx_dead::PASSIVE;
use super::SimNetwork;
use crate::frame::instant::{earliest_of, Instant};
use crate::frame::{FdFrame, Frame};
use crate::machine::{ErrorCause, PortStatus};
use core::cmp::Reverse;

impl SimNetwork {
    /// Brings the current instant to rest: touched devices driven, due timeouts run, idle
    /// segments arbitrating.
    pub(super) fn settle(&mut self) {
        self.flush_touched();
        self.run_due_timeouts();
        self.arbitrate();
        self.refill_held();
    }

    /// The next instant with work, if any.
    pub(super) fn next_time(&mut self) -> Option<Instant> {
        self.drop_stale_deadlines();
        let queues = earliest_of([
            self.deadlines.peek().map(|Reverse((t, _))| *t),
            self.delayed.peek().map(|d| d.at),
            self.actions.peek().map(|a| a.at),
        ]);
        let busy = self
            .buses
            .iter()
            .flat_map(|bus| bus.segments.iter().map(|seg| seg.busy.map(|tx| tx.end)));
        earliest_of(core::iter::once(queues).chain(busy))
    }

    /// Everything due at `t`, in the documented order.
    pub(super) fn process_instant(&mut self, t: Instant) {
        self.now = self.now.max(t);
        self.deliver_delayed();
        self.complete_transmissions();
        self.run_actions();
        self.run_due_timeouts();
        self.arbitrate();
        self.refill_held();
    }

    /// Devices blocked on a full queue that just freed a slot hand over their next frames, and
    /// those may start on idle segments at once (a driver refilling the controller).
    fn refill_held(&mut self) {
        while !self.refill.is_empty() {
            let mut list = std::mem::take(&mut self.refill);
            list.sort_unstable();
            list.dedup();
            for &d in &list {
                if self.devices[d as usize].powered {
                    self.flush(d as usize);
                }
            }
            list.clear();
            if self.refill.is_empty() {
                self.refill = list;
            }
            self.arbitrate();
        }
    }

    fn drop_stale_deadlines(&mut self) {
        while let Some(&Reverse((t, d))) = self.deadlines.peek() {
            let dev = &self.devices[d as usize];
            if dev.powered && dev.deadline == Some(t) {
                break;
            }
            self.deadlines.pop();
        }
        // Devices that move their deadline on every frame leave stale entries behind; rebuild
        // before they outnumber the live ones by far.
        if self.deadlines.len() > 4 * self.devices.len() + 1024 {
            self.deadlines = self
                .devices
                .iter()
                .enumerate()
                .filter(|(_, d)| d.powered)
                .filter_map(|(i, d)| d.deadline.map(|t| Reverse((t, i as u32))))
                .collect();
        }
    }

    fn flush_touched(&mut self) {
        if self.touched.is_empty() {
            return;
        }
        let mut list = std::mem::take(&mut self.touched);
        list.sort_unstable();
        for &d in &list {
            let d = d as usize;
            self.devices[d].touched = false;
            if self.devices[d].powered {
                self.devices[d].dev.handle_timeout(self.now);
                self.flush(d);
            }
        }
        list.clear();
        self.touched = list;
    }

    fn run_due_timeouts(&mut self) {
        let now = self.now;
        while let Some(&Reverse((t, d))) = self.deadlines.peek() {
            if t > now {
                break;
            }
            self.deadlines.pop();
            let dev = &mut self.devices[d as usize];
            if !dev.powered || dev.deadline != Some(t) {
                continue;
            }
            dev.deadline = None;
            if dev.spin_at == now {
                dev.spins += 1;
            } else {
                dev.spin_at = now;
                dev.spins = 1;
            }
            dev.dev.handle_timeout(now);
            self.flush(d as usize);
        }
    }

    fn run_actions(&mut self) {
        while self.actions.peek().is_some_and(|a| a.at <= self.now) {
            let Some(action) = self.actions.pop() else {
                break;
            };
            self.in_action = true;
            (action.item)(self);
            self.in_action = false;
            self.flush_touched();
        }
    }

    fn complete_transmissions(&mut self) {
        for b in 0..self.buses.len() {
            for s in 0..self.buses[b].segments.len() {
                if self.buses[b].segments[s]
                    .busy
                    .is_some_and(|tx| tx.end <= self.now)
                {
                    self.complete(b, s);
                }
            }
        }
    }

    fn arbitrate(&mut self) {
        for b in 0..self.buses.len() {
            for s in 0..self.buses[b].segments.len() {
                let seg = &self.buses[b].segments[s];
                if seg.busy.is_some() {
                    continue;
                }
                if let Some(&(_, p)) = seg.ready.first() {
                    self.start_tx(b, s, p as usize);
                }
            }
        }
    }

    fn start_tx(&mut self, b: usize, s: usize, p: usize) {
        let port = &mut self.ports[p];
        let mut fd = None;
        let (frame, serial, babble) = match (port.babble, port.queue.front()) {
            (Some(f), _) => (f, None, true),
            (None, Some(&(f, serial, _))) => {
                port.queue.pop_front();
                let serial = if serial & FD_SERIAL != 0 {
                    fd = port.fd_queue.pop_front();
                    serial & !FD_SERIAL
                } else {
                    serial
                };
                let owner = port.dev;
                if self.devices[owner as usize].held.is_some() {
                    self.refill.push(owner);
                }
                (f, Some(serial), false)
            }
            (None, None) => {
                self.refresh_port(p);
                return;
            }
        };
        port.transmitting = true;
        port.stats.tx_attempts += 1;
        let generation = self.devices[port.dev as usize].generation;
        self.refresh_port(p);
        let len = fd.as_ref().map_or(frame.data().len(), |f| f.data().len());
        let mut error = self.draw_detected_error(b, s, p, len);
        let mut refused = false;
        let (bits, duration) = match &fd {
            None => {
                let bits = if error {
                    timing::error_frame_bits(&frame)
                } else {
                    timing::frame_bits(&frame)
                };
                (bits, timing::bits_duration(bits, self.buses[b].bitrate))
            }
            Some(f) => {
                refused = self.classic_receiver(b, s, p);
                error |= refused;
                self.fd_wire(b, f, error)
            }
        };
        let bus = &mut self.buses[b];
        let end = self.now + duration;
        bus.segments[s].fd = fd;
        bus.segments[s].busy = Some(InFlight {
            start: self.now,
            end,
            sender: p as u32,
            generation,
            frame,
            serial,
            bits,
            babble,
            error,
            refused,
        });
    }

    /// Whether a live receiver on segment `s` is classic-only: its controller answers a CAN FD
    /// frame with error frames (possible on a classic bus only: a CAN FD bus takes no
    /// classic-only device).
    fn classic_receiver(&self, b: usize, s: usize, sender: usize) -> bool {
        self.buses[b].segments[s].members.iter().any(|&m| {
            let port = &self.ports[m as usize];
            m as usize != sender
                && !port.fd_capable
                && port.iface_up
                && self.devices[port.dev as usize].powered
        })
    }

    /// Bits and wire time of a CAN FD frame on bus `b`: both phases (see
    /// [`timing::fd_frame_duration`]); an error frame, as for classic frames, 7 bits (at the
    /// nominal rate) more than the good frame.
    fn fd_wire(
        &self,
        b: usize,
        f: &crate::frame::FdFrame,
        error: bool,
    ) -> (u32, crate::frame::instant::Duration) {
        let bus = &self.buses[b];
        let bits = timing::fd_frame_bits(f).total();
        let good = timing::fd_frame_duration(f, bus.bitrate, bus.data_bitrate);
        if error {
            (bits + 7, good + timing::bits_duration(7, bus.bitrate))
        } else {
            (bits, good)
        }
    }

    /// Whether the frame starting on segment `s`, `len` data bytes, will be destroyed by a
    /// detected error.
    fn draw_detected_error(&mut self, b: usize, s: usize, sender: usize, len: usize) -> bool {
        let bus = &self.buses[b];
        let rate = bus.faults.map_or(0.0, |f| f.corrupt_detected);
        if chance(&mut self.rng, rate) {
            return true;
        }
        let long = bus
            .faults
            .filter(|f| len >= usize::from(f.long_from))
            .map_or(0.0, |f| f.corrupt_long);
        if chance(&mut self.rng, long) {
            return true;
        }
        let own = self.ports[sender].faults.map_or(0.0, |f| f.corrupt_sent);
        if chance(&mut self.rng, own) {
            return true;
        }
        let bus = &self.buses[b];
        if bus.detect_ports == 0 {
            return false;
        }
        for &m in &bus.segments[s].members {
            let port = &self.ports[m as usize];
            let rate = port.faults.map_or(0.0, |f| f.corrupt_detected);
            // An error-passive receiver's error flag is recessive: it destroys nothing (see
            // `passive_flags`, drawn when the frame ends).
            if m as usize != sender
                && port.iface_up
                && port.bus_off.is_none()
                && port.tec < PASSIVE
                && self.devices[port.dev as usize].powered
                && chance(&mut self.rng, rate)
            {
                return true;
            }
        }
        false
    }

    fn complete(&mut self, b: usize, s: usize) {
        let Some(tx) = self.buses[b].segments[s].busy.take() else {
            return;
        };
        let fd = self.buses[b].segments[s].fd.take();
        let p = tx.sender as usize;
        let d = self.ports[p].dev as usize;
        self.ports[p].transmitting = false;
        let flushed = core::mem::take(&mut self.ports[p].flushed);

        let mut rx = std::mem::take(&mut self.receivers);
        rx.clear();
        for &m in &self.buses[b].segments[s].members {
            let port = &self.ports[m as usize];
            if m != tx.sender
                && port.iface_up
                && port.bus_off.is_none()
                && self.devices[port.dev as usize].powered
            {
                rx.push(m);
            }
        }
        // A dead transmitter cannot acknowledge: with nobody else, the frame is not acked and
        // its error flag destroys it for every receiver.
        let acked = rx.iter().any(|&m| !self.ports[m as usize].tx_dead);
        let alive = self.devices[d].powered && self.devices[d].generation == tx.generation;
        let outcome = if !alive {
            TxOutcome::SenderOff
        } else if !self.buses[b].up {
            TxOutcome::BusDown
        } else if !self.ports[p].connected {
            TxOutcome::SenderDisconnected
        } else if !acked {
            TxOutcome::NoAck
        } else if tx.error {
            TxOutcome::ErrorFrame
        } else {
            TxOutcome::Delivered {
                receivers: rx.len() as u32,
            }
        };
        if let (TxOutcome::ErrorFrame, Some(serial), false, false) =
            (outcome, tx.serial, flushed, tx.refused)
        {
            self.requeue(p, &tx, serial, fd);
        }
        self.refresh_port(p);

        let stats = &mut self.buses[b].stats;
        stats.attempts += 1;
        stats.busy_bits += u64::from(tx.bits);
        stats.busy_time = stats.busy_time + (tx.end - tx.start);
        match outcome {
            TxOutcome::Delivered { .. } => stats.delivered += 1,
            TxOutcome::ErrorFrame => stats.error_frames += 1,
            _ => stats.lost += 1,
        }
        self.record_tx(b, s, &tx, fd.as_ref(), outcome);

        let sender_status = match outcome {
            // Refused by a classic-only receiver: not retried (a real controller would retry
            // until it or the classic nodes went error passive).
            TxOutcome::ErrorFrame if tx.refused => Some(PortStatus::TxFailed(ErrorCause::Form)),
            TxOutcome::SenderOff | TxOutcome::Aborted => None,
            TxOutcome::BusDown | TxOutcome::SenderDisconnected | TxOutcome::NoAck => {
                Some(PortStatus::TxFailed(ErrorCause::NoAck))
            }
            TxOutcome::ErrorFrame => Some(PortStatus::Error(ErrorCause::Crc)),
            TxOutcome::Delivered { .. } => Some(PortStatus::TxOk),
        };
        if let Some(status) = sender_status {
            if outcome == TxOutcome::ErrorFrame {
                self.ports[p].stats.error_frames += 1;
            }
            if !tx.babble && self.ports[p].iface_up {
                match status {
                    PortStatus::TxOk => self.ports[p].stats.tx_ok += 1,
                    PortStatus::TxFailed(_) => self.ports[p].stats.tx_failed += 1,
                    _ => {}
                }
                self.port_status(p, status);
            }
        }
        if sender_status == Some(PortStatus::TxOk) {
            self.tx_ok_tec(p);
        }
        if alive {
            self.suspend_after(p, tx.end);
        }
        if matches!(outcome, TxOutcome::Delivered { .. }) && self.buses[b].detect_ports > 0 {
            self.passive_flags(b, &mut rx, &tx.frame, fd.as_ref());
        }
        match outcome {
            TxOutcome::ErrorFrame => {
                let cause = if tx.refused {
                    ErrorCause::Form
                } else {
                    ErrorCause::Crc
                };
                for &r in &rx {
                    self.ports[r as usize].stats.error_frames += 1;
                    self.port_status(r as usize, PortStatus::Error(cause));
                }
            }
            TxOutcome::Delivered { .. } if fd.is_some() => {
                if let Some(fd) = &fd {
                    self.deliver_fd_all(b, &rx, fd, (p as u32, tx.serial));
                }
            }
            TxOutcome::Delivered { .. } => {
                if nth(&mut self.buses[b].drop_every) {
                    for &r in &rx {
                        self.drop_rx(b, r as usize, &tx.frame);
                    }
                    self.receivers = rx;
                    return;
                }
                let bus_flip = self.buses[b].faults.map_or(0.0, |f| f.corrupt_undetected);
                let wire = if chance(&mut self.rng, bus_flip) {
                    flip_bit(&mut self.rng, &tx.frame).unwrap_or(tx.frame)
                } else {
                    tx.frame
                };
                let from = (p as u32, tx.serial);
                for &r in &rx {
                    self.deliver(b, r as usize, &tx.frame, &wire, from);
                }
            }
            _ => {}
        }
        self.receivers = rx;
    }

    /// Receivers in `rx` that are error passive and detect an error in the frame that just
    /// ended (their own rate of detected errors) raise a passive error flag: recessive, it
    /// destroys the frame for nobody else, and they alone lose it. Taken out of `rx`.
    fn passive_flags(&mut self, b: usize, rx: &mut Vec<u32>, sent: &Frame, fd: Option<&FdFrame>) {
        let mut k = 0;
        while k < rx.len() {
            let r = rx[k] as usize;
            let port = &self.ports[r];
            let rate = port.faults.map_or(0.0, |f| f.corrupt_detected);
            if port.tec >= PASSIVE && chance(&mut self.rng, rate) {
                rx.remove(k);
                self.ports[r].stats.error_frames += 1;
                self.record_rx_with(b, r, sent, fd, RxFault::Dropped);
                self.port_status(r, PortStatus::Error(ErrorCause::Crc));
            } else {
                k += 1;
            }
        }
    }

    /// Cuts short every frame on the bus's wires (partition or heal); senders retransmit.
    pub(super) fn abort_in_flight(&mut self, b: usize) {
        for s in 0..self.buses[b].segments.len() {
            let Some(mut tx) = self.buses[b].segments[s].busy.take() else {
                continue;
            };
            let fd = self.buses[b].segments[s].fd.take();
            tx.end = self.now;
            let p = tx.sender as usize;
            self.ports[p].transmitting = false;
            let flushed = core::mem::take(&mut self.ports[p].flushed);
            let d = self.ports[p].dev as usize;
            let alive = self.devices[d].generation == tx.generation;
            if let (Some(serial), true, false) = (tx.serial, alive, flushed) {
                self.requeue(p, &tx, serial, fd);
            }
            self.refresh_port(p);
            let stats = &mut self.buses[b].stats;
            stats.attempts += 1;
            stats.aborted += 1;
            stats.busy_time = stats.busy_time + (tx.end - tx.start);
            self.record_tx(b, s, &tx, fd.as_ref(), TxOutcome::Aborted);
        }
    }

    /// Puts a frame whose attempt failed back at the head of its port's queue.
    fn requeue(&mut self, p: usize, tx: &InFlight, serial: u64, fd: Option<crate::frame::FdFrame>) {
        let port = &mut self.ports[p];
        match fd {
            Some(fd) => {
                port.fd_queue.push_front(fd);
                port.queue
                    .push_front((tx.frame, serial | FD_SERIAL, Instant::ZERO));
            }
            None => port.queue.push_front((tx.frame, serial, Instant::ZERO)),
        }
    }

    fn record_tx(
        &mut self,
        b: usize,
        s: usize,
        tx: &InFlight,
        fd: Option<&crate::frame::FdFrame>,
        outcome: TxOutcome,
    ) {
        if !self.recording {
            return;
        }
        let sender = self.port_ref(tx.sender as usize);
        let name = self.devices[sender.device.index()].name.clone();
        self.trace.push(TraceRecord::Tx(TxRecord {
            start: tx.start,
            end: tx.end,
            bus: BusId(b as u32),
            segment: s as u32,
            sender,
            sender_name: name,
            frame: tx.frame,
            fd: fd.map(|f| Box::new(*f)),
            serial: tx.serial,
            babble: tx.babble,
            outcome,
        }));
    }
}
