//! The application's side of a running runtime.

use super::task::{Command, Start, Watcher};
use super::{Clock, RuntimeEvent};
use crate::frame::instant::Instant;
use crate::port::{PortCounters, PortCountersSnapshot};
use std::fmt;
use std::sync::{Arc, Mutex};
use tokio::sync::{broadcast, mpsc, oneshot};
use tokio::task::JoinHandle;

/// The runtime has stopped (shut down, or its task panicked).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RuntimeClosed;

impl fmt::Display for RuntimeClosed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("the duocan runtime has stopped")
    }
}

impl std::error::Error for RuntimeClosed {}

/// A cloneable handle to a running device. The runtime runs while any handle exists: dropping
/// the last one stops it, as does [`Handle::shutdown`].
pub struct Handle<D: crate::Device> {
    commands: mpsc::UnboundedSender<Command<D>>,
    events: broadcast::Sender<RuntimeEvent<D::Event>>,
    clock: Clock,
    names: Arc<[String]>,
    counters: Arc<[PortCounters]>,
    task: Arc<Mutex<Option<JoinHandle<()>>>>,
}

impl<D: crate::Device> Clone for Handle<D> {
    fn clone(&self) -> Self {
        Handle {
            commands: self.commands.clone(),
            events: self.events.clone(),
            clock: self.clock,
            names: self.names.clone(),
            counters: self.counters.clone(),
            task: self.task.clone(),
        }
    }
}

impl<D> Handle<D>
where
    D: crate::Device + Send + 'static,
    D::Event: Clone + Send + 'static,
{
    pub(crate) fn new(
        commands: mpsc::UnboundedSender<Command<D>>,
        events: broadcast::Sender<RuntimeEvent<D::Event>>,
        clock: Clock,
        names: Vec<String>,
        counters: Vec<PortCounters>,
        task: JoinHandle<()>,
    ) -> Self {
        Handle {
            commands,
            events,
            clock,
            names: names.into(),
            counters: counters.into(),
            task: Arc::new(Mutex::new(Some(task))),
        }
    }

    /// Runs `f` on the device inside the runtime, with the current time, and returns its result.
    /// Whatever the device queues (frames, events) is flushed right after.
    pub async fn call<R, F>(&self, f: F) -> Result<R, RuntimeClosed>
    where
        F: FnOnce(&mut D, Instant) -> R + Send + 'static,
        R: Send + 'static,
    {
        let (tx, rx) = oneshot::channel();
        let call = Box::new(move |d: &mut D, now: Instant| {
            let _ = tx.send(f(d, now));
        });
        self.commands
            .send(Command::Call(call))
            .map_err(|_| RuntimeClosed)?;
        rx.await.map_err(|_| RuntimeClosed)
    }

    /// Starts an operation and waits for the event that completes it. `start` runs on the
    /// device: `Err(r)` is an immediate result (it did not start), `Ok(token)` means it started;
    /// then `done` sees every following event of the device with the token (a transfer id, say)
    /// and the first `Some` is the result. No event is missed: the watch is set up in the same
    /// step as the start, inside the runtime, and does not depend on a subscriber keeping up.
    pub async fn request<T, R, S, M>(&self, start: S, mut done: M) -> Result<R, RuntimeClosed>
    where
        S: FnOnce(&mut D, Instant) -> Result<T, R> + Send + 'static,
        M: FnMut(&T, &D::Event) -> Option<R> + Send + 'static,
        T: Send + 'static,
        R: Send + 'static,
    {
        let (tx, rx) = oneshot::channel();
        let start: Start<D, D::Event> = Box::new(move |d: &mut D, now: Instant| {
            let token = match start(d, now) {
                Ok(t) => t,
                Err(r) => {
                    let _ = tx.send(r);
                    return None;
                }
            };
            let mut tx = Some(tx);
            let w: Watcher<D::Event> = Box::new(move |e: &D::Event| match done(&token, e) {
                Some(r) => {
                    if let Some(tx) = tx.take() {
                        let _ = tx.send(r);
                    }
                    true
                }
                None => false,
            });
            Some(w)
        });
        self.commands
            .send(Command::Watch(start))
            .map_err(|_| RuntimeClosed)?;
        rx.await.map_err(|_| RuntimeClosed)
    }

    /// Every event from now on. A subscriber more than [`super::EVENT_QUEUE`] events behind
    /// gets `Lagged` and continues with the newest.
    pub fn subscribe(&self) -> broadcast::Receiver<RuntimeEvent<D::Event>> {
        self.events.subscribe()
    }

    /// The runtime's current time.
    pub fn now(&self) -> Instant {
        self.clock.now()
    }

    /// Names of the ports, by index.
    pub fn port_names(&self) -> &[String] {
        &self.names
    }

    /// Counters of port `i`.
    pub fn port_counters(&self, i: usize) -> Option<PortCountersSnapshot> {
        self.counters.get(i).map(PortCounters::snapshot)
    }

    /// Stops the core task (the port tasks follow) and waits for it.
    pub async fn shutdown(&self) {
        let _ = self.commands.send(Command::Shutdown);
        let task = self.task.lock().ok().and_then(|mut t| t.take());
        if let Some(t) = task {
            let _ = t.await;
        }
    }
}
