//! The device's state, shared by the core task (commands, the device's deadlines) and the port
//! tasks (what the ports read, what they write).
//!
//! A port task that reads a frame hands it to the device itself, under the state's lock, and
//! writes what the device answers on its own port right after: a frame in, its answer out, with
//! no task hand-off between. Frames for another port are queued for that port's task (bounded:
//! a full queue drops and counts), which is woken. Handles run their closures under the same
//! lock in their callers' tasks ([`Direct`]). The core task waits for the device's next
//! deadline (and a shutdown) and runs its timeouts under the lock; port tasks and handles wake
//! it only when the device's deadline moved earlier than the one it waits for.
//!
//! What is done under the lock is in [`state`], who takes it and whom it wakes in [`shared`];
//! here are the interfaces the port tasks and handles see, and the core task.

pub(crate) use super::outbox::{Outbox, PortCmd};
use crate::frame::FdFrame;
use crate::machine::Device;
use crate::port::PortInput;
use std::sync::Arc;
use tokio::sync::mpsc;

/// Sees every event of the device until it returns true (it got what it waited for).
pub(crate) type Watcher<E> = Box<dyn FnMut(&E) -> bool + Send>;

/// Starts something and returns the watcher that completes it, if it started.
pub(crate) type Start<D, E> = Box<dyn FnOnce(&mut D, crate::Instant) -> Option<Watcher<E>> + Send>;

/// What a handle sends the core task: the runtime is to stop. (Closures do not travel: a handle
/// runs them on the device itself, see [`Direct`].)
pub(crate) enum Command {
    Shutdown,
}

/// How a handle runs its closures: on the device, under the state's lock, in the caller's own
/// task. A trip through the core task would cost a task hand-off per call (the request's start
/// waiting for the core task to be scheduled); the lock is what the core task would take anyway,
/// and the frames the closure queues wake their ports' tasks as they would from it.
pub(crate) trait Direct<D: Device>: Send + Sync {
    /// Runs `f` with the current time; false (and `f` not run) when the runtime has stopped.
    /// Borrowed, not boxed: a call allocates nothing.
    fn call(&self, f: &mut dyn FnMut(&mut D, crate::Instant)) -> bool;
    /// Runs `start` with the current time and keeps the watcher it returns; false when the
    /// runtime has stopped.
    fn watch(&self, start: Start<D, D::Event>) -> bool;
}

/// How long a shutdown waits at most for the port tasks to write what was queued before it.
const DRAIN_GRACE: std::time::Duration = std::time::Duration::from_millis(250);

/// What the port tasks see of the device: the one interface they need, not its type.
pub(crate) trait Hub: Send + Sync + 'static {
    /// Hands `x`, read from `port` at `at`, to the device (after any deadline that fell before
    /// it) and moves what the device has to the ports. False when the runtime has stopped.
    fn input(&self, port: usize, x: PortInput, at: crate::Instant) -> bool;
    /// Moves what is queued for `port`, oldest first, into `into` as far as it has room. False
    /// when the runtime has stopped and nothing is left for the port; after the stop only
    /// frames are moved (a port task writes them and takes again until this says false).
    fn take(&self, port: usize, into: &mut Outbox) -> bool;
    /// `port`'s task has ended: the runtime's shutdown no longer waits for it.
    fn finished(&self, port: usize);
    /// Moves the frames at the head of `port`'s queue, up to its first other command, into
    /// `into` as far as it has room: what a reader thread writes itself. `Some(true)` when
    /// something is left in the queue, `None` when the runtime has stopped.
    fn take_frames(&self, port: usize, into: &mut Outbox) -> Option<bool>;
    /// [`Hub::input`] for a CAN FD frame (`stamp`: its receive timestamp, if the port took one).
    /// False when the runtime has stopped.
    fn input_fd(
        &self,
        port: usize,
        frame: &FdFrame,
        stamp: Option<std::time::Instant>,
        at: crate::Instant,
    ) -> bool;
    /// [`Hub::input`], then [`Hub::take_frames`] for the same port, under one lock: what a
    /// reader thread does with each frame (holding the port's writer lock).
    fn input_take(
        &self,
        port: usize,
        x: PortInput,
        at: crate::Instant,
        into: &mut Outbox,
    ) -> Option<bool>;
    /// The runtime still runs.
    fn is_open(&self) -> bool;
    /// A re-initialisation of `port` is queued: a send waiting for room on it gives up (the
    /// device has given its frames up).
    fn reinit_queued(&self, port: usize) -> bool;
}

mod shared;
mod state;

pub(crate) use shared::Shared;
pub(crate) use state::State;

/// The core task: commands from handles and the device's deadlines.
pub(crate) async fn run<D>(shared: Arc<Shared<D>>, mut commands: mpsc::UnboundedReceiver<Command>)
where
    D: Device + Send + 'static,
    D::Event: Send + std::fmt::Debug,
{
    tracing::info!(ports = shared.ports.len(), "runtime started");
    let clock = match shared.state.lock() {
        Ok(st) => st.clock,
        Err(_) => return,
    };
    // One timer for the task's life, moved only when the device's deadline changes: setting a
    // timer on every wake-up would cost a trip through tokio's timer wheel each time.
    let sleep = tokio::time::sleep_until(clock.to_tokio(crate::Instant::MAX));
    tokio::pin!(sleep);
    let mut set_for: Option<Option<crate::Instant>> = None;
    // Each turn sets the timer for the device's deadline as it is now (`None`: the lock is
    // poisoned, a closure panicked in it: the runtime is over).
    while let Some(deadline) = shared.with(|st| {
        st.armed = st.device.poll_timeout();
        st.armed
    }) {
        if set_for != Some(deadline) {
            sleep
                .as_mut()
                .reset(clock.to_tokio(deadline.unwrap_or(crate::Instant::MAX)));
            set_for = Some(deadline);
        }
        tokio::select! {
            // Only a shutdown comes this way, or the last handle gone.
            _ = commands.recv() => break,
            () = shared.core.notified() => {}
            () = &mut sleep, if deadline.is_some() => {
                // Set the timer again next time round, even for the same deadline.
                set_for = None;
                if shared.with(|st| { let now = st.now(); st.timeouts(now) }).is_none() {
                    break;
                }
            }
        }
    }
    shared.close();
    shared.drain(DRAIN_GRACE).await;
    tracing::info!("runtime stopped");
}

#[cfg(test)]
mod tests;
