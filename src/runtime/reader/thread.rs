//! The reader thread itself: it waits in the port's own `read`, hands each input to the device
//! under the state's lock and writes the device's answers on the port in the same turn of the
//! writer lock. Apart from the task's side ([`super`]) because it runs outside tokio: it
//! blocks, and it reports failures back through [`Ctl`] and the hub.

use super::lock::WriterLock;
use super::Ctl;
use crate::machine::{ErrorCause, PortStatus};
use crate::port::{PortCounters, PortInput, PortReader};
use crate::runtime::defer::Unlocked;
use crate::runtime::port_task::is_down;
use crate::runtime::task::{Hub, Outbox, PortCmd};
use crate::runtime::ThreadClock;
use std::sync::Arc;
use tokio::sync::Notify;

/// What the reader thread holds.
pub(super) struct Thread {
    pub(super) index: usize,
    pub(super) clock: ThreadClock,
    pub(super) hub: Arc<dyn Hub>,
    pub(super) wake: Arc<Notify>,
    pub(super) counters: PortCounters,
    pub(super) ctl: Arc<Ctl>,
    pub(super) writer: Arc<WriterLock>,
}

/// Holds the thread's reader, and when the thread ends (also when the device panicked in it)
/// drops it (closing what it holds of the port) and then tells the task.
struct Exit(Arc<Ctl>, Option<Box<dyn PortReader>>);

impl Drop for Exit {
    fn drop(&mut self) {
        drop(self.1.take());
        self.0.exited.notify_one();
    }
}

impl Thread {
    pub(super) fn run(self, reader: Box<dyn PortReader>) {
        let mut exit = Exit(self.ctl.clone(), Some(reader));
        let Some(reader) = exit.1.as_mut() else {
            return;
        };
        let mut out = Outbox::new();
        while !self.ctl.stopped() {
            match reader.read() {
                Ok(None) => {
                    if !self.hub.is_open() {
                        return;
                    }
                }
                Ok(Some(x)) => {
                    if self.ctl.stopped() {
                        return;
                    }
                    // Whom the batch's inputs wake (a task waiting for a transfer's outcome) is
                    // woken once the writer lock is given back, not only the state's: woken
                    // before, its next request would find the port's task waiting for this
                    // turn, and the turn's end would wake that task across threads again.
                    let _later = Unlocked::new();
                    // They were read at one instant: the clock is read once for them all.
                    let at = self.clock.now();
                    // The writer lock first, then the state's: the order the task takes them in.
                    // The reader waits for it (the task holds it only while it writes what
                    // timers and calls queued) so that the batch's answers go out from here, in
                    // this turn, with no hand-over to the port's task.
                    let _turn = self.writer.take_blocking();
                    // What the port read with this input in the same system call is handed on
                    // under the same turn, and the answers to all of them sent together.
                    let mut next = Some(x);
                    while let Some(x) = next {
                        let Some(left) = self.hub.input_take(self.index, x, at, &mut out) else {
                            // The runtime stopped: the answers to the batch's earlier inputs
                            // still go out, as what was queued before a shutdown does.
                            self.flush(&mut **reader);
                            return;
                        };
                        if !self.write_answers(&mut **reader, &mut out, left) {
                            return;
                        }
                        next = reader.read_ready();
                    }
                    if !self.flush(&mut **reader) {
                        return;
                    }
                }
                Err(e) => {
                    tracing::warn!(error = %e, "receive failed");
                    self.fail(e.cause());
                    return;
                }
            }
        }
    }

    /// Tells the device and the task that the port failed.
    fn fail(&self, cause: ErrorCause) {
        let down = PortInput::Status(PortStatus::Down(cause));
        let _ = self.hub.input(self.index, down, self.clock.now());
        if let Ok(mut f) = self.ctl.failed.lock() {
            *f = Some(cause);
        }
        self.wake.notify_one();
    }

    /// Writes the frames taken into `out` and then what else is queued for the port, in order
    /// (`left`: something is); false when the thread is to stop. The caller holds the writer
    /// lock.
    fn write_answers(&self, reader: &mut dyn PortReader, out: &mut Outbox, left: bool) -> bool {
        let mut left = left;
        loop {
            if out.is_empty() {
                if !left {
                    return true;
                }
                match self.hub.take_frames(self.index, out) {
                    None => return false,
                    Some(more) if out.is_empty() => {
                        if more {
                            // A request waits at the head of the queue: the task's.
                            self.wake.notify_one();
                        }
                        return true;
                    }
                    Some(more) => left = more,
                }
            }
            while let Some(cmd) = out.pop_front() {
                // `take_frames` takes nothing else.
                let PortCmd::Send(f) = cmd else { continue };
                let written = self.write(reader, &f);
                if written != Written::Yes {
                    while out.pop_front().is_some() {
                        self.counters.tx_dropped();
                    }
                    // Given up for a re-initialisation: the task's, once this turn ends.
                    self.wake.notify_one();
                    return written == Written::GivenUp;
                }
            }
        }
    }

    /// Sends what the reader kept of the frames written, waiting for room as long as the
    /// runtime runs; false when the thread is to stop (the port failed, or the runtime
    /// stopped).
    fn flush(&self, reader: &mut dyn PortReader) -> bool {
        loop {
            match reader.flush() {
                Ok(true) => return true,
                Ok(false) => {
                    if self.ctl.stopped() || !self.hub.is_open() {
                        return false;
                    }
                    // What is kept is the task's to drop: it stops this thread before it
                    // re-opens the port, and the reader counts what it never sent.
                    if self.hub.reinit_queued(self.index) {
                        self.wake.notify_one();
                        return true;
                    }
                }
                Err(e) => {
                    if !self.failed_send(&e) {
                        return false;
                    }
                }
            }
        }
    }

    /// Reports a failed send; false when the thread is to stop.
    fn failed_send(&self, e: &crate::port::PortError) -> bool {
        tracing::warn!(error = %e, "send failed");
        if is_down(e.kind) {
            self.fail(e.cause());
            return false;
        }
        let failed = PortInput::Status(PortStatus::TxFailed(e.cause()));
        let open = self.hub.input(self.index, failed, self.clock.now());
        // What the device queued for this port on hearing it is the task's to send.
        self.wake.notify_one();
        open
    }

    /// Writes one frame, waiting for room as long as the runtime runs and no re-initialisation
    /// of the port is queued (the device gave its frames up: a port whose bus takes none
    /// would otherwise hold the writer lock, and the task could not re-open it).
    fn write(&self, reader: &mut dyn PortReader, f: &crate::Frame) -> Written {
        loop {
            match reader.write(f) {
                Ok(true) => return Written::Yes,
                Ok(false) => {
                    if self.ctl.stopped() || !self.hub.is_open() {
                        self.counters.tx_dropped();
                        return Written::Stop;
                    }
                    if self.hub.reinit_queued(self.index) {
                        self.counters.tx_dropped();
                        return Written::GivenUp;
                    }
                }
                Err(e) if self.failed_send(&e) => return Written::Yes,
                Err(_) => return Written::Stop,
            }
        }
    }
}

/// What became of a frame the reader thread wrote.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Written {
    /// Written (or failed alone: reported, the next one is tried).
    Yes,
    /// Given up, waiting for room, for a re-initialisation of the port.
    GivenUp,
    /// The thread is to stop (the port failed, or the runtime stopped).
    Stop,
}
