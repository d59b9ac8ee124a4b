//! Running a [`Device`] on `embedded_can::nb::Can` drivers: the no_std driver.
//!
//! A microcontroller has no runtime to wait on sockets; its main loop (or an interrupt) calls
//! [`EmbeddedDriver::poll`] with the current time whenever a frame may have arrived or the
//! previous deadline has passed. `poll` moves every received frame into the device, runs what is
//! due, hands every pending frame to the controller, and returns the next deadline to arm a timer
//! with. No allocation: the per-port transmit backlog is a fixed `heapless` queue.
//!
//! Classic CAN only: `embedded_can`'s `Frame` has no CAN FD frame (no 64-byte payload, no BRS
//! or ESI), so this driver neither asks a device for FD frames
//! (`Device::poll_transmit_fd`) nor hands it any. A CAN FD controller needs a driver of its
//! own.
//!
//! Controller errors ([`embedded_can::ErrorKind`]) are reported to the device as port status.
//! [`PortRequest::Reinit`](crate::machine::PortRequest) is handled here: the port's backlog is
//! flushed, the application's restart hook runs if one is installed
//! ([`EmbeddedDriver::with_reinit`]: only the application knows how to restart its controller)
//! and the device is told the port is up again (or down, if the hook failed). A layer waiting for
//! its re-initialisation is therefore never left waiting by an application that forgot it.
//!
//! Frames are handed to the device without receive timestamps ([`Device::handle_rx`], at the
//! `now` of the `poll` that read them): `embedded_can` frames carry none. A dual-bus layer then
//! stamps each frame with the time it is handed over and measures what lag that shows between
//! its ports; call `poll` promptly after a frame arrives (from the receive interrupt) so that
//! the hand-over is close to the frame's time on the bus.
//!
//! A hardware timer may wrap or be resynchronised: `poll` notices a time earlier than the last one
//! and hands it to the device with one `handle_timeout`, so the device re-anchors its timers as
//! the clock contract says ([`crate::frame::instant`]) even with no frame arriving.

use crate::frame::instant::{Instant, TimeWatch};
use crate::frame::Frame;
use crate::machine::{Device, ErrorCause, PortRequest, PortStatus};
use embedded_can::nb::Can;
use embedded_can::{Error as _, ErrorKind};
use heapless::Deque;

/// Frames waiting for a free transmit mailbox, per port.
pub const TX_BACKLOG: usize = 16;
/// Frames read from one port in one `poll` at most (so a babbling bus cannot starve timers).
pub const RX_BURST: usize = 64;

/// What a controller error means for the device.
pub fn status_of(kind: ErrorKind) -> PortStatus {
    match kind {
        ErrorKind::Overrun => PortStatus::Error(ErrorCause::RxOverflow),
        ErrorKind::Bit => PortStatus::Error(ErrorCause::Bit),
        ErrorKind::Stuff => PortStatus::Error(ErrorCause::Stuff),
        ErrorKind::Crc => PortStatus::Error(ErrorCause::Crc),
        ErrorKind::Form => PortStatus::Error(ErrorCause::Form),
        ErrorKind::Acknowledge => PortStatus::TxFailed(ErrorCause::NoAck),
        _ => PortStatus::Error(ErrorCause::Other),
    }
}

/// Counters of one port.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EmbeddedPortStats {
    /// Frames received and handed to the device.
    pub rx_frames: u32,
    /// Received frames the core cannot represent (bad DLC), dropped.
    pub rx_invalid: u32,
    /// Controller errors reported.
    pub errors: u32,
    /// Frames accepted by the controller.
    pub tx_frames: u32,
    /// Frames dropped: backlog full, or the driver's frame type refused them.
    pub tx_dropped: u32,
    /// Re-initialisations the device asked for and the driver performed.
    pub reinits: u32,
}

/// Restarts a controller (bus-off recovery, re-arming filters…); false if it failed.
pub type ReinitHook<C> = fn(&mut C) -> bool;

/// Drives a device over `PORTS` non-blocking CAN drivers.
pub struct EmbeddedDriver<D, C: Can, const PORTS: usize> {
    device: D,
    ports: [C; PORTS],
    backlog: [Deque<C::Frame, TX_BACKLOG>; PORTS],
    stats: [EmbeddedPortStats; PORTS],
    reinit: Option<ReinitHook<C>>,
    clock: TimeWatch,
}

impl<D: Device, C: Can, const PORTS: usize> EmbeddedDriver<D, C, PORTS> {
    /// A driver for `device` on `ports` (port `i` of the device is `ports[i]`).
    #[must_use]
    pub fn new(device: D, ports: [C; PORTS]) -> Self {
        Self::with_device(|| device, ports)
    }

