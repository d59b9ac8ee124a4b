//! The tokio runtime: drives a [`Device`] from real ports and the monotonic clock.
//!
//! ```text
//!   port task 0 ──(read: handle, answer)──┐      ┌──> broadcast: RuntimeEvent
//!   port task 1 ───────────────────────┐  │      │
//!                                      ▼  ▼      │
//!                          the Device, behind a lock ─┘
//!                                ▲     ▲
//!   Handle (closures, run in ────┘     └── core task: the device's next deadline, shutdown
//!   the caller's own task)
//! ```
//!
//! Each port runs in its own task. What a port reads its task hands to the device at once, and
//! what the device answers on that port the same task writes right after: a frame in and its
//! answer out cost no hand-off between tasks, so the runtime adds little to the transport's
//! own round trip. Frames for the other port wait in that port's bounded queue (a full queue
//! drops and counts, it never stalls the device), so a slow or failed port never holds up the
//! other; a failed port reports [`PortStatus::Down`](crate::PortStatus), is re-opened with
//! backoff ([`BACKOFF_MIN`] doubling up to [`BACKOFF_MAX`]), and reports `Up` when it works
//! again. A [`Handle`] runs its closures on the device itself, in the
//! caller's task under the same lock (a request starts without waiting for another task to be
//! scheduled), and the core task sleeps until the device's
//! [`poll_timeout`](Device::poll_timeout): there is no fixed tick, and a deadline that fell before a frame was read is handled before that
//! frame, at its own instant. Nothing on the way of a frame allocates. A task waiting for what
//! a frame completes (a transfer's outcome) is woken once the runtime's locks are given back,
//! so that its next call does not find them still held by the thread that woke it.
//!
//! A port that can read by blocking ([`Port::reader`]: SocketCAN ports) is read by a thread of
//! its own instead, which waits in the socket's `read` as a bare loop does (one system call per
//! frame, where a readiness wait adds an `epoll_wait` and a `read` that finds the socket empty)
//! and does the same: hands the frame to the device under the lock and writes the answer. The
//! port's task then only sends what the device queued on timers and commands, and re-opens the
//! port; a writer lock between the two keeps the queue's order on the wire.
//!
//! A frame a port hands over with its receive timestamp ([`PortInput::Frame`](crate::port::PortInput)) goes to the
//! device with it ([`Device::handle_rx_at`]: the stamp on the runtime's clock, never later than
//! the instant the frame is handled at), one without through [`Device::handle_rx`], at the
//! instant it was read. So a reader the scheduler held up hands its frames over late, but they
//! keep the time they arrived; a tap records received frames at that time too.
//!
//! # CAN FD
//!
//! A device that speaks CAN FD ([`Device::fd_capable`]) has its ports read through
//! [`Port::recv_any`]: a CAN FD frame goes to [`Device::handle_rx_fd`] with its receive
//! timestamp on the runtime's clock as a classic frame's does (the instant it is handled at if
//! the port took none), a classic frame and a status as above. The FD frames the device yields
//! ([`Device::poll_transmit_fd`], asked after the classic ones) wait in a queue of their own per
//! port ([`PORT_FD_TX_QUEUE`] frames; each also holds a place in the port's queue, which keeps
//! the order the device yielded them in) and go out through [`Port::send_fd`]: a send that
//! fails is reported as a classic one is ([`PortStatus::TxFailed`](crate::PortStatus), or the
//! port down and re-opened), a frame for a full queue is dropped and counted
//! ([`PortCounters`]' `tx_dropped`). A classic command stays the size of a classic frame: the
//! 72 bytes of an FD frame do not travel through every port's queue. Such a device's ports are
//! not read by a reader thread ([`Port::reader`] moves classic frames only), and the tap
//! records its classic frames only. A classic device is driven as before: its ports are read
//! through [`Port::recv`] (a port opened for CAN FD counts the FD frames it skips as invalid)
//! and it is never asked for FD frames.

