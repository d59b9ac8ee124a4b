//! The device's state under the lock: the device, its clock and the port queues. What is done
//! with them while the lock is held lives here (inputs handed to the device at their instants,
//! deadlines run in order, what the device has moved into the queues), apart from who takes
//! the lock and whom it wakes ([`super::shared`]), so that each can be read on its own.

use super::Watcher;
use crate::capture::recorder::{Tap, TapDirection, TapPoint};
use crate::frame::FdFrame;
use crate::machine::{Device, PortRequest, PortStatus};
use crate::port::{PortCounters, PortInput};
use crate::runtime::outbox::{Outbox, PortCmd};
use crate::runtime::{Clock, RuntimeEvent, PORT_FD_TX_QUEUE, PORT_TX_QUEUE};
use std::collections::VecDeque;
use std::sync::Arc;
use tokio::sync::broadcast;

/// Timeouts a device may have due at one instant before the runtime moves on: a device whose
/// deadline stays in the past after its timeout ran must not hold a port task forever.
const TIMEOUTS_PER_INPUT: usize = 64;

/// Everything the lock guards.
pub(crate) struct State<D: Device> {
    pub device: Box<D>,
    pub clock: Clock,
    pub counters: Vec<PortCounters>,
    pub events: broadcast::Sender<RuntimeEvent<D::Event>>,
    pub tap: Option<Arc<dyn Tap>>,
    pub watchers: Vec<Watcher<D::Event>>,
    /// The latest instant handed to the device: inputs stamped earlier (read before the
    /// device's last call) are handed over at this instant, so that its time never goes back.
    pub last: crate::Instant,
    /// Per port, what its task is to do, in order; never longer than [`PORT_TX_QUEUE`] (the
    /// room is taken once, when the runtime starts).
    pub queues: Vec<VecDeque<PortCmd>>,
    /// Per port, the CAN FD frames its [`PortCmd::SendFd`] commands stand for, in order; never
    /// longer than [`PORT_FD_TX_QUEUE`]. Empty (no room taken) for a classic device.
    pub fd_queues: Vec<VecDeque<FdFrame>>,
    /// The deadline the core task's timer is set for.
    pub armed: Option<crate::Instant>,
    /// The core task has stopped: port tasks write what is left in their queues, then stop.
    pub closed: bool,
    /// Per port, one bit: its task has written what was left when the runtime stopped (or
    /// has ended).
    pub drained: u64,
}

