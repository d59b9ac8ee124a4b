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

use super::defer::Unlocked;
pub(crate) use super::outbox::{move_into, Outbox, PortCmd};
use super::outbox::{move_one, take_frames};
use super::{Clock, RuntimeEvent, PORT_FD_TX_QUEUE, PORT_TX_QUEUE};
use crate::capture::recorder::{Tap, TapDirection, TapPoint};
use crate::frame::FdFrame;
use crate::machine::{Device, PortRequest, PortStatus};
use crate::port::{PortCounters, PortInput};
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use tokio::sync::{broadcast, mpsc, Notify};

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

/// Timeouts a device may have due at one instant before the runtime moves on: a device whose
/// deadline stays in the past after its timeout ran must not hold a port task forever.
const TIMEOUTS_PER_INPUT: usize = 64;

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

/// Everything the lock guards.
pub(crate) struct State<D: Device> {
    pub device: Box<D>,
    pub clock: Clock,
    pub counters: Vec<PortCounters>,
    pub events: broadcast::Sender<RuntimeEvent<D::Event>>,
    pub tap: Option<Arc<dyn Tap>>,
    pub watchers: Vec<Watcher<D::Event>>,
    /// The latest instant handed to the device: inputs stamped earlier (read before the
    /// device's last call) are handed over at this instant, so that its time never goes back.
    pub last: crate::Instant,
    /// Per port, what its task is to do, in order; never longer than [`PORT_TX_QUEUE`] (the
    /// room is taken once, when the runtime starts).
    pub queues: Vec<VecDeque<PortCmd>>,
    /// Per port, the CAN FD frames its [`PortCmd::SendFd`] commands stand for, in order; never
    /// longer than [`PORT_FD_TX_QUEUE`]. Empty (no room taken) for a classic device.
    pub fd_queues: Vec<VecDeque<FdFrame>>,
    /// The deadline the core task's timer is set for.
    pub armed: Option<crate::Instant>,
    /// The core task has stopped: port tasks write what is left in their queues, then stop.
    pub closed: bool,
    /// Per port, one bit: its task has written what was left when the runtime stopped (or
    /// has ended).
    pub drained: u64,
}

/// The state and the wake-ups around it.
pub(crate) struct Shared<D: Device> {
    pub state: Mutex<State<D>>,
    /// Wakes the core task: the device's deadline moved earlier than its timer.
    pub core: Notify,
    /// Wakes each port's task: something was queued for it, or the runtime stopped.
    pub ports: Vec<Arc<Notify>>,
    /// Notified when a port task has drained its queue after the runtime stopped.
    pub drained: Notify,
}

