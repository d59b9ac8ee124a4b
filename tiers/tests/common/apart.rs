//! How far apart a test's sender put a frame's two copies on the wires: from before its write
//! to the first bus to after its write to the second (the kernel stamps each copy within that).
//! The layer pairs copies stamped within its skew window, so a frame whose copies were further
//! apart (the VM's emulated CPU holding the sender up between its two writes) is two
//! occurrences to it by its documented rule, delivered once or twice; the tests that send on
//! both buses themselves count such frames so. (`vcan_failover` measures the same on the wire,
//! from the kernel stamps of both buses, since there the writer is a slave's runtime.)

use duocan::Frame;
use std::time::{Duration, Instant};

/// The frames a sender put further apart than the layer's default skew window, and the
/// widest gap.
#[derive(Clone, Debug, Default)]
pub struct Apart {
    /// The widest gap between a frame's two writes.
    pub longest: Duration,
    /// The frames sent so (each once per such sending).
    pub beyond_window: Vec<Frame>,
}

impl Apart {
    /// The layer's default skew window.
    pub fn window() -> Duration {
        let w = duocan_redundancy::DualBusConfig::default().skew_window;
        Duration::from_micros(w.as_micros())
    }

    /// Notes `f`, whose first write began at `first` and whose second has just ended; true if
    /// its copies are further apart than the window.
    pub fn note(&mut self, f: &Frame, first: Instant) -> bool {
        let d = first.elapsed();
        self.longest = self.longest.max(d);
        let beyond = d > Self::window();
        if beyond {
            self.beyond_window.push(*f);
        }
        beyond
    }
}
