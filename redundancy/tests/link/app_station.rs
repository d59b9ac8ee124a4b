//! The station of `sim.rs` (a node and the cyclic application on a dual-bus layer), which on a
//! CAN FD network sends its application's TPDO1 (a counter) as a 64-byte FD frame (BRS) and
//! hands the FD frames its layer delivers back to the application as the counter they carry,
//! so that the exactly-once checks of `sim.rs` judge FD frames as they judge classic ones.
//!
//! A wrapper, because the library's generic `Station<L, M>` is classic-only (neither `BusLink`
//! nor `Machine` has an FD path): this is what a board's application does beside its station.
#![allow(dead_code)]

use super::sim::Machines;
use core::ops::{Deref, DerefMut};
use duocan::machine::{Device, PortRequest, PortStatus};
use duocan::{BusLink, Frame, Instant, Machine, Station};
use duocan_redundancy::DualBus;

/// A station of `sim.rs`; `fd`: its TPDO1 goes out as an FD frame.
pub struct AppStation {
    pub st: Station<DualBus, Machines>,
    pub fd: bool,
    now: Instant,
}

impl AppStation {
    /// A classic station.
    pub fn new(st: Station<DualBus, Machines>) -> Self {
        AppStation {
            st,
            fd: false,
            now: Instant::ZERO,
        }
    }

    /// Hands what the machine has to send to the layer: TPDO1 (0x181…0x1FF) as an FD frame on
    /// an FD network, everything else as it is.
    fn pump(&mut self) {
        while let Some(f) = self.st.machine.poll_transmit() {
            #[cfg(feature = "fd")]
            if self.fd && (0x181..=0x1FF).contains(&f.id().raw()) {
                self.st
                    .link
                    .send_fd(self.now, &fd::widen(&f))
                    .expect("the ports of an FD network's station are FD-capable");
                continue;
            }
            self.st.link.send(self.now, &f);
        }
    }
}

impl Deref for AppStation {
    type Target = Station<DualBus, Machines>;
    fn deref(&self) -> &Self::Target {
        &self.st
    }
}
impl DerefMut for AppStation {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.st
    }
}

impl Device for AppStation {
    type Event = <Station<DualBus, Machines> as Device>::Event;
    fn port_count(&self) -> usize {
        self.st.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.now = now;
        self.st.handle_rx(now, port, frame);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.now = now;
        self.st.handle_rx_at(now, port, frame, at);
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
    #[cfg(feature = "fd")]
    fn fd_capable(&self) -> bool {
        self.st.link.fd_capable()
    }
    #[cfg(feature = "fd")]
    fn handle_rx_fd(&mut self, now: Instant, port: usize, frame: &duocan::FdFrame, at: Instant) {
        self.now = now;
        fd::received(&mut self.st, now, port, frame, at);
    }
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<(usize, duocan::FdFrame)> {
        self.pump();
        self.st.link.poll_transmit_fd()
    }
}

#[cfg(feature = "fd")]
mod fd {
    use super::Machines;
    use duocan::machine::{forward_commands, forward_requests};
    use duocan::{FdFrame, Frame, Instant, Machine, Station};
    use duocan_redundancy::DualBus;

    fn filler(counter: &[u8], i: usize) -> u8 {
        counter[0].wrapping_mul(13) ^ (i as u8)
    }

    /// TPDO1's counter (four bytes) and 60 bytes made from it.
    pub fn widen(f: &Frame) -> FdFrame {
        let mut data = [0u8; 64];
        data[..f.data().len()].copy_from_slice(f.data());
        for (i, b) in data.iter_mut().enumerate().skip(f.data().len()) {
            *b = filler(f.data(), i);
        }
        FdFrame::new(f.id(), &data).unwrap().with_brs(true)
    }

    /// The TPDO1 `f` was widened from; it must carry exactly the bytes `widen` made (a frame
    /// garbled or cut short on its way is a failure, not a counter).
    fn narrow(f: &FdFrame) -> Frame {
        let d = f.data();
        assert_eq!(d.len(), 64, "{f:?}");
        assert!(
            (4..64).all(|i| d[i] == filler(&d[..4], i)),
            "FD frame garbled: {f:?}"
        );
        Frame::new(f.id(), &d[..4]).unwrap()
    }

    /// An FD frame from `port` through the layer, as `Station` takes a classic one: the
    /// layer's requests and the machine's commands exchanged, what the layer delivers to the
    /// machine (as the TPDO1 it was widened from), and the exchange again.
    pub fn received(
        st: &mut Station<DualBus, Machines>,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
    ) {
        let Station { link, machine, .. } = st;
        let f = link.handle_rx_fd_at(now, port, frame, at);
        forward_requests(now, link, machine);
        forward_commands(now, machine, link);
        if let Some(f) = f {
            machine.handle_frame_at(now, &narrow(&f), at);
            forward_requests(now, link, machine);
            forward_commands(now, machine, link);
        }
    }
}
