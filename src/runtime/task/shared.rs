//! The state behind its lock, and the wake-ups around it: how port tasks, handles and the core
//! task take the lock, and whom they wake after (the port tasks that got work, the core task
//! when the device's deadline moved earlier). Kept apart from what is done under the lock
//! ([`super::state`]): this is the concurrency, that the device's order.

use super::{Direct, Hub, Start, State};
use crate::frame::FdFrame;
use crate::machine::{Device, PortRequest};
use crate::port::PortInput;
use crate::runtime::defer::Unlocked;
use crate::runtime::outbox::{move_into, move_one, take_frames, Outbox, PortCmd};
use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use tokio::sync::Notify;

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
