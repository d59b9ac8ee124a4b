//! An in-process bus: ports that share frames through memory. For testing applications and the
//! runtime without sockets; every port sees every frame the others send, in order.

use super::{Port, PortCounters, PortError, PortErrorKind, PortInput};
use crate::frame::Frame;
use crate::machine::PortStatus;
use tokio::sync::broadcast;

/// Frames a slow port may fall behind before it loses some (counted as `rx_invalid`).
pub const MEM_BUS_DEPTH: usize = 4096;

/// One in-process bus.
#[derive(Clone, Debug)]
pub struct MemBus {
    tx: broadcast::Sender<(u64, Frame)>,
    name: String,
}

impl MemBus {
    /// A new, empty bus.
    #[must_use]
    pub fn new(name: impl Into<String>) -> Self {
        MemBus {
            tx: broadcast::channel(MEM_BUS_DEPTH).0,
            name: name.into(),
        }
    }
    /// A port on this bus.
    pub fn port(&self) -> MemPort {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);
        MemPort {
            bus: self.clone(),
            rx: Some(self.tx.subscribe()),
            me: NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            counters: PortCounters::new(),
        }
    }
}

/// A port on a [`MemBus`].
#[derive(Debug)]
pub struct MemPort {
    bus: MemBus,
    rx: Option<broadcast::Receiver<(u64, Frame)>>,
    me: u64,
    counters: PortCounters,
}

impl Port for MemPort {
    fn name(&self) -> &str {
        &self.bus.name
    }
    fn counters(&self) -> PortCounters {
        self.counters.clone()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        loop {
            let Some(rx) = self.rx.as_mut() else {
                return Err(PortError::new(
                    &self.bus.name,
                    PortErrorKind::Closed,
                    "closed",
                ));
            };
            match rx.recv().await {
                Ok((from, _)) if from == self.me => {}
                Ok((_, f)) => {
                    self.counters.rx_frames();
                    return Ok(PortInput::Frame(f));
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    for _ in 0..n {
                        self.counters.rx_invalid();
                    }
                    return Ok(PortInput::Status(PortStatus::Error(
                        crate::machine::ErrorCause::RxOverflow,
                    )));
                }
                Err(broadcast::error::RecvError::Closed) => {
                    self.rx = None;
                }
            }
        }
    }
    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        // No receivers is not an error: nobody else is on the bus.
        let _ = self.bus.tx.send((self.me, *frame));
        self.counters.tx_frames();
        Ok(())
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        self.rx = Some(self.bus.tx.subscribe());
        self.counters.reopened();
        Ok(())
    }
}
