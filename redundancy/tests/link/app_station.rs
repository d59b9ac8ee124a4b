//! The station of `sim.rs` (a node and the cyclic application on a dual-bus layer) as an
//! [`FdStation`] (the library's generic `Station` is classic-only, see
//! `common/fd_station.rs`): on a CAN FD network its application's TPDO1 (a counter) goes out as
//! a 64-byte FD frame (BRS), and the FD frames its layer delivers come back to the application
//! as the counter they carry, so that the exactly-once checks of `sim.rs` judge FD frames as
//! they judge classic ones.
#![allow(dead_code)]

use super::fd_station::{FdApp, FdStation};
use super::sim::Machines;
use duocan::{FdFrame, Frame};

/// A station of `sim.rs`.
pub type AppStation = FdStation<Machines, WideTpdo1>;

/// TPDO1 (0x181…0x1FF) widened to a 64-byte FD frame when `fd`.
pub struct WideTpdo1 {
    pub fd: bool,
}

fn filler(counter: &[u8], i: usize) -> u8 {
    counter[0].wrapping_mul(13) ^ (i as u8)
}

impl FdApp for WideTpdo1 {
    // The counter (four bytes) and 60 bytes made from it.
    fn widen(&mut self, f: &Frame) -> Option<FdFrame> {
        if !self.fd || !(0x181..=0x1FF).contains(&f.id().raw()) {
            return None;
        }
        let mut data = [0u8; 64];
        let len = f.data().len();
        data[..len].copy_from_slice(f.data());
        for (i, b) in data.iter_mut().enumerate().skip(len) {
            *b = filler(f.data(), i);
        }
        Some(FdFrame::new(f.id(), &data).unwrap().with_brs(true))
    }
    // The TPDO1 `f` was widened from; it must carry exactly the bytes `widen` made (a frame
    // garbled or cut short on its way is a failure, not a counter).
    fn narrow(&mut self, f: &FdFrame) -> Option<Frame> {
        let d = f.data();
        assert_eq!(d.len(), 64, "{f:?}");
        assert!(
            (4..64).all(|i| d[i] == filler(&d[..4], i)),
            "FD frame garbled: {f:?}"
        );
        Some(Frame::new(f.id(), &d[..4]).unwrap())
    }
}