impl<D: Device> State<D>
where
    D::Event: std::fmt::Debug,
{
    /// A state with room taken for every queue.
    pub fn new(
        device: Box<D>,
        clock: Clock,
        counters: Vec<PortCounters>,
        events: broadcast::Sender<RuntimeEvent<D::Event>>,
        tap: Option<Arc<dyn Tap>>,
    ) -> Self {
        let queues = (0..counters.len())
            .map(|_| VecDeque::with_capacity(PORT_TX_QUEUE))
            .collect();
        let fd_queues = if device.fd_capable() {
            (0..counters.len())
                .map(|_| VecDeque::with_capacity(PORT_FD_TX_QUEUE))
                .collect()
        } else {
            Vec::new()
        };
        State {
            device,
            clock,
            counters,
            events,
            tap,
            watchers: Vec::new(),
            last: crate::Instant::ZERO,
            queues,
            fd_queues,
            armed: None,
            closed: false,
            drained: 0,
        }
    }

    /// The clock's time, as the device's next instant.
    pub fn now(&mut self) -> crate::Instant {
        self.at(self.clock.now())
    }

    /// `t`, or the device's last instant if that is later.
    fn at(&mut self, t: crate::Instant) -> crate::Instant {
        self.last = self.last.max(t);
        self.last
    }

    /// Runs the device's timeouts due by `t`, each at the instant it fell due (or the device's
    /// last instant, if later).
    pub fn timeouts(&mut self, t: crate::Instant) {
        self.due_before(t, true);
    }

    /// Runs the timeouts due before `t` (`t` itself too if `inclusive`): a deadline that
    /// passed before an input was read is handled before that input, at its own instant; one
    /// that falls at the very instant of the input comes after it, as the input arrived in time.
    fn due_before(&mut self, t: crate::Instant, inclusive: bool) {
        for _ in 0..TIMEOUTS_PER_INPUT {
            match self.device.poll_timeout() {
                Some(due) if due < t || (inclusive && due == t) => {
                    let now = self.at(due);
                    self.device.handle_timeout(now);
                }
                _ => return,
            }
        }
    }

    /// Hands `x`, read from `port` at `read_at`, to the device: a frame with its receive
    /// timestamp through [`Device::handle_rx_at`] (the stamp on the runtime's clock, never
    /// after the instant it is handled at), one without through [`Device::handle_rx`].
    pub fn input(&mut self, port: usize, x: PortInput, read_at: crate::Instant) {
        self.due_before(read_at, false);
        let now = self.at(read_at);
        match x {
            PortInput::Frame(f, stamp) => {
                let at = stamp.map(|s| self.clock.instant_of(s).min(now));
                if let Some(t) = &self.tap {
                    t.frame(
                        at.unwrap_or(now),
                        TapPoint::Port(port),
                        TapDirection::Rx,
                        &f,
                    );
                }
                match at {
                    Some(at) => self.device.handle_rx_at(now, port, &f, at),
                    None => self.device.handle_rx(now, port, &f),
                }
            }
            // A transmission confirmed (a port asked to confirm them, one per frame sent): the
            // device's business, no news for logs or subscribers.
            PortInput::Status(PortStatus::TxOk) => {
                self.device.handle_port_status(now, port, PortStatus::TxOk)
            }
            PortInput::Status(status) => {
                match status {
                    PortStatus::Down(_) | PortStatus::TxFailed(_) | PortStatus::Error(_) => {
                        tracing::warn!(port, ?status, "port status")
                    }
                    _ => tracing::info!(port, ?status, "port status"),
                }
                self.device.handle_port_status(now, port, status);
                let _ = self.events.send(RuntimeEvent::Port {
                    at: now,
                    port,
                    status,
                });
            }
        }
    }

    /// Hands a CAN FD frame read from `port` at `read_at` to the device through
    /// [`Device::handle_rx_fd`], with its receive timestamp on the runtime's clock as for a
    /// classic frame (`stamp` none: the instant it is handled at).
    pub fn input_fd(
        &mut self,
        port: usize,
        f: &FdFrame,
        stamp: Option<std::time::Instant>,
        read_at: crate::Instant,
    ) {
        self.due_before(read_at, false);
        let now = self.at(read_at);
        let at = stamp.map_or(now, |s| self.clock.instant_of(s).min(now));
        self.device.handle_rx_fd(now, port, f, at);
    }

    /// Drops the frames queued for `port` (counted as dropped), CAN FD ones too.
    fn drop_sends(&mut self, port: usize) {
        let (Some(q), Some(counters)) = (self.queues.get_mut(port), self.counters.get(port)) else {
            return;
        };
        q.retain(|c| {
            let send = matches!(c, PortCmd::Send(_) | PortCmd::SendFd);
            if send {
                counters.tx_dropped();
            }
            !send
        });
        if let Some(fd) = self.fd_queues.get_mut(port) {
            fd.clear();
        }
    }

    /// Queues `cmd` for `port`; false if the port has no room (or does not exist).
    fn queue(&mut self, port: usize, cmd: PortCmd) -> bool {
        match self.queues.get_mut(port) {
            Some(q) if q.len() < PORT_TX_QUEUE => {
                q.push_back(cmd);
                true
            }
            _ => false,
        }
    }

    /// Moves everything the device has to the port queues and the subscribers; returns the
    /// ports that got work, one bit each (all bits from 63 on for ports past 62).
    pub fn flush(&mut self) -> u64 {
        self.flush_into(None)
    }

    /// [`State::flush`], but frames for the port of `direct` go straight into its outbox while
    /// that port's queue is empty and the outbox has room (a reader thread writing its answers:
    /// no trip through the queue, and the order is kept, as the queue is taken after).
    pub fn flush_into(&mut self, mut direct: Option<(usize, &mut Outbox)>) -> u64 {
        let bit = |port: usize| 1u64 << port.min(63);
        let mut woken = 0;
        // Only the tap needs the time: read the clock once, and only for it.
        let mut now = None;
        // Taking an event may give the device more to send (a transfer waiting for a session
        // starts when another's result is taken): until a round takes none.
        let mut again = true;
        while std::mem::take(&mut again) {
            while let Some((port, f)) = self.device.poll_transmit() {
                if port >= self.queues.len() {
                    tracing::error!(port, "device sent on a port it does not have");
                    continue;
                }
                if let Some(t) = &self.tap {
                    let at = *now.get_or_insert_with(|| self.clock.now());
                    t.frame(at, TapPoint::Port(port), TapDirection::Tx, &f);
                }
                let cmd = match &mut direct {
                    Some((own, into)) if *own == port && self.queues[port].is_empty() => {
                        match into.push_back(PortCmd::Send(f)) {
                            Ok(()) => continue,
                            Err(cmd) => cmd,
                        }
                    }
                    _ => PortCmd::Send(f),
                };
                if self.queue(port, cmd) {
                    woken |= bit(port);
                } else {
                    // The port cannot keep up (or is down): drop rather than stall the device.
                    self.counters[port].tx_dropped();
                    tracing::debug!(port, frame = %f, "port queue full, frame dropped");
                }
            }
            self.flush_fd(&mut woken);
            while let Some((port, req)) = self.device.poll_port_request() {
                tracing::info!(port, ?req, "port request");
                // A re-initialisation flushes the port: what waits for it was given up by
                // the device (a stalled port's frames would only come out late, as
                // duplicates of their twins), so it does not go out before the re-opening.
                if req == PortRequest::Reinit {
                    self.drop_sends(port);
                }
                if self.queue(port, PortCmd::Request(req)) {
                    woken |= bit(port);
                }
            }
            while let Some(e) = self.device.poll_event() {
                again = true;
                tracing::debug!(event = ?e, "event");
                // Watchers see every event, losslessly, before subscribers (who may lag).
                self.watchers.retain_mut(|w| !w(&e));
                // No subscriber is fine: events are then only logged (and not stored).
                if self.events.receiver_count() > 0 {
                    let _ = self.events.send(RuntimeEvent::Device(e));
                }
            }
        }
        woken
    }
}

