//! An in-memory point-to-point wire whose ports never allocate: each direction is a queue with
//! its room taken once, and a wake-up.

use duocan::port::{Port, PortCounters, PortError, PortInput};
use duocan::Frame;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use tokio::sync::Notify;

/// Frames a direction holds; more are dropped (a test that needs more is wrong).
const DEPTH: usize = 64;

#[derive(Default)]
struct Direction {
    frames: Mutex<VecDeque<Frame>>,
    ready: Notify,
}

/// One end of the wire.
pub struct LoopPort {
    rx: Arc<Direction>,
    tx: Arc<Direction>,
    counters: PortCounters,
}

/// The two ends.
pub fn pair() -> (LoopPort, LoopPort) {
    let new = || {
        Arc::new(Direction {
            frames: Mutex::new(VecDeque::with_capacity(DEPTH)),
            ready: Notify::new(),
        })
    };
    let (a, b) = (new(), new());
    let end = |rx: &Arc<Direction>, tx: &Arc<Direction>| LoopPort {
        rx: rx.clone(),
        tx: tx.clone(),
        counters: PortCounters::new(),
    };
    (end(&a, &b), end(&b, &a))
}

impl Port for LoopPort {
    fn name(&self) -> &str {
        "loop"
    }
    fn counters(&self) -> PortCounters {
        self.counters.clone()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        loop {
            if let Some(x) = self.try_recv() {
                return x;
            }
            self.rx.ready.notified().await;
        }
    }
    fn try_recv(&mut self) -> Option<Result<PortInput, PortError>> {
        let f = self.rx.frames.lock().unwrap().pop_front()?;
        self.counters.rx_frames();
        // Stamped, as a SocketCAN or UDP port's frames are.
        Some(Ok(PortInput::Frame(f, Some(std::time::Instant::now()))))
    }
    async fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        let mut q = self.tx.frames.lock().unwrap();
        if q.len() < DEPTH {
            q.push_back(*frame);
            self.counters.tx_frames();
        } else {
            self.counters.tx_dropped();
        }
        drop(q);
        self.tx.ready.notify_one();
        Ok(())
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        Ok(())
    }
}
