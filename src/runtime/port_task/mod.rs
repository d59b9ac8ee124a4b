//! One task per port: reads and hands what it read to the device, writes what the device
//! queued for its port, and re-opens the port after failures.

use super::task::{Hub, Outbox, PortCmd};
use crate::machine::{ErrorCause, PortRequest, PortStatus};
use crate::port::{AnyInput, Port, PortError, PortErrorKind, PortInput};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;

/// First wait before re-opening a failed port; doubles up to [`BACKOFF_MAX`].
pub const BACKOFF_MIN: Duration = Duration::from_millis(20);
/// Longest wait between re-open attempts.
pub const BACKOFF_MAX: Duration = Duration::from_millis(500);

pub(crate) struct Wiring {
    pub index: usize,
    pub net: String,
    pub clock: super::Clock,
    /// The device speaks CAN FD: the port is read through [`Port::recv_any`].
    pub fd: bool,
    pub hub: Arc<dyn Hub>,
    /// Notified when something is queued for this port (or the runtime stops).
    pub wake: Arc<Notify>,
}

pub(super) enum Step {
    Continue,
    /// The port is unusable, for this reason (reported already).
    Failed(ErrorCause),
    Stop,
}

/// Inputs read per wake-up without waiting again (then the queue gets its turn).
const BURST: usize = 32;

pub(crate) async fn run<P: Port>(mut port: P, w: Wiring) {
    // However the task ends (also aborted with its runtime), the shutdown stops waiting for it.
    let _finished = Finished(w.hub.clone(), w.index);
    // The reader thread moves classic frames only: a device that speaks CAN FD reads its
    // ports through `recv_any`.
    if w.fd {
        return run_any(port, w, Outbox::new()).await;
    }
    if let Some(reader) = port.reader() {
        return super::reader::run(port, reader, w).await;
    }
    run_async(port, w, Outbox::new()).await;
}

/// Tells the hub the port's task has ended, when dropped.
struct Finished(Arc<dyn Hub>, usize);

impl Drop for Finished {
    fn drop(&mut self) {
        self.0.finished(self.1);
    }
}

/// The port's task reading through the port's `recv` (`out`: what is left to do first).
pub(super) async fn run_async<P: Port>(mut port: P, w: Wiring, mut out: Outbox) {
    w.wake.notify_one();
    loop {
        let step = tokio::select! {
            () = w.wake.notified() => serve(&mut port, &w, &mut out).await,
            r = port.recv() => {
                let mut r = r;
                let mut step = Step::Continue;
                // Each input is handed over and answered before the next is looked for: the
                // answer to a frame does not wait for a look at an empty socket.
                for n in 1..=BURST {
                    let handed = r.map(|x| w.hub.input(w.index, x, w.clock.now()));
                    step = answer(&mut port, &w, &mut out, handed).await;
                    if n == BURST || !matches!(step, Step::Continue) {
                        break;
                    }
                    match port.try_recv() {
                        Some(next) => r = next,
                        None => break,
                    }
                }
                step
            }
        };
        if !settle(&mut port, &w, &mut out, step).await {
            return;
        }
    }
}

/// The port's task reading through the port's `recv_any`, for a device that speaks CAN FD
/// (`out`: what is left to do first).
async fn run_any<P: Port>(mut port: P, w: Wiring, mut out: Outbox) {
    w.wake.notify_one();
    loop {
        let step = tokio::select! {
            () = w.wake.notified() => serve(&mut port, &w, &mut out).await,
            r = port.recv_any() => {
                let now = w.clock.now();
                let handed = r.map(|x| match x {
                    AnyInput::Fd(f, stamp) => w.hub.input_fd(w.index, &f, stamp, now),
                    AnyInput::Frame(f, stamp) => {
                        w.hub.input(w.index, PortInput::Frame(f, stamp), now)
                    }
                    AnyInput::Status(s) => w.hub.input(w.index, PortInput::Status(s), now),
                });
                answer(&mut port, &w, &mut out, handed).await
            }
        };
        if !settle(&mut port, &w, &mut out, step).await {
            return;
        }
    }
}

/// After an input was read: `Ok(true)` it was handed to the device, whose answers go out now;
/// `Ok(false)` the runtime stopped (what is left in the queue still goes out); `Err` the port
/// failed (reported).
async fn answer<P: Port>(
    port: &mut P,
    w: &Wiring,
    out: &mut Outbox,
    handed: Result<bool, PortError>,
) -> Step {
    match handed {
        Ok(true) => serve(port, w, out).await,
        Ok(false) => match serve(port, w, out).await {
            Step::Continue => Step::Stop,
            other => other,
        },
        Err(e) => {
            tracing::warn!(error = %e, "receive failed");
            report(w, PortStatus::Down(e.cause()));
            Step::Failed(e.cause())
        }
    }
}

/// Does what is queued for the port, in order, until the queue is empty.
async fn serve<P: Port>(port: &mut P, w: &Wiring, out: &mut Outbox) -> Step {
    loop {
        if !w.hub.take(w.index, out) {
            return Step::Stop;
        }
        if out.is_empty() {
            return Step::Continue;
        }
        while let Some(cmd) = out.pop_front() {
            let step = command(port, w, cmd, out).await;
            if !matches!(step, Step::Continue) {
                return step;
            }
        }
    }
}

