//! A port read by a thread of its own ([`Port::reader`]): the thread waits in the socket's own
//! `read`, as a bare loop does, hands each input to the device under the state's lock and
//! writes the device's answers on its port right after. Inputs the port read together (one
//! system call, [`PortReader::read_ready`]) are handed on one by one in one turn of the writer
//! lock, and what the port kept of their answers is sent at the end of it
//! ([`PortReader::flush`]). The port's task serves what others
//! queued for the port (the device's timers, commands, the other port's frames), sends without
//! waiting, and re-opens the port after failures.
//!
//! Both write on the port: each holds the port's writer lock while it takes frames from the
//! queue and writes them, so that they go out in the order they were queued. The thread takes
//! only frames: a request to re-initialise the port is the task's, and it stops the thread
//! before it re-opens the port (frames read from the old socket never follow ones from the new).

use super::port_task::{command, is_down, report, settle, Step, Wiring};
use super::task::{Hub, Outbox, PortCmd};
use crate::machine::{ErrorCause, PortRequest, PortStatus};
use crate::port::{Port, PortCounters, PortInput, PortReader};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use tokio::sync::Notify;

/// One reader thread's controls.
#[derive(Default)]
struct Ctl {
    /// Set by the task: the thread is to stop (it looks at least every
    /// [`READER_WAIT`](crate::port::READER_WAIT)).
    stop: AtomicBool,
    /// Set by the thread: the port failed (reported already).
    failed: Mutex<Option<ErrorCause>>,
    /// Notified by the thread when it has stopped.
    exited: Notify,
}

impl Ctl {
    fn stopped(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }
}

/// Stops the current reader thread when the task ends, however it ends (also when its runtime
/// is dropped without a shutdown).
struct Current(Arc<Ctl>);

impl Drop for Current {
    fn drop(&mut self) {
        self.0.stop.store(true, Ordering::Release);
    }
}

/// The port's writer lock, between its reader thread (which takes it for every frame it reads:
/// one atomic swap each way, no wait machinery) and its task (which takes it seldom: for what
/// the device sends on timers and commands).
#[derive(Default)]
struct WriterLock {
    busy: AtomicBool,
    /// The task waits for the lock.
    waiting: AtomicBool,
    freed: Notify,
}

/// Holds the writer lock; gives it back when dropped.
struct Turn<'a>(&'a WriterLock);

impl Drop for Turn<'_> {
    fn drop(&mut self) {
        // Sequentially consistent with `take`'s store and swap: either the task's last try
        // sees the lock free, or this sees the task waiting.
        self.0.busy.store(false, Ordering::SeqCst);
        if self.0.waiting.swap(false, Ordering::SeqCst) {
            self.0.freed.notify_one();
        }
    }
}

impl WriterLock {
    fn try_take(&self) -> Option<Turn<'_>> {
        // `then`, not `then_some`: a `Turn` made eagerly for a failed try would be dropped at
        // once, and its drop gives the lock back, freeing it under its holder.
        self.busy
            .compare_exchange(false, true, Ordering::SeqCst, Ordering::Relaxed)
            .is_ok()
            .then(|| Turn(self))
    }

    /// For the task.
    async fn take(&self) -> Turn<'_> {
        loop {
            if let Some(t) = self.try_take() {
                return t;
            }
            let freed = self.freed.notified();
            tokio::pin!(freed);
            freed.as_mut().enable();
            self.waiting.store(true, Ordering::SeqCst);
            if let Some(t) = self.try_take() {
                self.waiting.store(false, Ordering::SeqCst);
                return t;
            }
            freed.await;
        }
    }

    /// For the reader thread: the task holds the lock only while it writes a few frames.
    fn take_blocking(&self) -> Turn<'_> {
        let mut tries = 0u32;
        loop {
            if let Some(t) = self.try_take() {
                return t;
            }
            tries += 1;
            if tries < 64 {
                std::thread::yield_now();
            } else {
                std::thread::sleep(std::time::Duration::from_micros(100));
            }
        }
    }
}

/// What stopped the serving of a port's queue.
enum Outcome {
    Step(Step),
    /// The device asked for the port to be re-initialised.
    Reinit,
}