impl<D: Device> State<D> {
    /// Moves the CAN FD frames the device has into their ports' FD queues, each with a
    /// [`PortCmd::SendFd`] in the port's queue; a frame for a full queue (or from a device
    /// that said it is classic) is dropped and counted.
    fn flush_fd(&mut self, woken: &mut u64) {
        if self.fd_queues.is_empty() {
            return;
        }
        while let Some((port, f)) = self.device.poll_transmit_fd() {
            let (Some(q), Some(fd)) = (self.queues.get_mut(port), self.fd_queues.get_mut(port))
            else {
                tracing::error!(
                    port,
                    "device sent a CAN FD frame on a port it does not have"
                );
                continue;
            };
            if q.len() < PORT_TX_QUEUE && fd.len() < PORT_FD_TX_QUEUE {
                fd.push_back(f);
                q.push_back(PortCmd::SendFd);
                *woken |= 1u64 << port.min(63);
            } else {
                self.counters[port].tx_dropped();
                tracing::debug!(port, frame = %f, "port queue full, CAN FD frame dropped");
            }
        }
    }
}

impl<D: Device + Send + 'static> Shared<D>
where
    D::Event: Send + std::fmt::Debug,
{
    /// Wakes the tasks of the ports in `woken` but `own` (a port task serves its own queue
    /// right after), and the core task if the device's deadline is now earlier than its timer.
    fn wake(&self, st: &State<D>, woken: u64, own: Option<usize>) {
        if woken != 0 {
            for (i, n) in self.ports.iter().enumerate() {
                if Some(i) != own && woken & (1u64 << i.min(63)) != 0 {
                    n.notify_one();
                }
            }
        }
        if let Some(t) = st.device.poll_timeout() {
            if st.armed.is_none_or(|a| t < a) {
                self.core.notify_one();
            }
        }
    }

    /// Runs `f` on the state, then flushes and wakes whoever got work.
    pub fn with<R>(&self, f: impl FnOnce(&mut State<D>) -> R) -> Option<R> {
        let _later = Unlocked::new();
        let mut st = self.state.lock().ok()?;
        let r = f(&mut st);
        let woken = st.flush();
        self.wake(&st, woken, None);
        Some(r)
    }

    /// Stops the port tasks: each writes what is left in its queue first.
    pub fn close(&self) {
        if let Ok(mut st) = self.state.lock() {
            st.closed = true;
        }
        for n in &self.ports {
            n.notify_one();
        }
    }

    /// Waits until every port task has written what was left in its queue when the runtime
    /// stopped (or has ended), at most `grace`: a port that cannot send does not hold up the
    /// shutdown for longer.
    pub async fn drain(&self, grace: std::time::Duration) {
        let all = match self.ports.len() {
            0 => return,
            n => u64::MAX >> (64 - n.min(64)),
        };
        let _ = tokio::time::timeout(grace, async {
            loop {
                let freed = self.drained.notified();
                tokio::pin!(freed);
                freed.as_mut().enable();
                match self.state.lock() {
                    Ok(st) if st.drained & all != all => {}
                    _ => return,
                }
                freed.await;
            }
        })
        .await;
    }

    /// Marks `port`'s task as drained.
    fn mark_drained(&self, st: &mut State<D>, port: usize) {
        st.drained |= 1u64 << port.min(63);
        self.drained.notify_one();
    }
}

