//! The receive path: random per-receiver faults, fixed port latency, late deliveries in order,
//! hand-over to devices.

use super::fault::{chance, either, flip_bit, nth, FaultRates};
use super::ids::BusId;
use super::sched::{DelayedRx, Timed};
use super::trace::{RxFault, RxRecord, TraceRecord};
use super::{RxNote, SimNetwork};
use crate::frame::instant::{Duration, Instant};
use crate::frame::{FdFrame, Frame};
use crate::machine::{ErrorCause, PortStatus};

impl SimNetwork {
    pub(super) fn deliver_delayed(&mut self) {
        while self.delayed.peek().is_some_and(|d| d.at <= self.now) {
            let Some(Timed { item, .. }) = self.delayed.pop() else {
                break;
            };
            let p = item.port as usize;
            let d = self.ports[p].dev as usize;
            if self.devices[d].generation != item.generation || !self.devices[d].powered {
                continue;
            }
            self.ports[p].delayed = self.ports[p].delayed.saturating_sub(1);
            // A closed interface loses what its driver still held.
            if self.ports[p].iface_up {
                match &item.fd {
                    None => self.rx_now(p, &item.frame, item.wire, item.from),
                    Some(fd) => self.rx_now_fd(p, fd, item.wire, item.from),
                }
            }
        }
    }

    pub(super) fn record_rx(&mut self, b: usize, r: usize, frame: &Frame, fault: RxFault) {
        self.record_rx_with(b, r, frame, None, fault);
    }

    /// Records a fault at receiver `r`; `fd` the CAN FD frame `frame` stands in for.
    pub(super) fn record_rx_with(
        &mut self,
        b: usize,
        r: usize,
        frame: &Frame,
        fd: Option<&FdFrame>,
        fault: RxFault,
    ) {
        let port = self.port_ref(r);
        let (at, frame) = (self.now, *frame);
        self.record(|| {
            TraceRecord::Rx(RxRecord {
                at,
                bus: BusId(b as u32),
                port,
                frame,
                fd: fd.map(|f| Box::new(*f)),
                fault,
            })
        });
    }

    /// Receiver `r` misses the frame (controller overflow): counted, traced, reported.
    pub(super) fn drop_rx(&mut self, b: usize, r: usize, sent: &Frame) {
        self.drop_rx_with(b, r, sent, None);
    }

    /// [`drop_rx`](Self::drop_rx) of a frame that may be a CAN FD one.
    pub(super) fn drop_rx_with(&mut self, b: usize, r: usize, sent: &Frame, fd: Option<&FdFrame>) {
        self.ports[r].stats.rx_dropped += 1;
        self.record_rx_with(b, r, sent, fd, RxFault::Dropped);
        self.port_status(r, PortStatus::Error(ErrorCause::RxOverflow));
    }