/// The port's task while a thread reads the port.
pub(super) async fn run<P: Port>(mut port: P, first: Box<dyn PortReader>, w: Wiring) {
    let mut out = Outbox::new();
    let writer = Arc::new(WriterLock::default());
    let mut reader = Some(first);
    // Replaced by each new thread's, which stops the old one.
    let mut current: Current;
    loop {
        let ctl = Arc::new(Ctl::default());
        current = Current(ctl.clone());
        let started = match reader.take() {
            Some(r) => start(r, &w, &port.counters(), &ctl, &writer),
            None => false,
        };
        let outcome = if started {
            serve(&mut port, &w, &mut out, &ctl, &writer).await
        } else {
            report(&w, PortStatus::Down(ErrorCause::Other));
            Outcome::Step(Step::Failed(ErrorCause::Other))
        };
        // The old thread stops before anything else is done on the port.
        ctl.stop.store(true, Ordering::Release);
        if started {
            ctl.exited.notified().await;
        }
        let step = match outcome {
            Outcome::Reinit => {
                let reinit = PortCmd::Request(PortRequest::Reinit);
                command(&mut port, &w, reinit, &mut out).await
            }
            Outcome::Step(s) => s,
        };
        if !settle(&mut port, &w, &mut out, step).await {
            return;
        }
        // Re-opened: what was left of the queue when the old thread stopped is served first.
        w.wake.notify_one();
        reader = port.reader();
        if reader.is_none() {
            tracing::warn!("the re-opened port has no reader, reading through readiness");
            drop(current);
            return super::port_task::run_async(port, w, out).await;
        }
    }
}

/// Starts the reader thread; false (reported) if the system refused a thread.
fn start(
    reader: Box<dyn PortReader>,
    w: &Wiring,
    counters: &PortCounters,
    ctl: &Arc<Ctl>,
    writer: &Arc<WriterLock>,
) -> bool {
    let t = Thread {
        index: w.index,
        clock: w.clock.on_thread(),
        hub: w.hub.clone(),
        wake: w.wake.clone(),
        counters: counters.clone(),
        ctl: ctl.clone(),
        writer: writer.clone(),
    };
    // Named after the runtime's worker that starts it when the application named its workers
    // (tokio's builder), so that per-thread accounting (`top -H`, /proc/<pid>/task) puts the
    // port's reading with the runtime it works for.
    let name = match std::thread::current().name() {
        Some(n) if !n.starts_with("tokio-runtime") => format!("{n}-rx{}", w.index),
        _ => format!("duocan-rx{}", w.index),
    };
    match std::thread::Builder::new()
        .name(name)
        .spawn(move || t.run(reader))
    {
        Ok(_) => true,
        Err(e) => {
            tracing::error!(error = %e, "cannot start the port's reader thread");
            false
        }
    }
}

/// Serves the port's queue each time it is woken, until the runtime stops, the port fails or
/// the device asks for a re-initialisation (what follows that request stays in `out`).
async fn serve<P: Port>(
    port: &mut P,
    w: &Wiring,
    out: &mut Outbox,
    ctl: &Ctl,
    writer: &WriterLock,
) -> Outcome {
    loop {
        if let Some(cause) = ctl.failed.lock().ok().and_then(|f| *f) {
            return Outcome::Step(Step::Failed(cause));
        }
        {
            let _turn = writer.take().await;
            loop {
                if !w.hub.take(w.index, out) {
                    return Outcome::Step(Step::Stop);
                }
                if out.is_empty() {
                    break;
                }
                while let Some(cmd) = out.pop_front() {
                    if matches!(cmd, PortCmd::Request(PortRequest::Reinit)) {
                        return Outcome::Reinit;
                    }
                    let step = command(port, w, cmd, out).await;
                    if !matches!(step, Step::Continue) {
                        return Outcome::Step(step);
                    }
                }
            }
        }
        w.wake.notified().await;
    }
}

/// What the reader thread holds.
struct Thread {
    index: usize,
    clock: super::ThreadClock,
    hub: Arc<dyn Hub>,
    wake: Arc<Notify>,
    counters: PortCounters,
    ctl: Arc<Ctl>,
    writer: Arc<WriterLock>,
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
    fn run(self, reader: Box<dyn PortReader>) {
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
                    let _later = super::defer::Unlocked::new();
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

#[cfg(test)]
mod tests {
    use super::WriterLock;

    /// A try that fails must leave the lock with its holder (a guard made for the failed try
    /// and dropped would give it back: two writers at once, frames out of order).
    #[test]
    fn a_failed_try_leaves_the_lock_with_its_holder() {
        let lock = WriterLock::default();
        let held = lock.try_take().expect("a free lock is taken");
        assert!(lock.try_take().is_none());
        assert!(lock.try_take().is_none(), "still held after a failed try");
        drop(held);
        assert!(lock.try_take().is_some());
    }
}
