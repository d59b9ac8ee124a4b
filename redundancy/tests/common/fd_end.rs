//! What the CAN FD tests share (`link/fd.rs` on the simulated buses, `runtime/fd.rs` under the
//! tokio runtime): one test device on a dual-bus layer with both ports FD, so that the same
//! device is exercised on both drivers.
#![allow(dead_code)]

use duocan::frame::FdFrame;
use duocan::machine::{BusLink, Device, PortRequest, PortStatus};
use duocan::{Frame, Instant};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEvent};

/// A device whose two ports are a [`DualBus`] with both ports FD: it sends what it is given
/// and records what the layer delivers upward, CAN FD and classic frames apart.
pub struct FdEnd {
    pub link: DualBus,
    pub got: Vec<FdFrame>,
    pub got_classic: Vec<Frame>,
}

impl FdEnd {
    pub fn new() -> Self {
        Self::with_config(DualBusConfig::default())
    }

    /// As [`FdEnd::new`], its layer configured with `cfg` (a wider skew window in an emulated
    /// VM, whose sender may write a frame's two copies further apart than real buses skew).
    pub fn with_config(cfg: DualBusConfig) -> Self {
        let mut link = DualBus::new(cfg);
        link.set_port_fd(0, true);
        link.set_port_fd(1, true);
        FdEnd {
            link,
            got: vec![],
            got_classic: vec![],
        }
    }
}

impl Device for FdEnd {
    type Event = LinkEvent;
    fn port_count(&self) -> usize {
        2
    }
    fn fd_capable(&self) -> bool {
        self.link.fd_capable()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.got_classic
            .extend(self.link.handle_rx(now, port, frame));
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.got_classic
            .extend(self.link.handle_rx_at(now, port, frame, at));
    }
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        self.got
            .extend(self.link.handle_rx_fd_at(now, port, frame, at));
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.link.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.link.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.link.poll_transmit()
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.link.poll_transmit_fd()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.link.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.link.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<LinkEvent> {
        self.link.poll_event()
    }
}