    /// Hands a frame that ended on the wire to receiver `r`, through its random faults.
    /// `wire` is `sent` after any bus-wide bit flip; `from` its sending port and serial.
    pub(super) fn deliver(
        &mut self,
        b: usize,
        r: usize,
        sent: &Frame,
        wire: &Frame,
        from: (u32, Option<u64>),
    ) {
        if wire != sent {
            self.ports[r].stats.rx_corrupted += 1;
            self.record_rx(b, r, sent, RxFault::Corrupted { delivered: *wire });
        }
        let (bus_f, port_f) = (self.buses[b].faults, self.ports[r].faults);
        let latency = self.ports[r].latency;
        if self.ports[r].drop_every.0 > 0 && nth(&mut self.ports[r].drop_every) {
            self.drop_rx(b, r, sent);
            return;
        }
        if bus_f.is_none() && port_f.is_none() {
            // The common case, a fault-free port with nothing waiting: straight to the device
            // (kept apart so that it stays inlined here, the hottest path of a long soak).
            if latency.is_zero() && self.ports[r].delayed == 0 {
                self.rx_now(r, wire, self.now, from);
            } else {
                self.enqueue_rx(r, wire, latency, from);
            }
            return;
        }
        let bf = bus_f.unwrap_or(FaultRates::NONE);
        let pf = port_f.unwrap_or(FaultRates::NONE);
        if chance(&mut self.rng, either(bf.drop, pf.drop)) {
            self.drop_rx(b, r, sent);
            return;
        }
        let mut frame = *wire;
        if chance(&mut self.rng, pf.corrupt_undetected) {
            if let Some(f) = flip_bit(&mut self.rng, &frame) {
                frame = f;
                self.ports[r].stats.rx_corrupted += 1;
                self.record_rx(b, r, sent, RxFault::Corrupted { delivered: f });
            }
        }
        let random = if chance(&mut self.rng, either(bf.delay, pf.delay)) {
            let max = bf.max_delay.max(pf.max_delay).as_micros().max(1);
            Duration::from_micros(self.rng.u64(1..=max))
        } else {
            Duration::ZERO
        };
        let delay = latency + random;
        let twice = chance(&mut self.rng, either(bf.duplicate, pf.duplicate));
        if !random.is_zero() {
            let until = self.delivery_time(r, delay);
            self.ports[r].stats.rx_delayed += 1;
            self.record_rx(b, r, sent, RxFault::Delayed { until });
        }
        if twice {
            self.ports[r].stats.rx_duplicated += 1;
            self.record_rx(b, r, sent, RxFault::Duplicated);
        }
        self.enqueue_rx(r, &frame, delay, from);
        if twice {
            self.enqueue_rx(r, &frame, delay, from);
        }
    }

    /// When a frame delayed by `delay` reaches port `r`: never before one delayed earlier.
    pub(super) fn delivery_time(&self, r: usize, delay: Duration) -> Instant {
        let port = &self.ports[r];
        let due = self.now + delay;
        if port.delayed > 0 {
            due.max(port.delay_tail)
        } else {
            due
        }
    }

    fn enqueue_rx(&mut self, r: usize, frame: &Frame, delay: Duration, from: (u32, Option<u64>)) {
        if delay.is_zero() && self.ports[r].delayed == 0 {
            self.rx_now(r, frame, self.now, from);
            return;
        }
        let at = self.delivery_time(r, delay);
        let generation = self.devices[self.ports[r].dev as usize].generation;
        let port = &mut self.ports[r];
        port.delayed += 1;
        port.delay_tail = at;
        let seq = self.next_seq();
        self.delayed.push(Timed {
            at,
            seq,
            item: DelayedRx {
                port: r as u32,
                generation,
                frame: *frame,
                wire: self.now,
                from,
                fd: None,
            },
        });
    }

    /// Hands a frame that ended on the wire at `wire`, sent by `from`, to receiver `r` now,
    /// stamped with its wire time unless the port hands frames over without one.
    fn rx_now(&mut self, r: usize, frame: &Frame, wire: Instant, from: (u32, Option<u64>)) {
        if self.rx_hook.is_some() {
            let (receiver, sender) = (self.port_ref(r), self.port_ref(from.0 as usize));
            let note = RxNote {
                wire,
                receiver,
                sender,
                serial: from.1,
                frame: *frame,
                fd: None,
                bridged: self.bridged_origin(from),
            };
            if let Some(hook) = self.rx_hook.as_mut() {
                hook(&note);
            }
        }
        let port = &mut self.ports[r];
        port.stats.rx += 1;
        let (d, local) = (port.dev as usize, port.local as usize);
        if self.bridge.is_some() && self.is_bridge(d) {
            self.bridge_heard(r, frame, wire, from);
            return;
        }
        let port = &self.ports[r];
        if port.stamps {
            let at = port.clock.stamp(wire);
            self.devices[d].dev.handle_rx_at(self.now, local, frame, at);
        } else {
            self.devices[d].dev.handle_rx(self.now, local, frame);
        }
        self.flush(d);
    }
}