/// Does `cmd`, just taken from `out` (whose next CAN FD frame is a [`PortCmd::SendFd`]'s).
pub(super) async fn command<P: Port>(
    port: &mut P,
    w: &Wiring,
    cmd: PortCmd,
    out: &mut Outbox,
) -> Step {
    match cmd {
        PortCmd::Send(f) => match sent_or_given_up(w, port.send(&f)).await {
            None => {
                tracing::debug!(frame = %f, "send given up for the port's re-initialisation");
                port.counters().tx_dropped();
                Step::Continue
            }
            Some(r) => sent(w, r),
        },
        PortCmd::SendFd => {
            let Some(f) = out.pop_fd() else {
                return Step::Continue;
            };
            match sent_or_given_up(w, port.send_fd(&f)).await {
                None => {
                    tracing::debug!(frame = %f, "send given up for the port's re-initialisation");
                    port.counters().tx_dropped();
                    Step::Continue
                }
                Some(r) => sent(w, r),
            }
        }
        PortCmd::Request(PortRequest::Reinit) => match port.reopen().await {
            Ok(()) => {
                report(w, PortStatus::Up);
                Step::Continue
            }
            Err(e) => {
                tracing::warn!(error = %e, "re-init failed");
                report(w, PortStatus::Down(e.cause()));
                Step::Failed(e.cause())
            }
        },
    }
}

/// What became of a send: a failure is reported (and a port gone is to be re-opened).
fn sent(w: &Wiring, r: Result<(), PortError>) -> Step {
    match r {
        Ok(()) => Step::Continue,
        Err(e) => {
            tracing::warn!(error = %e, "send failed");
            if is_down(e.kind) {
                report(w, PortStatus::Down(e.cause()));
                Step::Failed(e.cause())
            } else {
                report(w, PortStatus::TxFailed(e.cause()));
                Step::Continue
            }
        }
    }
}

/// Sends a frame (`send`: the port's send of it), or gives it up (`None`) when a re-initialisation of the port
/// is queued while the send waits (for room on a port whose bus takes no frames: the
/// re-initialisation would otherwise wait behind it, and the device has given the frame up
/// already).
async fn sent_or_given_up(
    w: &Wiring,
    send: impl std::future::Future<Output = Result<(), PortError>>,
) -> Option<Result<(), PortError>> {
    let reinit = async {
        // Each wake-up is something queued for the port; what is not a re-initialisation is
        // served after this send, as the queue is taken again then.
        loop {
            w.wake.notified().await;
            if w.hub.reinit_queued(w.index) {
                return;
            }
        }
    };
    tokio::select! {
        biased;
        r = send => Some(r),
        () = reinit => None,
    }
}

/// Goes on after `step`: re-opens a failed port (with backoff). False when the task is to end.
pub(super) async fn settle<P: Port>(
    port: &mut P,
    w: &Wiring,
    out: &mut Outbox,
    step: Step,
) -> bool {
    match step {
        Step::Continue => true,
        Step::Stop => false,
        Step::Failed(cause) => recover(port, w, out, cause).await,
    }
}

/// A send failed because the port is gone (not only this frame).
pub(super) fn is_down(kind: PortErrorKind) -> bool {
    matches!(
        kind,
        PortErrorKind::InterfaceDown | PortErrorKind::NoSuchInterface | PortErrorKind::Closed
    )
}

/// Hands the port's status to the device.
pub(super) fn report(w: &Wiring, s: PortStatus) {
    let _ = w.hub.input(w.index, PortInput::Status(s), w.clock.now());
}

/// Re-opens with backoff; frames the device sends meanwhile are dropped and counted, and a
/// re-initialisation the device asks for meanwhile is answered with the port still down (so
/// that it does not count on a port that cannot carry anything yet). What was queued before
/// the failure goes the same way.
/// Returns false when the runtime is shutting down.
pub(super) async fn recover<P: Port>(
    port: &mut P,
    w: &Wiring,
    out: &mut Outbox,
    cause: ErrorCause,
) -> bool {
    let counters = port.counters();
    let mut wait = BACKOFF_MIN;
    let mut attempts = 0u32;
    // Refuses what is queued; false when the runtime stopped.
    let refuse = |out: &mut Outbox| loop {
        while let Some(cmd) = out.pop_front() {
            match cmd {
                PortCmd::Send(_) => counters.tx_dropped(),
                PortCmd::SendFd => {
                    let _ = out.pop_fd();
                    counters.tx_dropped();
                }
                PortCmd::Request(_) => report(w, PortStatus::Down(cause)),
            }
        }
        if !w.hub.take(w.index, out) {
            return false;
        }
        if out.is_empty() {
            return true;
        }
    };
    if !refuse(out) {
        return false;
    }
    loop {
        let until = tokio::time::Instant::now() + wait;
        loop {
            tokio::select! {
                () = w.wake.notified() => if !refuse(out) {
                    return false;
                },
                () = tokio::time::sleep_until(until) => break,
            }
        }
        attempts += 1;
        match port.reopen().await {
            Ok(()) => {
                tracing::info!(attempts, "port re-opened");
                report(w, PortStatus::Up);
                return true;
            }
            Err(e) => {
                if attempts == 1 || attempts.is_multiple_of(20) {
                    tracing::warn!(attempts, error = %e, "re-open failed, retrying");
                }
                wait = (wait * 2).min(BACKOFF_MAX);
            }
        }
    }
}

#[cfg(test)]
mod tests;