    /// A driver for the device `make` builds, on `ports`: the same as [`new`](Self::new), but
    /// `make` is called last, so that a constructor that is not inlined writes the device
    /// straight into the driver. On a microcontroller the device is tens of kilobytes and
    /// every move of it a copy on the stack.
    #[must_use]
    #[inline]
    pub fn with_device(make: impl FnOnce() -> D, ports: [C; PORTS]) -> Self {
        // Everything else first: a loop between the call and the move would keep the copy.
        let backlog = [const { Deque::new() }; PORTS];
        let stats = [EmbeddedPortStats::default(); PORTS];
        EmbeddedDriver {
            device: make(),
            ports,
            backlog,
            stats,
            reinit: None,
            clock: TimeWatch::new(),
        }
    }

    /// Installs the controller restart the driver runs when the device asks to re-initialise a
    /// port.
    #[must_use]
    pub fn with_reinit(mut self, hook: ReinitHook<C>) -> Self {
        self.reinit = Some(hook);
        self
    }

    /// The device.
    pub fn device(&self) -> &D {
        &self.device
    }
    /// The device, to command it (write the dictionary, send NMT, drain port requests).
    pub fn device_mut(&mut self) -> &mut D {
        &mut self.device
    }
    /// A controller driver (to restart it after bus-off, …).
    pub fn port_mut(&mut self, i: usize) -> Option<&mut C> {
        self.ports.get_mut(i)
    }
    /// Counters of port `i`.
    pub fn stats(&self, i: usize) -> Option<EmbeddedPortStats> {
        self.stats.get(i).copied()
    }
    /// Next event of the device.
    #[must_use]
    pub fn poll_event(&mut self) -> Option<D::Event> {
        self.device.poll_event()
    }

    /// Does everything that can be done at `now`; returns when to call again at the latest
    /// (`None`: only when a frame arrives).
    pub fn poll(&mut self, now: Instant) -> Option<Instant> {
        for i in 0..PORTS {
            self.receive(now, i);
        }
        // A step back of the timer is reported at once, due or not (the clock contract).
        let stepped_back = self.clock.step_back(now).is_some();
        if stepped_back || self.device.poll_timeout().is_some_and(|t| t <= now) {
            self.device.handle_timeout(now);
        }
        self.reinit_requested(now);
        self.transmit(now);
        self.device.poll_timeout()
    }

    fn reinit_requested(&mut self, now: Instant) {
        while let Some((i, PortRequest::Reinit)) = self.device.poll_port_request() {
            let (Some(port), Some(backlog)) = (self.ports.get_mut(i), self.backlog.get_mut(i))
            else {
                continue;
            };
            backlog.clear();
            self.stats[i].reinits = self.stats[i].reinits.wrapping_add(1);
            let ok = self.reinit.is_none_or(|restart| restart(port));
            let status = if ok {
                PortStatus::Up
            } else {
                PortStatus::Down(ErrorCause::Other)
            };
            self.device.handle_port_status(now, i, status);
        }
    }

    fn receive(&mut self, now: Instant, i: usize) {
        for _ in 0..RX_BURST {
            match self.ports[i].receive() {
                Ok(f) => match Frame::from_embedded(&f) {
                    Ok(frame) => {
                        self.stats[i].rx_frames = self.stats[i].rx_frames.wrapping_add(1);
                        self.device.handle_rx(now, i, &frame);
                    }
                    Err(_) => self.stats[i].rx_invalid = self.stats[i].rx_invalid.wrapping_add(1),
                },
                Err(nb::Error::WouldBlock) => return,
                Err(nb::Error::Other(e)) => {
                    self.stats[i].errors = self.stats[i].errors.wrapping_add(1);
                    self.device.handle_port_status(now, i, status_of(e.kind()));
                }
            }
        }
    }

    fn transmit(&mut self, now: Instant) {
        while let Some((port, frame)) = self.device.poll_transmit() {
            let Some(q) = self.backlog.get_mut(port) else {
                continue; // a port the driver does not have: nothing can send it
            };
            let queued = frame
                .to_embedded::<C::Frame>()
                .map(|f| q.push_back(f).is_ok());
            if queued != Some(true) {
                self.stats[port].tx_dropped = self.stats[port].tx_dropped.wrapping_add(1);
            }
        }
        for i in 0..PORTS {
            while let Some(f) = self.backlog[i].pop_front() {
                match self.ports[i].transmit(&f) {
                    Ok(replaced) => {
                        self.stats[i].tx_frames = self.stats[i].tx_frames.wrapping_add(1);
                        if let Some(r) = replaced {
                            // A lower-priority frame left the mailbox: send it later.
                            if self.backlog[i].push_front(r).is_err() {
                                self.stats[i].tx_dropped = self.stats[i].tx_dropped.wrapping_add(1);
                            }
                            break;
                        }
                    }
                    Err(nb::Error::WouldBlock) => {
                        let _ = self.backlog[i].push_front(f);
                        break;
                    }
                    Err(nb::Error::Other(e)) => {
                        self.stats[i].errors = self.stats[i].errors.wrapping_add(1);
                        let status = match status_of(e.kind()) {
                            PortStatus::Error(c) => PortStatus::TxFailed(c),
                            s => s,
                        };
                        self.device.handle_port_status(now, i, status);
                        break;
                    }
                }
            }
        }
    }
}

