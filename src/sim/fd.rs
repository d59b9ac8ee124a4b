//! The receive path of CAN FD frames: the same faults as classic frames (drop, every n-th
//! drop, undetected bit flip, random delay, fixed latency, duplication), kept apart from the
//! classic path so that it stays as it was.

use super::bus::stand_in;
use super::fault::{chance, either, nth, FaultRates};
use super::sched::{DelayedRx, Timed};
use super::trace::RxFault;
use super::{RxNote, SimNetwork};
use crate::frame::instant::{Duration, Instant};
use crate::frame::FdFrame;

/// `frame` with data bit `bit` flipped (0: the most significant bit of byte 0).
pub(super) fn with_bit_flipped(frame: &FdFrame, bit: u16) -> FdFrame {
    let mut data = [0u8; crate::frame::fd::FD_MAX_LEN];
    let len = frame.len();
    data[..len].copy_from_slice(frame.data());
    let bit = usize::from(bit);
    data[bit / 8] ^= 0x80 >> (bit % 8);
    // Same identifier and an FD length: cannot fail.
    FdFrame::new(frame.id(), &data[..len])
        .map(|f| f.with_flags(frame.flags()))
        .unwrap_or(*frame)
}

impl SimNetwork {
    /// Hands a CAN FD frame that ended on the wire of bus `b` to every receiver in `rx`.
    pub(super) fn deliver_fd_all(
        &mut self,
        b: usize,
        rx: &[u32],
        sent: &FdFrame,
        from: (u32, Option<u64>),
    ) {
        let stand = stand_in(sent);
        if nth(&mut self.buses[b].drop_every) {
            for &r in rx {
                self.drop_rx_with(b, r as usize, &stand, Some(sent));
            }
            return;
        }
        let bus_flip = self.buses[b].faults.map_or(0.0, |f| f.corrupt_undetected);
        let flip = if chance(&mut self.rng, bus_flip) && !sent.is_empty() {
            Some(self.rng.u16(0..(sent.len() * 8) as u16))
        } else {
            None
        };
        for &r in rx {
            self.deliver_fd(b, r as usize, sent, flip, from);
        }
    }

    /// [`deliver`](Self::deliver) for a CAN FD frame; `flip` a bus-wide bit flip.
    fn deliver_fd(
        &mut self,
        b: usize,
        r: usize,
        sent: &FdFrame,
        flip: Option<u16>,
        from: (u32, Option<u64>),
    ) {
        let stand = stand_in(sent);
        let mut frame = *sent;
        if let Some(bit) = flip {
            frame = with_bit_flipped(sent, bit);
            self.ports[r].stats.rx_corrupted += 1;
            self.record_rx_with(b, r, &stand, Some(sent), RxFault::CorruptedFd { bit });
        }
        if self.ports[r].drop_every.0 > 0 && nth(&mut self.ports[r].drop_every) {
            self.drop_rx_with(b, r, &stand, Some(sent));
            return;
        }
        let (bus_f, port_f) = (self.buses[b].faults, self.ports[r].faults);
        let latency = self.ports[r].latency;
        if bus_f.is_none() && port_f.is_none() {
            self.enqueue_rx_fd(r, &frame, latency, from);
            return;
        }
        let bf = bus_f.unwrap_or(FaultRates::NONE);
        let pf = port_f.unwrap_or(FaultRates::NONE);
        if chance(&mut self.rng, either(bf.drop, pf.drop)) {
            self.drop_rx_with(b, r, &stand, Some(sent));
            return;
        }
        if chance(&mut self.rng, pf.corrupt_undetected) && !frame.is_empty() {
            let bit = self.rng.u16(0..(frame.len() * 8) as u16);
            frame = with_bit_flipped(&frame, bit);
            self.ports[r].stats.rx_corrupted += 1;
            self.record_rx_with(b, r, &stand, Some(sent), RxFault::CorruptedFd { bit });
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
            self.record_rx_with(b, r, &stand, Some(sent), RxFault::Delayed { until });
        }
        if twice {
            self.ports[r].stats.rx_duplicated += 1;
            self.record_rx_with(b, r, &stand, Some(sent), RxFault::Duplicated);
        }
        self.enqueue_rx_fd(r, &frame, delay, from);
        if twice {
            self.enqueue_rx_fd(r, &frame, delay, from);
        }
    }

    fn enqueue_rx_fd(
        &mut self,
        r: usize,
        frame: &FdFrame,
        delay: Duration,
        from: (u32, Option<u64>),
    ) {
        if delay.is_zero() && self.ports[r].delayed == 0 {
            self.rx_now_fd(r, frame, self.now, from);
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
                frame: stand_in(frame),
                wire: self.now,
                from,
                fd: Some(Box::new(*frame)),
            },
        });
    }

    /// Hands a CAN FD frame that ended on the wire at `wire` to receiver `r` now, stamped with
    /// its wire time (or the hand-over time, for a port that stamps none: see
    /// [`set_port_stamps`](Self::set_port_stamps)).
    pub(super) fn rx_now_fd(
        &mut self,
        r: usize,
        frame: &FdFrame,
        wire: Instant,
        from: (u32, Option<u64>),
    ) {
        if self.rx_hook.is_some() {
            let (receiver, sender) = (self.port_ref(r), self.port_ref(from.0 as usize));
            let note = RxNote {
                wire,
                receiver,
                sender,
                serial: from.1,
                frame: stand_in(frame),
                fd: Some(*frame),
                bridged: None,
            };
            if let Some(hook) = self.rx_hook.as_mut() {
                hook(&note);
            }
        }
        let port = &mut self.ports[r];
        port.stats.rx += 1;
        let (d, local) = (port.dev as usize, port.local as usize);
        let at = if port.stamps {
            port.clock.stamp(wire)
        } else {
            self.now
        };
        self.devices[d].dev.handle_rx_fd(self.now, local, frame, at);
        self.flush(d);
    }
}
