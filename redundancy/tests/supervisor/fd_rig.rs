//! CAN FD process data on the supervised network of `net.rs`: its slaves and masters as
//! FD-capable devices, so that the failover scenarios run on FD buses as on classic ones.
//!
//! The library's generic `Station<L, M>` (a slave board: a node on a dual-bus layer) is
//! classic-only: neither `BusLink` nor `Machine` has an FD path, so the simulator refuses it on
//! a bus with a data bit rate. [`Board`] is that station with the FD path of its layer wired
//! beside it (what a board's application would do), and the application's process data: on
//! every SYNC it delivers, each member of a producing pair sends one 64-byte FD frame (BRS) on
//! its TPDO1 identifier over the dual bus, both members of a pair the same bytes (the same
//! function, as redundant boards compute it). [`FdMaster`] is a redundant master station whose
//! application takes every FD frame its layer delivers, recording when.
#![allow(dead_code)]

use core::ops::{Deref, DerefMut};
use duocan::frame::FdFrame;
use duocan::machine::{forward_commands, forward_requests, Device, PortRequest, PortStatus};
use duocan::od::DynamicDictionary;
use duocan::{Frame, Id, Instant, Node, Station};
use duocan_redundancy::{DualBus, SupervisedStation};

/// The FD frame a producing member sends on the SYNC it was delivered at `at`: its TPDO1
/// identifier, 64 bytes made from the SYNC's instant (equal for both members of a pair, a
/// different frame each cycle).
pub fn process_data(node: u8, at: Instant) -> FdFrame {
    let mut data = [0u8; 64];
    data[..8].copy_from_slice(&at.as_micros().to_le_bytes());
    for (i, b) in data.iter_mut().enumerate().skip(8) {
        *b = data_byte(at, i);
    }
    FdFrame::new(Id::Standard(0x180 + node as u16), &data)
        .unwrap()
        .with_brs(true)
}

fn data_byte(at: Instant, i: usize) -> u8 {
    (at.as_micros() as u8).wrapping_mul(7).wrapping_add(i as u8)
}

/// A slave board: a standard node on a dual-bus layer, FD-capable when its layer is; a
/// producer of FD process data when `produces`.
pub struct Board {
    pub st: Station<DualBus, Node<DynamicDictionary>>,
    pub id: u8,
    pub produces: bool,
}

impl Board {
    /// What the layer delivered to the node: a SYNC has the producer send its process data.
    fn delivered(&mut self, now: Instant, f: Option<Frame>) {
        if self.produces && f.is_some_and(|f| f.id() == Id::Standard(0x80)) {
            self.st
                .link
                .send_fd(now, &process_data(self.id, now))
                .expect("a producer's ports are FD-capable");
        }
    }
}

impl Deref for Board {
    type Target = Station<DualBus, Node<DynamicDictionary>>;
    fn deref(&self) -> &Self::Target {
        &self.st
    }
}
impl DerefMut for Board {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.st
    }
}

impl Device for Board {
    type Event = <Station<DualBus, Node<DynamicDictionary>> as Device>::Event;
    fn port_count(&self) -> usize {
        self.st.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        let f = self.st.handle_rx_delivered(now, port, frame, None);
        self.delivered(now, f);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        let f = self.st.handle_rx_delivered(now, port, frame, Some(at));
        self.delivered(now, f);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.st.handle_port_status(now, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.st.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
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
    // Through the layer (port health, reachability, the merge), and the exchange of requests
    // and commands a classic frame is followed by; the node has no use for FD frames.
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        let Station { link, machine, .. } = &mut self.st;
        let _ = link.handle_rx_fd_at(now, port, frame, at);
        forward_requests(now, link, machine);
        forward_commands(now, machine, link);
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.st.link.poll_transmit_fd()
    }
}

/// A redundant master whose application takes every FD frame its layer delivers, at once:
/// `(when, frame)`.
pub struct FdMaster {
    pub st: SupervisedStation<DynamicDictionary>,
    pub fd_got: Vec<(Instant, FdFrame)>,
}

impl FdMaster {
    pub fn new(st: SupervisedStation<DynamicDictionary>) -> Self {
        FdMaster { st, fd_got: vec![] }
    }
}

impl Deref for FdMaster {
    type Target = SupervisedStation<DynamicDictionary>;
    fn deref(&self) -> &Self::Target {
        &self.st
    }
}
impl DerefMut for FdMaster {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.st
    }
}

impl Device for FdMaster {
    type Event = <SupervisedStation<DynamicDictionary> as Device>::Event;
    duocan::forward_device_to!(st);
    fn poll_event(&mut self) -> Option<Self::Event> {
        self.st.poll_event()
    }
    fn fd_capable(&self) -> bool {
        self.st.fd_capable()
    }
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &FdFrame, at: Instant) {
        self.st.handle_rx_fd(now, port, frame, at);
        while let Some(f) = self.st.poll_fd_frame() {
            self.fd_got.push((now, f));
        }
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.st.poll_transmit_fd()
    }
}
