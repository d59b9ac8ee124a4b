//! An in-memory CAN segment between two `embedded-can` controllers, for running the gateway
//! (or any [`EmbeddedDriver`](duocan::port::embedded::EmbeddedDriver)) off the board.
//!
//! A [`Wire`] joins exactly two controllers ([`MockCan`]): what one transmits, the other
//! receives, in order. No heap: each direction is a fixed queue; a full queue is a busy
//! mailbox (`WouldBlock`), as on a controller whose peer has not read yet. [`Wire::cut`]
//! models a broken segment: queued frames are lost, and a controller alone on its stub gets no
//! acknowledge for what it sends ([`ErrorKind::Acknowledge`]) and receives nothing.

use core::cell::{Cell, RefCell};
use duocan::Frame;
use embedded_can::nb::Can;
use embedded_can::ErrorKind;
use heapless::Deque;

/// Frames in flight per direction.
pub const WIRE_QUEUE: usize = 64;

/// A CAN segment with two controllers on it.
pub struct Wire {
    to: [RefCell<Deque<Frame, WIRE_QUEUE>>; 2],
    cut: Cell<bool>,
    lost: Cell<u32>,
}

impl Default for Wire {
    fn default() -> Self {
        Self::new()
    }
}

impl Wire {
    /// An intact, empty segment.
    #[must_use]
    pub const fn new() -> Self {
        Wire {
            to: [RefCell::new(Deque::new()), RefCell::new(Deque::new())],
            cut: Cell::new(false),
            lost: Cell::new(0),
        }
    }
    /// The two controllers.
    pub fn ends(&self) -> [MockCan<'_>; 2] {
        [
            MockCan { wire: self, end: 0 },
            MockCan { wire: self, end: 1 },
        ]
    }
    /// Breaks (`true`) or repairs the segment. Breaking loses what is in flight.
    pub fn cut(&self, broken: bool) {
        if broken {
            for q in &self.to {
                let mut q = q.borrow_mut();
                self.lost.set(self.lost.get() + q.len() as u32);
                q.clear();
            }
        }
        self.cut.set(broken);
    }
    /// True while broken.
    pub fn is_cut(&self) -> bool {
        self.cut.get()
    }
    /// Frames sent and not yet received.
    pub fn in_flight(&self) -> usize {
        self.to.iter().map(|q| q.borrow().len()).sum()
    }
    /// Frames lost to cuts, and frames sent while cut.
    pub fn lost(&self) -> u32 {
        self.lost.get()
    }
}

/// One controller on a [`Wire`].
pub struct MockCan<'w> {
    wire: &'w Wire,
    end: usize,
}

impl Can for MockCan<'_> {
    type Frame = Frame;
    type Error = ErrorKind;

    fn transmit(&mut self, frame: &Frame) -> nb::Result<Option<Frame>, ErrorKind> {
        if self.wire.cut.get() {
            self.wire.lost.set(self.wire.lost.get() + 1);
            return Err(nb::Error::Other(ErrorKind::Acknowledge));
        }
        let mut q = self.wire.to[1 - self.end].borrow_mut();
        q.push_back(*frame).map_err(|_| nb::Error::WouldBlock)?;
        Ok(None)
    }

    fn receive(&mut self) -> nb::Result<Frame, ErrorKind> {
        if self.wire.cut.get() {
            return Err(nb::Error::WouldBlock);
        }
        self.wire.to[self.end]
            .borrow_mut()
            .pop_front()
            .ok_or(nb::Error::WouldBlock)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan::Id;

    #[test]
    fn frames_cross_in_order_and_a_cut_loses_them() {
        let w = Wire::new();
        let [mut a, mut b] = w.ends();
        let f = |n| Frame::from_array(Id::Standard(n), [n as u8]);
        a.transmit(&f(1)).unwrap();
        a.transmit(&f(2)).unwrap();
        b.transmit(&f(3)).unwrap();
        assert_eq!(w.in_flight(), 3);
        assert_eq!(b.receive().unwrap(), f(1));
        assert_eq!(b.receive().unwrap(), f(2));
        assert!(matches!(b.receive(), Err(nb::Error::WouldBlock)));
        w.cut(true);
        assert!(matches!(a.receive(), Err(nb::Error::WouldBlock)));
        assert!(matches!(
            a.transmit(&f(4)),
            Err(nb::Error::Other(ErrorKind::Acknowledge))
        ));
        assert_eq!(w.lost(), 2, "f(3) in flight and f(4) sent while cut");
        w.cut(false);
        a.transmit(&f(5)).unwrap();
        assert_eq!(b.receive().unwrap(), f(5));
        for n in 0..WIRE_QUEUE as u16 {
            a.transmit(&f(n)).unwrap();
        }
        assert!(matches!(a.transmit(&f(0)), Err(nb::Error::WouldBlock)));
    }
}
