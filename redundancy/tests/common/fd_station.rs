//! A station on a dual-bus layer with an FD path beside it, for the rigs that run their classic
//! scenarios on CAN FD buses too (`link/sim.rs`, `supervisor/net.rs`).
//!
//! The library's generic `Station<L, M>` is classic-only: neither `BusLink` nor `Machine` has
//! an FD path, so the simulator refuses it on a bus with a data bit rate. [`FdStation`] is that
//! station with what a board's application does beside it: the layer's FD path wired to the
//! simulator, and an application ([`FdApp`]) that decides which frames go out as FD frames and
//! what the machine gets of the FD frames the layer delivers. Its ports are FD when its
//! layer's are ([`DualBus::set_port_fd`]); on classic buses it is the station itself.
#![allow(dead_code)]

use core::ops::{Deref, DerefMut};
use duocan::frame::FdFrame;
use duocan::machine::{forward_commands, forward_requests, Device, PortRequest, PortStatus};
use duocan::{BusLink, Frame, Instant, Machine, Station};
use duocan_redundancy::DualBus;

/// The application beside an [`FdStation`]'s machine; every hook does nothing by default.
pub trait FdApp {
    /// A frame the machine sends: the FD frame to send instead, if any.
    fn widen(&mut self, f: &Frame) -> Option<FdFrame> {
        let _ = f;
        None
    }
    /// A classic frame the layer delivered to the machine at `now`: an FD frame to send on it,
    /// if any.
    fn on_delivered(&mut self, now: Instant, f: &Frame) -> Option<FdFrame> {
        let _ = (now, f);
        None
    }
    /// An FD frame the layer delivered: the classic frame the machine takes for it, if any.
    fn narrow(&mut self, f: &FdFrame) -> Option<Frame> {
        let _ = f;
        None
    }
}

/// A machine on a dual-bus layer, with the FD path of [`FdApp`] beside it.
pub struct FdStation<M, A> {
    pub st: Station<DualBus, M>,
    pub app: A,
    now: Instant,
}

impl<M: Machine, A: FdApp> FdStation<M, A>
where
    M::LinkCommand: Into<<DualBus as BusLink>::Command>,
{
    pub fn new(st: Station<DualBus, M>, app: A) -> Self {
        FdStation {
            st,
            app,
            now: Instant::ZERO,
        }
    }

    fn send_fd(&mut self, f: &FdFrame) {
        self.st
            .link
            .send_fd(self.now, f)
            .expect("an FD application's ports are FD-capable");
    }

    /// Hands what the machine has to send to the layer, FD frames where the application widens
    /// them (what `Station::poll_transmit` does for classic frames alone).
    fn pump(&mut self) {
        while let Some(f) = self.st.machine.poll_transmit() {
            match self.app.widen(&f) {
                Some(fd) => self.send_fd(&fd),
                None => self.st.link.send(self.now, &f),
            }
        }
    }

    fn received(&mut self, now: Instant, port: usize, frame: &Frame, at: Option<Instant>) {
        self.now = now;
        let f = self.st.handle_rx_delivered(now, port, frame, at);
        if let Some(fd) = f.and_then(|f| self.app.on_delivered(now, &f)) {
            self.send_fd(&fd);
        }
    }
}

impl<M, A> Deref for FdStation<M, A> {
    type Target = Station<DualBus, M>;
    fn deref(&self) -> &Self::Target {
        &self.st
    }
}
impl<M, A> DerefMut for FdStation<M, A> {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.st
    }
}

impl<M: Machine, A: FdApp> Device for FdStation<M, A>
where
    M::LinkCommand: Into<<DualBus as BusLink>::Command>,
{
    type Event = <Station<DualBus, M> as Device>::Event;
    fn port_count(&self) -> usize {
        self.st.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.received(now, port, frame, None);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.received(now, port, frame, Some(at));
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.now = now;
        self.st.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.st.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.pump();
        self.st.poll_transmit()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.st.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.st.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        self.st.poll_event()
    }
    fn fd_capable(&self) -> bool {
        self.st.link.fd_capable()
    }
    // Through the layer as `Station` takes a classic frame: the layer's requests and the
    // machine's commands exchanged, what the application makes of the delivered frame to the
    // machine, and the exchange again.
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        self.now = now;
        let Station { link, machine, .. } = &mut self.st;
        let f = link.handle_rx_fd_at(now, port, frame, at);
        forward_requests(now, link, machine);
        forward_commands(now, machine, link);
        if let Some(f) = f.and_then(|f| self.app.narrow(&f)) {
            machine.handle_frame_at(now, &f, at);
            forward_requests(now, link, machine);
            forward_commands(now, machine, link);
        }
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.pump();
        self.st.link.poll_transmit_fd()
    }
}