//! Everything the application does goes through the [`Handle`] as a closure run on the device
//! under the runtime's lock ([`Handle::call`]), with typed helpers for nodes ([`NodeHost`]) and a
//! request/response helper ([`Handle::request`]) that starts an operation and awaits the event
//! that completes it — the shape asynchronous SDO transfers take.
//!
//! A node run on an in-memory bus, seen from a second port on it:
//!
//! ```
//! use duocan::nmt::{command_frame, NmtCommand, NmtState, NmtTarget};
//! use duocan::od::comm;
//! use duocan::port::{mem::MemBus, Port, PortInput};
//! use duocan::runtime::Runtime;
//! use duocan::{Frame, Id, Node, NodeConfig, NodeId, Station};
//! use std::time::Duration;
//!
//! /// The next frame a port received (a test gives up after 5 s).
//! async fn next(port: &mut impl Port) -> Frame {
//!     match tokio::time::timeout(Duration::from_secs(5), port.recv()).await.expect("no frame") {
//!         Ok(PortInput::Frame(f, _stamp)) => f,
//!         other => panic!("{other:?}"),
//!     }
//! }
//!
//! #[tokio::main]
//! async fn main() -> Result<(), Box<dyn std::error::Error>> {
//!     let bus = MemBus::new("mem0");
//!     let mut tester = bus.port();
//!     let node = Node::new(NodeConfig::slave(NodeId::must(5)), comm::standard_dictionary(5, Default::default()));
//!     let handle = Runtime::new(Station::single(node)).port(bus.port()).spawn()?;
//!     handle.boot().await?;
//!     let heartbeat = |state| Frame::from_array(Id::Standard(0x705), [state]);
//!     assert_eq!(next(&mut tester).await, heartbeat(0x00)); // the boot-up
//!
//!     // A heartbeat every second, written through the handle: the first one goes out at once.
//!     handle.write(comm::HEARTBEAT_PRODUCER, 0, 1000u16.to_le_bytes().to_vec()).await?;
//!     assert_eq!(next(&mut tester).await, heartbeat(0x7F)); // pre-operational
//!     // Started from the bus: the new state is announced at once too.
//!     tester.send(&command_frame(Id::Standard(0), NmtCommand::Start, NmtTarget::All)).await?;
//!     assert_eq!(next(&mut tester).await, heartbeat(0x05));
//!     assert_eq!(handle.nmt_state().await?, NmtState::Operational);
//!     handle.shutdown().await;
//!     Ok(())
//! }
//! ```

mod defer;
mod handle;
mod node;
mod outbox;
mod port_task;
mod reader;
mod sdo;
mod task;

pub(crate) use defer::after_unlock;
pub use handle::{Handle, RuntimeClosed, RuntimeError};
pub use node::{LocalNode, NodeHost};
pub use port_task::{BACKOFF_MAX, BACKOFF_MIN};
pub use sdo::{SdoEvents, SdoHost, SdoStart};

use crate::capture::recorder::Tap;
use crate::frame::instant::Instant;
use crate::machine::{Device, PortStatus};
use crate::port::{Port, PortCounters};
use std::fmt;
use std::sync::Arc;
use tokio::sync::{broadcast, mpsc, Notify};
use tracing::Instrument;

/// Capacity of each port's outgoing queue (frames the device produced, not yet written).
pub const PORT_TX_QUEUE: usize = 256;
/// Capacity of each port's outgoing queue of CAN FD frames, for a device that speaks CAN FD
/// ([`Device::fd_capable`]); each of them takes a place in [`PORT_TX_QUEUE`] too, which keeps
/// the order of classic and FD frames. A frame for a full queue is dropped and counted.
pub const PORT_FD_TX_QUEUE: usize = 64;
/// Capacity of the event broadcast: a subscriber lagging further misses events (and is told).
pub const EVENT_QUEUE: usize = 1024;

/// What the runtime reports.
#[derive(Clone, Debug, PartialEq)]
pub enum RuntimeEvent<E> {
    /// An event of the device, as it produced it.
    Device(E),
    /// A port's status as its driver reported it (also handed to the device).
    Port {
        /// When.
        at: Instant,
        /// Port index.
        port: usize,
        /// What.
        status: PortStatus,
    },
}

/// The runtime's clock: microseconds since the runtime started.
#[derive(Clone, Copy, Debug)]
pub struct Clock {
    origin: tokio::time::Instant,
}

impl Clock {
    /// A clock starting now.
    #[must_use]
    pub fn start() -> Self {
        Clock {
            origin: tokio::time::Instant::now(),
        }
    }
    /// Current time.
    pub fn now(&self) -> Instant {
        micros(self.origin.elapsed())
    }
    /// A receive timestamp (the standard library's monotonic clock) on this clock: its time
    /// since the clock started, [`Instant::ZERO`] if it came before.
    pub fn instant_of(&self, t: std::time::Instant) -> Instant {
        micros(t.saturating_duration_since(self.origin.into_std()))
    }
    /// The clock as a reader thread reads it: from the standard library's clock, which is
    /// tokio's outside a runtime (and cheaper to read there).
    pub(crate) fn on_thread(&self) -> ThreadClock {
        ThreadClock(self.origin.into_std())
    }
    /// The tokio instant of `t` (far future for [`Instant::MAX`]).
    pub fn to_tokio(&self, t: Instant) -> tokio::time::Instant {
        let far = self.origin + std::time::Duration::from_secs(86_400 * 365 * 30);
        self.origin
            .checked_add(std::time::Duration::from_micros(t.as_micros()))
            .map_or(far, |x| x.min(far))
    }
}

/// [`Clock`] for a thread outside the tokio runtime.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ThreadClock(std::time::Instant);

