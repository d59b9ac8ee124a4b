//! The application's side of a running runtime.

use super::task::{Command, Direct, Start, Watcher};
use super::{Clock, RuntimeEvent};
use crate::cia301::sdo::SdoError;
use crate::frame::instant::Instant;
use crate::node::QueueFull;
use crate::od::abort::AbortCode;
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

/// Why an operation through a [`Handle`] failed: the runtime stopped, or the operation itself
/// failed on the device. Every typed handle call ([`Handle::sdo_read`], [`Handle::read`],
/// [`Handle::nmt`], …) returns this one error, so a caller ends each call in `?` and still
/// tells the cases apart by matching.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum RuntimeError {
    /// The runtime has stopped (shut down, or its task panicked).
    Closed,
    /// The SDO transfer could not start, or failed (node, object and cause inside).
    Sdo(SdoError),
    /// The local dictionary refused the access with this abort code.
    Abort(AbortCode),
    /// The local node's transmit queue was full.
    QueueFull(QueueFull),
}

impl fmt::Display for RuntimeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The wrapped error says it all; repeating a prefix would only lengthen the message.
        match self {
            RuntimeError::Closed => fmt::Display::fmt(&RuntimeClosed, f),
            RuntimeError::Sdo(e) => fmt::Display::fmt(e, f),
            RuntimeError::Abort(code) => write!(f, "the local dictionary refused: {code}"),
            RuntimeError::QueueFull(e) => fmt::Display::fmt(e, f),
        }
    }
}

impl std::error::Error for RuntimeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            RuntimeError::Closed => None,
            RuntimeError::Sdo(e) => Some(e),
            RuntimeError::Abort(code) => Some(code),
            RuntimeError::QueueFull(e) => Some(e),
        }
    }
}

impl From<RuntimeClosed> for RuntimeError {
    fn from(_: RuntimeClosed) -> Self {
        RuntimeError::Closed
    }
}

impl From<SdoError> for RuntimeError {
    fn from(e: SdoError) -> Self {
        RuntimeError::Sdo(e)
    }
}

impl From<AbortCode> for RuntimeError {
    fn from(code: AbortCode) -> Self {
        RuntimeError::Abort(code)
    }
}

impl From<QueueFull> for RuntimeError {
    fn from(e: QueueFull) -> Self {
        RuntimeError::QueueFull(e)
    }
}

/// A cloneable handle to a running device. The runtime runs while any handle exists: dropping
/// the last one stops it, as does [`Handle::shutdown`].
pub struct Handle<D: crate::Device> {
    commands: mpsc::UnboundedSender<Command>,
    direct: Arc<dyn Direct<D>>,
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
            direct: self.direct.clone(),
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
        commands: mpsc::UnboundedSender<Command>,
        direct: Arc<dyn Direct<D>>,
        events: broadcast::Sender<RuntimeEvent<D::Event>>,
        clock: Clock,
        names: Vec<String>,
        counters: Vec<PortCounters>,
        task: JoinHandle<()>,
    ) -> Self {
        Handle {
            commands,
            direct,
            events,
            clock,
            names: names.into(),
            counters: counters.into(),
            task: Arc::new(Mutex::new(Some(task))),
        }
    }

    /// Runs `f` on the device, with the current time, and returns its result. It runs in the
    /// caller's task, under the runtime's lock (no trip through the runtime's own task); whatever
    /// the device queues (frames, events) is flushed right after, and the ports' tasks write it. For a fallible `f`,
    /// [`Handle::try_call`] returns one flat error instead of a result inside a result.
    pub async fn call<R, F>(&self, f: F) -> Result<R, RuntimeClosed>
    where
        F: FnOnce(&mut D, Instant) -> R + Send + 'static,
        R: Send + 'static,
    {
        let mut f = Some(f);
        let mut out = None;
        let ran = self.direct.call(&mut |d: &mut D, now: Instant| {
            if let Some(f) = f.take() {
                out = Some(f(d, now));
            }
        });
        match out {
            Some(r) if ran => Ok(r),
            _ => Err(RuntimeClosed),
        }
    }

    /// [`Handle::call`] for a fallible `f`: its error and a stopped runtime come back as one
    /// error `E` (anything a [`RuntimeClosed`] converts into: [`RuntimeError`], a boxed error,
    /// an application's own error type), so the call ends in `?`.
    pub async fn try_call<T, E, F>(&self, f: F) -> Result<T, E>
    where
        F: FnOnce(&mut D, Instant) -> Result<T, E> + Send + 'static,
        T: Send + 'static,
        E: From<RuntimeClosed> + Send + 'static,
    {
        self.call(f).await?
    }

    /// Starts an operation and waits for the event that completes it. `start` runs on the
    /// device: `Err(e)` means it did not start, `Ok(token)` means it started; then `done` sees
    /// every following event of the device with the token (a transfer id, say) and the first
    /// `Some` is the outcome. The refusal, the outcome's error and a stopped runtime are one
    /// error `E` (anything a [`RuntimeClosed`] converts into), so the call ends in `?`. No event
    /// is missed: the watch is set up in the same step as the start, inside the runtime, and
    /// does not depend on a subscriber keeping up.
    pub async fn request<T, R, E, S, M>(&self, start: S, mut done: M) -> Result<R, E>
    where
        S: FnOnce(&mut D, Instant) -> Result<T, E> + Send + 'static,
        M: FnMut(&T, &D::Event) -> Option<Result<R, E>> + Send + 'static,
        T: Send + 'static,
        R: Send + 'static,
        E: From<RuntimeClosed> + Send + 'static,
    {
        let (tx, rx) = oneshot::channel::<Result<R, E>>();
        let start: Start<D, D::Event> = Box::new(move |d: &mut D, now: Instant| {
            let token = match start(d, now) {
                Ok(t) => t,
                Err(e) => {
                    let _ = tx.send(Err(e));
                    return None;
                }
            };
            let mut tx = Some(tx);
            let w: Watcher<D::Event> = Box::new(move |e: &D::Event| match done(&token, e) {
                Some(r) => {
                    if let Some(tx) = tx.take() {
                        // Woken once the runtime gives its locks back (see `defer`).
                        super::defer::after_unlock(move || {
                            let _ = tx.send(r);
                        });
                    }
                    true
                }
                None => false,
            });
            Some(w)
        });
        if !self.direct.watch(start) {
            return Err(RuntimeClosed.into());
        }
        rx.await.map_err(|_| RuntimeClosed)?
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
