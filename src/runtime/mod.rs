//! The tokio runtime: drives a [`Device`] from real ports and the monotonic clock.
//!
//! ```text
//!   port task 0 ──(frames, status)──┐                 ┌──> broadcast: RuntimeEvent
//!   port task 1 ──────────────────┐ │                 │
//!                                 ▼ ▼                 │
//!                     core task: the Device ──────────┘
//!                        ▲   waits on: port input, commands, the device's next deadline
//!   Handle ──(closures)──┘
//! ```
//!
//! The core task owns the device and sleeps until whichever comes first: input from a port, a
//! command from a [`Handle`], or the device's [`poll_timeout`](Device::poll_timeout). There is
//! no fixed tick. Each port runs in its own task, so a slow or failed port never holds up the
//! other; a failed port reports [`PortStatus::Down`](crate::PortStatus), is re-opened with
//! backoff, and reports `Up` when it works again.
//!
//! Everything the application does goes through the [`Handle`] as a closure run on the device
//! inside the core task ([`Handle::call`]), with typed helpers for nodes ([`NodeHost`]) and a
//! request/response helper ([`Handle::request`]) that starts an operation and awaits the event
//! that completes it — the shape asynchronous SDO transfers take.

mod core;
mod handle;
mod node;
mod port_task;

pub use handle::{Handle, RuntimeClosed};
pub use node::{LocalNode, NodeHost};

use crate::capture::recorder::Tap;
use crate::machine::{Device, PortStatus};
use crate::port::{Port, PortCounters};
use crate::time::Instant;
use std::fmt;
use std::sync::Arc;
use tokio::sync::{broadcast, mpsc};
use tracing::Instrument;

/// Capacity of each port's outgoing queue (frames the device produced, not yet written).
pub const PORT_TX_QUEUE: usize = 256;
/// Capacity of the queue from all ports into the core task.
pub const RX_QUEUE: usize = 1024;
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
    pub fn start() -> Self {
        Clock {
            origin: tokio::time::Instant::now(),
        }
    }
    /// Current time.
    pub fn now(&self) -> Instant {
        let d = self.origin.elapsed();
        Instant::from_micros(u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
    }
    /// The tokio instant of `t` (far future for [`Instant::MAX`]).
    pub fn to_tokio(&self, t: Instant) -> tokio::time::Instant {
        let far = self.origin + std::time::Duration::from_secs(86_400 * 365 * 30);
        self.origin
            .checked_add(std::time::Duration::from_micros(t.as_micros()))
            .map_or(far, |x| x.min(far))
    }
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
    device: D,
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
    pub fn new(device: D) -> Self {
        Runtime {
            device,
            name: "duocan".into(),
            ports: Vec::new(),
            tap: None,
        }
    }
    /// Names the network (the `net` field of every log line of this runtime).
    pub fn name(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }
    /// Adds the next port (index = number of ports added before).
    pub fn port<P: Port>(mut self, port: P) -> Self {
        let name = port.name().to_owned();
        let counters = port.counters();
        let spawn: SpawnPort = Box::new(move |w: port_task::Wiring| {
            let span = tracing::info_span!("port", net = %w.net, port = w.index, name = %port.name());
            tokio::spawn(port_task::run(port, w).instrument(span));
        });
        self.ports.push((name, counters, spawn));
        self
    }
    /// Records every frame each port received or sent (see [`crate::capture::recorder`]).
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
        let (in_tx, in_rx) = mpsc::channel(RX_QUEUE);
        let (cmd_tx, cmd_rx) = mpsc::unbounded_channel();
        let (ev_tx, _) = broadcast::channel(EVENT_QUEUE);
        let mut port_txs = Vec::with_capacity(given);
        let mut names = Vec::with_capacity(given);
        let mut counters = Vec::with_capacity(given);
        for (index, (name, c, spawn)) in self.ports.into_iter().enumerate() {
            let (tx, rx) = mpsc::channel(PORT_TX_QUEUE);
            spawn(port_task::Wiring {
                index,
                net: self.name.clone(),
                to_core: in_tx.clone(),
                from_core: rx,
            });
            port_txs.push(tx);
            names.push(name);
            counters.push(c);
        }
        drop(in_tx);
        let span = tracing::info_span!("net", net = %self.name);
        let core = core::Core {
            device: self.device,
            clock,
            ports: port_txs,
            counters: counters.clone(),
            events: ev_tx.clone(),
            tap: self.tap,
        };
        let task = tokio::spawn(core.run(cmd_rx, in_rx).instrument(span));
        Ok(Handle::new(cmd_tx, ev_tx, clock, names, counters, task))
    }
}
