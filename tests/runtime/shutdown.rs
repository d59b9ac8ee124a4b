//! A shutdown writes what was queued before it: a tool that sends a command and exits does not
//! lose the command's frame to its own shutdown. A port that cannot send does not hold the
//! shutdown up for more than a moment.

use super::rig::{queue, Probe};
use duocan::port::{Port, PortCounters, PortError, PortInput};
use duocan::runtime::Runtime;
use duocan::{Frame, Id};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::{Notify, Semaphore};

/// A port whose sends each wait for a permit of `gate`; `entered` is notified when a send
/// starts waiting.
struct Gated {
    gate: Arc<Semaphore>,
    entered: Arc<Notify>,
    written: Arc<Mutex<Vec<u8>>>,
}

impl Port for Gated {
    fn name(&self) -> &str {
        "gated0"
    }
    fn counters(&self) -> PortCounters {
        PortCounters::new()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        std::future::pending().await
    }
    async fn send(&mut self, f: &Frame) -> Result<(), PortError> {
        self.entered.notify_one();
        self.gate.acquire().await.expect("gate open").forget();
        self.written.lock().unwrap().push(f.data()[0]);
        Ok(())
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        Ok(())
    }
}

struct Bench {
    handle: duocan::runtime::Handle<Probe>,
    gate: Arc<Semaphore>,
    entered: Arc<Notify>,
    written: Arc<Mutex<Vec<u8>>>,
}

fn start() -> Bench {
    let gate = Arc::new(Semaphore::new(0));
    let entered = Arc::new(Notify::new());
    let written = Arc::new(Mutex::new(Vec::new()));
    let port = Gated {
        gate: gate.clone(),
        entered: entered.clone(),
        written: written.clone(),
    };
    let handle = Runtime::new(Probe::default()).port(port).spawn().unwrap();
    Bench {
        handle,
        gate,
        entered,
        written,
    }
}

impl Bench {
    async fn queue(&self, marks: std::ops::RangeInclusive<u8>) {
        let frames = marks.map(|m| Frame::new(Id::Standard(0x200), &[m]).unwrap());
        queue(&self.handle, frames).await;
    }

    /// Queues `marks` and waits until the port is sending the first of them.
    async fn sending(&self, marks: std::ops::RangeInclusive<u8>) {
        let entered = self.entered.notified();
        self.queue(marks).await;
        entered.await;
    }
}

/// Mark 1 is being sent when marks 2 to 40 are queued and the runtime is shut down: the
/// shutdown returns only when all 40 are written, in order.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_queued_before_a_shutdown_are_written_before_it_returns() {
    let b = start();
    b.sending(1..=1).await;
    b.queue(2..=40).await;
    let handle = b.handle.clone();
    let shutdown = tokio::spawn(async move { handle.shutdown().await });
    // The core task takes the shutdown while the port still waits in its send.
    tokio::time::sleep(Duration::from_millis(50)).await;
    assert!(!shutdown.is_finished(), "the shutdown waits for the port");
    b.gate.add_permits(1000);
    tokio::time::timeout(Duration::from_secs(5), shutdown)
        .await
        .expect("the shutdown returns once the queue is written")
        .unwrap();
    assert_eq!(*b.written.lock().unwrap(), (1..=40).collect::<Vec<u8>>());
}

/// A port whose send never ends holds the shutdown up for a moment only.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_port_that_cannot_send_does_not_hold_the_shutdown() {
    let b = start();
    b.sending(1..=5).await;
    let t0 = std::time::Instant::now();
    tokio::time::timeout(Duration::from_secs(2), b.handle.shutdown())
        .await
        .expect("the shutdown gives up on the stuck port");
    assert!(
        t0.elapsed() >= Duration::from_millis(200),
        "{:?}",
        t0.elapsed()
    );
    assert!(b.written.lock().unwrap().is_empty());
}
