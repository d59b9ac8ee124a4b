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
//!
//! The writer lock is in [`lock`], the thread's own loop in [`thread`]; here is the port's task
//! that starts, serves beside and stops the thread.

mod lock;
mod thread;

use super::port_task::{command, report, settle, Step, Wiring};
use super::task::{Outbox, PortCmd};
use crate::machine::{ErrorCause, PortRequest, PortStatus};
use crate::port::{Port, PortCounters, PortReader};
use lock::WriterLock;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use thread::Thread;
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
