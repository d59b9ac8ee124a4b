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
    /// Overruns of the sockets closed before the current one.
    rx_overrun_before: AtomicU64,
    /// The current socket's count of overruns (the kernel's, since it was opened).
    rx_overrun_socket: AtomicU64,
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
    /// Frames the kernel dropped because the port's receive queue was full (its reader had
    /// fallen that far behind): lost to this port. Counted where the system reports them
    /// (SocketCAN and UDP ports on Linux), as the first frame queued after the loss is read.
    pub rx_overrun: u64,
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
        tx_dropped
    );
    /// Adds one to `reopened`: a new socket, whose count of overruns starts again at zero.
    pub fn reopened(&self) {
        let i = &self.0;
        i.reopened.fetch_add(1, Ordering::Relaxed);
        let closed = i.rx_overrun_socket.swap(0, Ordering::Relaxed);
        i.rx_overrun_before.fetch_add(closed, Ordering::Relaxed);
    }
    /// The socket's own count of frames dropped on its full receive queue, as the kernel
    /// reports it with a frame read (a running total since the socket was opened; the reader
    /// thread and the task may report the same total, or an older one, in any order).
    pub fn rx_overrun_total(&self, on_socket: u32) {
        self.0
            .rx_overrun_socket
            .fetch_max(u64::from(on_socket), Ordering::Relaxed);
    }
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
            rx_overrun: i.rx_overrun_before.load(Ordering::Relaxed)
                + i.rx_overrun_socket.load(Ordering::Relaxed),
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

    /// A socket's overruns are its running total (reported in any order, and twice by the
    /// reader and the task); a reopened port's new socket counts from zero again, and the
    /// snapshot adds the closed sockets' totals.
    #[test]
    fn overruns_add_up_over_reopened_sockets() {
        let c = PortCounters::new();
        c.rx_overrun_total(5);
        c.rx_overrun_total(3);
        c.rx_overrun_total(5);
        assert_eq!(c.snapshot().rx_overrun, 5);
        c.reopened();
        assert_eq!(c.snapshot().rx_overrun, 5);
        c.rx_overrun_total(2);
        assert_eq!((c.snapshot().rx_overrun, c.snapshot().reopened), (7, 1));
    }
}