impl ThreadClock {
    /// Current time, as [`Clock::now`] gives it.
    pub(crate) fn now(&self) -> Instant {
        micros(self.0.elapsed())
    }
}

/// `d` as an instant after the clock's origin, in whole microseconds.
fn micros(d: std::time::Duration) -> Instant {
    Instant::ZERO + crate::Duration::from(d)
}

/// The runtime could not start.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StartError {
    /// The device has a different number of ports than were given.
    PortCount {
        /// Ports the device has.
        device: usize,
        /// Ports given.
        given: usize,
    },
}

impl fmt::Display for StartError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StartError::PortCount { device, given } => write!(
                f,
                "the device has {device} port(s) but {given} were given: add one Port per device port"
            ),
        }
    }
}

impl std::error::Error for StartError {}

type SpawnPort = Box<dyn FnOnce(port_task::Wiring) + Send>;

/// Builds and starts a runtime for one device.
pub struct Runtime<D> {
    // Boxed: devices can be large (a dual-bus layer's merger is ~100 KiB), and the device
    // must not be copied through every future and stack frame on its way into the task.
    device: Box<D>,
    name: String,
    ports: Vec<(String, PortCounters, SpawnPort)>,
    tap: Option<Arc<dyn Tap>>,
}

impl<D> Runtime<D>
where
    D: Device + Send + 'static,
    D::Event: Clone + Send + fmt::Debug + 'static,
{
    /// A runtime for `device`; add its ports in order with [`Runtime::port`].
    #[must_use]
    pub fn new(device: D) -> Self {
        Self::boxed(Box::new(device))
    }
    /// A runtime for a device already on the heap (large devices built in place).
    #[must_use]
    pub fn boxed(device: Box<D>) -> Self {
        Runtime {
            device,
            name: "duocan".into(),
            ports: Vec::new(),
            tap: None,
        }
    }
    /// Names the network (the `net` field of every log line of this runtime).
    #[must_use]
    pub fn name(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }
    /// Adds the next port (index = number of ports added before).
    ///
    /// For a device with more than one port (a dual-bus layer) the port is asked to confirm
    /// its transmissions ([`Port::confirm_transmissions`]): the layer's transmit-stall rule
    /// judges each port by when its frames left, against their twins on the other bus.
    #[must_use]
    pub fn port<P: Port>(mut self, mut port: P) -> Self {
        if self.device.port_count() > 1 {
            port.confirm_transmissions();
        }
        let name = port.name().to_owned();
        let counters = port.counters();
        let spawn: SpawnPort = Box::new(move |w: port_task::Wiring| {
            let span =
                tracing::info_span!("port", net = %w.net, port = w.index, name = %port.name());
            tokio::spawn(port_task::run(port, w).instrument(span));
        });
        self.ports.push((name, counters, spawn));
        self
    }
    /// Records every frame each port received or sent (see [`crate::capture::recorder`]).
    #[must_use]
    pub fn tap(mut self, tap: Arc<dyn Tap>) -> Self {
        self.tap = Some(tap);
        self
    }

    /// Starts the port tasks and the core task on the current tokio runtime.
    pub fn spawn(self) -> Result<Handle<D>, StartError> {
        let given = self.ports.len();
        if given != self.device.port_count() {
            return Err(StartError::PortCount {
                device: self.device.port_count(),
                given,
            });
        }
        let clock = Clock::start();
        let fd = self.device.fd_capable();
        let (cmd_tx, cmd_rx) = mpsc::unbounded_channel();
        let (ev_tx, _) = broadcast::channel(EVENT_QUEUE);
        let mut names = Vec::with_capacity(given);
        let mut counters = Vec::with_capacity(given);
        let mut spawns = Vec::with_capacity(given);
        for (name, c, spawn) in self.ports {
            names.push(name);
            counters.push(c);
            spawns.push(spawn);
        }
        let state = task::State::new(
            self.device,
            clock,
            counters.clone(),
            ev_tx.clone(),
            self.tap,
        );
        let shared = Arc::new(task::Shared {
            state: std::sync::Mutex::new(state),
            core: Notify::new(),
            ports: (0..given).map(|_| Arc::new(Notify::new())).collect(),
            drained: Notify::new(),
        });
        for (index, spawn) in spawns.into_iter().enumerate() {
            spawn(port_task::Wiring {
                index,
                net: self.name.clone(),
                clock,
                fd,
                hub: shared.clone(),
                wake: shared.ports[index].clone(),
            });
        }
        let span = tracing::info_span!("net", net = %self.name);
        let direct: Arc<dyn task::Direct<D>> = shared.clone();
        let task = tokio::spawn(task::run(shared, cmd_rx).instrument(span));
        Ok(Handle::new(
            cmd_tx, direct, ev_tx, clock, names, counters, task,
        ))
    }
}

#[cfg(test)]
mod tests;
