//! Min-heap entries ordered by time, then by insertion: equal times keep their order.

use super::SimNetwork;
use crate::frame::instant::Instant;
use crate::frame::{FdFrame, Frame};
use core::cmp::Ordering;

/// Something due at `at`; the sequence number breaks ties in insertion order.
pub(super) struct Timed<T> {
    pub(super) at: Instant,
    pub(super) seq: u64,
    pub(super) item: T,
}

impl<T> PartialEq for Timed<T> {
    fn eq(&self, other: &Self) -> bool {
        (self.at, self.seq) == (other.at, other.seq)
    }
}
impl<T> Eq for Timed<T> {}
impl<T> PartialOrd for Timed<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
/// Reversed, so that `BinaryHeap` (a max-heap) pops the earliest first.
impl<T> Ord for Timed<T> {
    fn cmp(&self, other: &Self) -> Ordering {
        (other.at, other.seq).cmp(&(self.at, self.seq))
    }
}

/// A frame handed to a port later than it ended on the wire.
pub(super) struct DelayedRx {
    pub(super) port: u32,
    /// Receiver's generation when scheduled: a power-off meanwhile discards it.
    pub(super) generation: u32,
    pub(super) frame: Frame,
    /// When the frame ended on the wire: its receive timestamp.
    pub(super) wire: Instant,
    /// The sending port and the frame's serial (see the receive hook).
    pub(super) from: (u32, Option<u64>),
    /// A CAN FD frame (`frame` its stand-in); boxed, so a delayed classic frame stays small.
    pub(super) fd: Option<Box<FdFrame>>,
}

/// A scheduled closure (see [`SimNetwork::at`]).
pub(super) type Action = Box<dyn FnOnce(&mut SimNetwork)>;