impl<D: Device> State<D>
where
    D::Event: std::fmt::Debug,
{
    /// A state with room taken for every queue.
    pub fn new(
        device: Box<D>,
        clock: Clock,
        counters: Vec<PortCounters>,
        events: broadcast::Sender<RuntimeEvent<D::Event>>,
        tap: Option<Arc<dyn Tap>>,
    ) -> Self {
        let queues = (0..counters.len())
            .map(|_| VecDeque::with_capacity(PORT_TX_QUEUE))
            .collect();
        let fd_queues = if device.fd_capable() {
            (0..counters.len())
                .map(|_| VecDeque::with_capacity(PORT_FD_TX_QUEUE))
                .collect()
        } else {
            Vec::new()
        };
        State {
            device,
            clock,
            counters,
            events,
            tap,
            watchers: Vec::new(),
            last: crate::Instant::ZERO,
            queues,
            fd_queues,
            armed: None,
            closed: false,
            drained: 0,
        }
    }

    /// The clock's time, as the device's next instant.
    pub fn now(&mut self) -> crate::Instant {
        self.at(self.clock.now())
    }

    /// `t`, or the device's last instant if that is later.
    fn at(&mut self, t: crate::Instant) -> crate::Instant {
        self.last = self.last.max(t);
        self.last
    }

    /// Runs the device's timeouts due by `t`, each at the instant it fell due (or the device's
    /// last instant, if later).
    pub fn timeouts(&mut self, t: crate::Instant) {
        self.due_before(t, true);
    }

    /// Runs the timeouts due before `t` (`t` itself too if `inclusive`): a deadline that
    /// passed before an input was read is handled before that input, at its own instant; one
    /// that falls at the very instant of the input comes after it, as the input arrived in time.
    fn due_before(&mut self, t: crate::Instant, inclusive: bool) {
        for _ in 0..TIMEOUTS_PER_INPUT {
            match self.device.poll_timeout() {
                Some(due) if due < t || (inclusive && due == t) => {
                    let now = self.at(due);
                    self.device.handle_timeout(now);
                }
                _ => return,
            }
        }
    }

    /// Hands `x`, read from `port` at `read_at`, to the device: a frame with its receive
    /// timestamp through [`Device::handle_rx_at`] (the stamp on the runtime's clock, never
    /// after the instant it is handled at), one without through [`Device::handle_rx`].
    pub fn input(&mut self, port: usize, x: PortInput, read_at: crate::Instant) {
        self.due_before(read_at, false);
        let now = self.at(read_at);
        match x {
            PortInput::Frame(f, stamp) => {
                let at = stamp.map(|s| self.clock.instant_of(s).min(now));
                if let Some(t) = &self.tap {
                    t.frame(
                        at.unwrap_or(now),
                        TapPoint::Port(port),
                        TapDirection::Rx,
                        &f,
                    );
                }
                match at {
                    Some(at) => self.device.handle_rx_at(now, port, &f, at),
                    None => self.device.handle_rx(now, port, &f),
                }
            }
            // A transmission confirmed (a port asked to confirm them, one per frame sent): the
            // device's business, no news for logs or subscribers.
            PortInput::Status(PortStatus::TxOk) => {
                self.device.handle_port_status(now, port, PortStatus::TxOk)
            }
            PortInput::Status(status) => {
                match status {
                    PortStatus::Down(_) | PortStatus::TxFailed(_) | PortStatus::Error(_) => {
                        tracing::warn!(port, ?status, "port status")
                    }
                    _ => tracing::info!(port, ?status, "port status"),
                }
                self.device.handle_port_status(now, port, status);
                let _ = self.events.send(RuntimeEvent::Port {
                    at: now,
                    port,
                    status,
                });
            }
        }
    }

    /// Hands a CAN FD frame read from `port` at `read_at` to the device through
    /// [`Device::handle_rx_fd`], with its receive timestamp on the runtime's clock as for a
    /// classic frame (`stamp` none: the instant it is handled at).
    pub fn input_fd(
        &mut self,
        port: usize,
        f: &FdFrame,
        stamp: Option<std::time::Instant>,
        read_at: crate::Instant,
    ) {
        self.due_before(read_at, false);
        let now = self.at(read_at);
        let at = stamp.map_or(now, |s| self.clock.instant_of(s).min(now));
        self.device.handle_rx_fd(now, port, f, at);
    }

    /// Drops the frames queued for `port` (counted as dropped), CAN FD ones too.
    fn drop_sends(&mut self, port: usize) {
        let (Some(q), Some(counters)) = (self.queues.get_mut(port), self.counters.get(port)) else {
            return;
        };
        q.retain(|c| {
            let send = matches!(c, PortCmd::Send(_) | PortCmd::SendFd);
            if send {
                counters.tx_dropped();
            }
            !send
        });
        if let Some(fd) = self.fd_queues.get_mut(port) {
            fd.clear();
        }
    }

    /// Queues `cmd` for `port`; false if the port has no room (or does not exist).
    fn queue(&mut self, port: usize, cmd: PortCmd) -> bool {
        match self.queues.get_mut(port) {
            Some(q) if q.len() < PORT_TX_QUEUE => {
                q.push_back(cmd);
                true
            }
            _ => false,
        }
    }

    /// Moves everything the device has to the port queues and the subscribers; returns the
    /// ports that got work, one bit each (all bits from 63 on for ports past 62).
    pub fn flush(&mut self) -> u64 {
        self.flush_into(None)
    }

    /// [`State::flush`], but frames for the port of `direct` go straight into its outbox while
    /// that port's queue is empty and the outbox has room (a reader thread writing its answers:
    /// no trip through the queue, and the order is kept, as the queue is taken after).
    pub fn flush_into(&mut self, mut direct: Option<(usize, &mut Outbox)>) -> u64 {
        let bit = |port: usize| 1u64 << port.min(63);
        let mut woken = 0;
        // Only the tap needs the time: read the clock once, and only for it.
        let mut now = None;
        // Taking an event may give the device more to send (a transfer waiting for a session
        // starts when another's result is taken): until a round takes none.
        let mut again = true;
        while std::mem::take(&mut again) {
            while let Some((port, f)) = self.device.poll_transmit() {
                if port >= self.queues.len() {
                    tracing::error!(port, "device sent on a port it does not have");
                    continue;
                }
                if let Some(t) = &self.tap {
                    let at = *now.get_or_insert_with(|| self.clock.now());
                    t.frame(at, TapPoint::Port(port), TapDirection::Tx, &f);
                }
                let cmd = match &mut direct {
                    Some((own, into)) if *own == port && self.queues[port].is_empty() => {
                        match into.push_back(PortCmd::Send(f)) {
                            Ok(()) => continue,
                            Err(cmd) => cmd,
                        }
                    }
                    _ => PortCmd::Send(f),
                };
                if self.queue(port, cmd) {
                    woken |= bit(port);
                } else {
                    // The port cannot keep up (or is down): drop rather than stall the device.
                    self.counters[port].tx_dropped();
                    tracing::debug!(port, frame = %f, "port queue full, frame dropped");
                }
            }
            self.flush_fd(&mut woken);
            while let Some((port, req)) = self.device.poll_port_request() {
                tracing::info!(port, ?req, "port request");
                // A re-initialisation flushes the port: what waits for it was given up by
                // the device (a stalled port's frames would only come out late, as
                // duplicates of their twins), so it does not go out before the re-opening.
                if req == PortRequest::Reinit {
                    self.drop_sends(port);
                }
                if self.queue(port, PortCmd::Request(req)) {
                    woken |= bit(port);
                }
            }
            while let Some(e) = self.device.poll_event() {
                again = true;
                tracing::debug!(event = ?e, "event");
                // Watchers see every event, losslessly, before subscribers (who may lag).
                self.watchers.retain_mut(|w| !w(&e));
                // No subscriber is fine: events are then only logged (and not stored).
                if self.events.receiver_count() > 0 {
                    let _ = self.events.send(RuntimeEvent::Device(e));
                }
            }
        }
        woken
    }
}

impl<D: Device> State<D> {
    /// Moves the CAN FD frames the device has into their ports' FD queues, each with a
    /// [`PortCmd::SendFd`] in the port's queue; a frame for a full queue (or from a device
    /// that said it is classic) is dropped and counted.
    fn flush_fd(&mut self, woken: &mut u64) {
        if self.fd_queues.is_empty() {
            return;
        }
        while let Some((port, f)) = self.device.poll_transmit_fd() {
            let (Some(q), Some(fd)) = (self.queues.get_mut(port), self.fd_queues.get_mut(port))
            else {
                tracing::error!(
                    port,
                    "device sent a CAN FD frame on a port it does not have"
                );
                continue;
            };
            if q.len() < PORT_TX_QUEUE && fd.len() < PORT_FD_TX_QUEUE {
                fd.push_back(f);
                q.push_back(PortCmd::SendFd);
                *woken |= 1u64 << port.min(63);
            } else {
                self.counters[port].tx_dropped();
                tracing::debug!(port, frame = %f, "port queue full, CAN FD frame dropped");
            }
        }
    }
}
