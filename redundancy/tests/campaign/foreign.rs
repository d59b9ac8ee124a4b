//! A node that is not duocan: a dual-port board whose stack puts every frame on bus 1, then
//! on bus 2, with no layer of its own (no transmit stall rule, no merge), as a vendor board
//! with two controllers does. It beats every 20 ms and, on a network with process data, sends
//! a TPDO every 10 ms whose data never changes. What the others receive of it is judged like
//! any frame; what it receives is not (nothing of it is duocan's).

use crate::oracle::Oracle;
use crate::plant::SLAVE_HB;
use duocan::{Device, Duration, Frame, Id, Instant, NmtState, PortStatus};
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

/// Its node-ID.
pub const FOREIGN: u8 = 0x7B;

pub struct Foreign {
    node: usize,
    oracle: Rc<RefCell<Oracle>>,
    next_beat: Instant,
    next_pdo: Option<Instant>,
    /// Copies not yet handed to a port: (port, frame, occurrence).
    out: VecDeque<(usize, Frame, u64)>,
}

impl Foreign {
    /// Sending from `now`; `node` is its index in the oracle.
    pub fn new(now: Instant, node: usize, oracle: Rc<RefCell<Oracle>>, pdo: bool) -> Self {
        Foreign {
            node,
            oracle,
            next_beat: now + SLAVE_HB,
            next_pdo: pdo.then(|| now + Duration::from_millis(10)),
            out: VecDeque::new(),
        }
    }
    fn send(&mut self, now: Instant, frame: Frame) {
        let of = self.oracle.borrow_mut().sent(self.node, now, &frame);
        self.out.push_back((0, frame, of));
        self.out.push_back((1, frame, of));
    }
}

impl Device for Foreign {
    type Event = ();
    fn port_count(&self) -> usize {
        2
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {}
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        while self.next_beat <= now {
            let t = self.next_beat;
            let beat = [NmtState::Operational.code()];
            self.send(
                t,
                Frame::from_array(Id::Standard(0x700 + FOREIGN as u16), beat),
            );
            self.next_beat = t + SLAVE_HB;
        }
        while let Some(t) = self.next_pdo.filter(|t| *t <= now) {
            let data = [0x7B, 0xB7, 0x5A, 0xA5];
            self.send(
                t,
                Frame::from_array(Id::Standard(0x180 + FOREIGN as u16), data),
            );
            self.next_pdo = Some(t + Duration::from_millis(10));
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        let (port, frame, of) = self.out.pop_front()?;
        self.oracle.borrow_mut().copy(self.node, Some(of), port);
        Some((port, frame))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        Some(
            self.next_pdo
                .map_or(self.next_beat, |p| p.min(self.next_beat)),
        )
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}
