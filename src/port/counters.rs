//! Per-port counters shared between a port (moved into its task) and whoever watches it.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// Counters of one port. Cloning shares them: the port keeps counting, the clone reads.
#[derive(Clone, Debug, Default)]
pub struct PortCounters(Arc<Inner>);

#[derive(Debug, Default)]
struct Inner {
    rx_frames: AtomicU64,
    tx_frames: AtomicU64,
    rx_invalid: AtomicU64,
    rx_error_frames: AtomicU64,
    tx_failed: AtomicU64,
    tx_dropped: AtomicU64,
    reopened: AtomicU64,
}

/// The counters at one moment.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PortCountersSnapshot {
    /// Classic frames received and handed on.
    pub rx_frames: u64,
    /// Frames written to the interface.
    pub tx_frames: u64,
    /// Input refused: CAN FD, bad DLC or flags, undecodable datagrams, frames from ourselves.
    pub rx_invalid: u64,
    /// Controller error frames received (decoded into port status).
    pub rx_error_frames: u64,
    /// Writes that failed.
    pub tx_failed: u64,
    /// Frames not written because the port was down or its queue was full.
    pub tx_dropped: u64,
    /// Successful re-opens after a failure.
    pub reopened: u64,
}

macro_rules! bump {
    ($($name:ident),*) => {$(
        #[doc = concat!("Adds one to `", stringify!($name), "`.")]
        pub fn $name(&self) {
            self.0.$name.fetch_add(1, Ordering::Relaxed);
        }
    )*};
}

impl PortCounters {
    /// Fresh counters at zero.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }
    bump!(
        rx_frames,
        tx_frames,
        rx_invalid,
        rx_error_frames,
        tx_failed,
        tx_dropped,
        reopened
    );
    /// Reads every counter.
    pub fn snapshot(&self) -> PortCountersSnapshot {
        let i = &self.0;
        PortCountersSnapshot {
            rx_frames: i.rx_frames.load(Ordering::Relaxed),
            tx_frames: i.tx_frames.load(Ordering::Relaxed),
            rx_invalid: i.rx_invalid.load(Ordering::Relaxed),
            rx_error_frames: i.rx_error_frames.load(Ordering::Relaxed),
            tx_failed: i.tx_failed.load(Ordering::Relaxed),
            tx_dropped: i.tx_dropped.load(Ordering::Relaxed),
            reopened: i.reopened.load(Ordering::Relaxed),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_counts() {
        let a = PortCounters::new();
        let b = a.clone();
        a.rx_invalid();
        a.rx_invalid();
        b.tx_frames();
        let s = b.snapshot();
        assert_eq!(s.rx_invalid, 2);
        assert_eq!(s.tx_frames, 1);
        assert_eq!(s.rx_frames, 0);
    }
}