impl<D: Device + Send + 'static> Hub for Shared<D>
where
    D::Event: Send + std::fmt::Debug,
{
    fn input(&self, port: usize, x: PortInput, at: crate::Instant) -> bool {
        let _later = Unlocked::new();
        let Ok(mut st) = self.state.lock() else {
            return false;
        };
        if st.closed {
            return false;
        }
        st.input(port, x, at);
        let woken = st.flush();
        self.wake(&st, woken, Some(port));
        true
    }

    fn input_fd(
        &self,
        port: usize,
        frame: &FdFrame,
        stamp: Option<std::time::Instant>,
        at: crate::Instant,
    ) -> bool {
        let _later = Unlocked::new();
        let Ok(mut st) = self.state.lock() else {
            return false;
        };
        if st.closed {
            return false;
        }
        st.input_fd(port, frame, stamp, at);
        let woken = st.flush();
        self.wake(&st, woken, Some(port));
        true
    }

    fn take(&self, port: usize, into: &mut Outbox) -> bool {
        let Ok(mut st) = self.state.lock() else {
            return false;
        };
        let st = &mut *st;
        let mut none = VecDeque::new();
        let fd = st.fd_queues.get_mut(port).unwrap_or(&mut none);
        let Some(q) = st.queues.get_mut(port) else {
            return !st.closed;
        };
        if st.closed {
            // What was queued before the stop still goes out (the NMT command a tool sends
            // just before it exits): the frames, not requests to re-initialise the port.
            while matches!(q.front(), Some(PortCmd::Request(_))) {
                q.pop_front();
            }
            while !q.is_empty() && move_one(q, fd, into) {
                while matches!(q.front(), Some(PortCmd::Request(_))) {
                    q.pop_front();
                }
            }
            if into.is_empty() {
                self.mark_drained(st, port);
                return false;
            }
            return true;
        }
        move_into(q, fd, into);
        true
    }

    fn finished(&self, port: usize) {
        if let Ok(mut st) = self.state.lock() {
            self.mark_drained(&mut st, port);
        }
    }

    fn take_frames(&self, port: usize, into: &mut Outbox) -> Option<bool> {
        let mut st = self.state.lock().ok()?;
        if st.closed {
            return None;
        }
        take_frames(st.queues.get_mut(port)?, into)
    }

    fn input_take(
        &self,
        port: usize,
        x: PortInput,
        at: crate::Instant,
        into: &mut Outbox,
    ) -> Option<bool> {
        let _later = Unlocked::new();
        let mut st = self.state.lock().ok()?;
        if st.closed {
            return None;
        }
        st.input(port, x, at);
        let woken = st.flush_into(Some((port, into)));
        self.wake(&st, woken, Some(port));
        take_frames(st.queues.get_mut(port)?, into)
    }

    fn is_open(&self) -> bool {
        self.state.lock().is_ok_and(|st| !st.closed)
    }

    fn reinit_queued(&self, port: usize) -> bool {
        self.state.lock().is_ok_and(|st| {
            st.queues.get(port).is_some_and(|q| {
                q.iter()
                    .any(|c| matches!(c, PortCmd::Request(PortRequest::Reinit)))
            })
        })
    }
}

impl<D: Device + Send + 'static> Direct<D> for Shared<D>
where
    D::Event: Send + std::fmt::Debug,
{
    fn call(&self, f: &mut dyn FnMut(&mut D, crate::Instant)) -> bool {
        self.with(|st| {
            if st.closed {
                return false;
            }
            let now = st.now();
            f(&mut *st.device, now);
            true
        }) == Some(true)
    }

    fn watch(&self, start: Start<D, D::Event>) -> bool {
        self.with(|st| {
            if st.closed {
                return false;
            }
            let now = st.now();
            if let Some(w) = start(&mut *st.device, now) {
                st.watchers.push(w);
            }
            true
        }) == Some(true)
    }
}

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