#[cfg(all(test, feature = "alloc"))]
mod tests {
    use super::*;
    use crate::frame::Id;
    use crate::machine::{Machine, Station};
    use crate::od::{comm, ObjectDictionary};
    use crate::{Duration, Node, NodeConfig, NodeId};

    /// A controller with one mailbox that is busy every other call.
    #[derive(Default)]
    struct Flaky {
        rx: heapless::Deque<Frame, 8>,
        sent: heapless::Vec<Frame, 32>,
        busy: bool,
        fail_next_rx: bool,
    }

    impl Can for Flaky {
        type Frame = Frame;
        type Error = ErrorKind;
        fn transmit(&mut self, f: &Frame) -> nb::Result<Option<Frame>, ErrorKind> {
            self.busy = !self.busy;
            if self.busy {
                return Err(nb::Error::WouldBlock);
            }
            self.sent
                .push(*f)
                .map_err(|_| nb::Error::Other(ErrorKind::Overrun))?;
            Ok(None)
        }
        fn receive(&mut self) -> nb::Result<Frame, ErrorKind> {
            if core::mem::take(&mut self.fail_next_rx) {
                return Err(nb::Error::Other(ErrorKind::Crc));
            }
            self.rx.pop_front().ok_or(nb::Error::WouldBlock)
        }
    }

    #[test]
    fn drives_a_node_through_a_busy_mailbox() {
        let id = NodeId::new(5).unwrap();
        let mut od = comm::standard_dictionary(5, comm::Identity::default());
        od.write_local(comm::HEARTBEAT_PRODUCER, 0, &100u16.to_le_bytes())
            .unwrap();
        let mut node = Node::new(NodeConfig::slave(id), od);
        node.boot(Instant::ZERO);
        let mut drv = EmbeddedDriver::new(Station::single(node), [Flaky::default()]);
        let mut now = Instant::ZERO;
        let mut deadline = drv.poll(now);
        for _ in 0..10 {
            now = deadline.unwrap_or(now).max(now);
            deadline = drv.poll(now);
            // Retry the busy mailbox right away, as a TX-complete interrupt would.
            drv.poll(now);
        }
        let sent = &drv.ports[0].sent;
        assert_eq!(sent[0], Frame::from_array(Id::Standard(0x705), [0x00]));
        assert!(sent[1..].iter().all(|f| f.data() == [0x7F]));
        assert!(sent.len() >= 5, "boot-up and heartbeats went out: {sent:?}");
        // NMT start from the bus, and a CRC error reported as status.
        drv.ports[0].fail_next_rx = true;
        let _ = drv.ports[0]
            .rx
            .push_back(Frame::from_array(Id::Standard(0), [1, 5]));
        drv.poll(now);
        assert_eq!(drv.stats(0).unwrap().errors, 1);
        assert_eq!(drv.stats(0).unwrap().rx_frames, 1);
        assert_eq!(
            drv.device().machine.nmt_state(),
            crate::NmtState::Operational
        );
        assert_eq!(drv.device().link.last_error, Some(ErrorCause::Crc));
        while drv.poll_event().is_some() {}
        let _ = drv.device_mut().machine.poll_event();
    }

    #[test]
    fn a_timer_that_steps_back_is_reported_to_the_device() {
        let id = NodeId::new(5).unwrap();
        let mut od = comm::standard_dictionary(5, comm::Identity::default());
        od.write_local(comm::HEARTBEAT_PRODUCER, 0, &100u16.to_le_bytes())
            .unwrap();
        let mut node = Node::new(NodeConfig::slave(id), od);
        node.boot(Instant::ZERO);
        let mut drv = EmbeddedDriver::new(Station::single(node), [Flaky::default()]);
        let ms = Instant::from_millis;
        assert_eq!(drv.poll(ms(0)), Some(ms(100)));
        // A glitch to an hour ahead: the heartbeat due goes out, the next is on the grid.
        let glitch = Instant::from_secs(3600);
        assert_eq!(drv.poll(glitch), Some(glitch + Duration::from_millis(100)));
        // The timer comes back to 50 ms: with no frame and nothing due by the old clock, the
        // driver still tells the device, whose heartbeat is again 100 ms away.
        assert_eq!(drv.poll(ms(50)), Some(ms(150)));
    }
}
