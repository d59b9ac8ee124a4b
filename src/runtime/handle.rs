//! The application's side of a running runtime.

use super::task::Command;
use super::{Clock, RuntimeEvent};
use crate::port::{PortCounters, PortCountersSnapshot};
use crate::time::Instant;
use std::fmt;
use std::future::Future;
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

    /// Starts an operation with `start` and waits for the event that completes it: `done`
    /// is given every event from then on, with what `start` returned (a transfer id, say),
    /// and the first `Some` is the result. Events are subscribed to before `start` runs, so
    /// none is missed.
    pub fn request<T, R, S, M>(
        &self,
        start: S,
        mut done: M,
    ) -> impl Future<Output = Result<R, RuntimeClosed>> + Send + 'static
    where
        S: FnOnce(&mut D, Instant) -> T + Send + 'static,
        M: FnMut(&T, &D::Event) -> Option<R> + Send + 'static,
        T: Send + Sync + 'static,
        R: Send + 'static,
    {
        let mut rx = self.events.subscribe();
        let commands = self.commands.clone();
        async move {
            let (tx, token) = oneshot::channel();
            let call = Box::new(move |d: &mut D, now: Instant| {
                let _ = tx.send(start(d, now));
            });
            commands
                .send(Command::Call(call))
                .map_err(|_| RuntimeClosed)?;
            let token = token.await.map_err(|_| RuntimeClosed)?;
            loop {
                match rx.recv().await {
                    Ok(RuntimeEvent::Device(e)) => {
                        if let Some(r) = done(&token, &e) {
                            return Ok(r);
                        }
                    }
                    Ok(RuntimeEvent::Port { .. }) => {}
                    Err(broadcast::error::RecvError::Lagged(n)) => {
                        tracing::warn!(missed = n, "request waiter lagged behind events");
                    }
                    Err(broadcast::error::RecvError::Closed) => return Err(RuntimeClosed),
                }
            }
        }
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
