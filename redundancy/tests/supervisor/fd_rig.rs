//! CAN FD process data on the supervised network of `net.rs`: its slaves and masters as
//! FD-capable devices, so that the failover scenarios run on FD buses as on classic ones.
//!
//! A slave [`Board`] is an [`FdStation`] (the library's generic `Station` is classic-only, see
//! `common/fd_station.rs`) whose application sends the process data: on every SYNC it
//! delivers, each member of a producing pair sends one 64-byte FD frame (BRS) on its TPDO1
//! identifier over the dual bus, both members of a pair the same bytes (the same function, as
//! redundant boards compute it), the standby too (its frames are what the same-function merge
//! must hold back). [`FdMaster`] is a redundant master station whose application
//! takes every FD frame its layer delivers, recording when.
#![allow(dead_code)]

use crate::fd_station::{FdApp, FdStation};
use core::ops::{Deref, DerefMut};
use duocan::frame::FdFrame;
use duocan::machine::Device;
use duocan::od::DynamicDictionary;
use duocan::{Frame, Id, Instant, Node};
use duocan_redundancy::SupervisedStation;

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

/// The application of a slave board (a standard node on a dual-bus layer): a producer of FD
/// process data (`produces`) sends it on every SYNC the layer delivers.
pub struct SyncProducer {
    pub id: u8,
    pub produces: bool,
}

impl FdApp for SyncProducer {
    fn on_delivered(&mut self, now: Instant, f: &Frame) -> Option<FdFrame> {
        (self.produces && f.id() == Id::Standard(0x80)).then(|| process_data(self.id, now))
    }
}

/// A slave board: a node on a dual-bus layer, FD-capable when its layer is.
pub type Board = FdStation<Node<DynamicDictionary>, SyncProducer>;

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
