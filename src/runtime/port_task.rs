//! One task per port: reads, writes, and re-opens after failures.

use crate::frame::instant::Instant;
use crate::frame::Frame;
use crate::machine::{ErrorCause, PortRequest, PortStatus};
use crate::port::{Port, PortErrorKind, PortInput};
use std::time::Duration;
use tokio::sync::mpsc;

/// First wait before re-opening a failed port; doubles up to [`BACKOFF_MAX`].
pub const BACKOFF_MIN: Duration = Duration::from_millis(20);
/// Longest wait between re-open attempts.
pub const BACKOFF_MAX: Duration = Duration::from_millis(500);

pub(crate) enum PortCmd {
    Send(Frame),
    Request(PortRequest),
}

/// What a port task hands the core: the port, the input, and when it was read (so that the
/// merger measures the skew between the buses, not the core's backlog).
pub(crate) type Arrival = (usize, PortInput, Instant);

pub(crate) struct Wiring {
    pub index: usize,
    pub net: String,
    pub clock: super::Clock,
    pub to_core: mpsc::Sender<Arrival>,
    pub from_core: mpsc::Receiver<PortCmd>,
}

enum Step {
    Continue,
    /// The port is unusable, for this reason (reported already).
    Failed(ErrorCause),
    Stop,
}

/// Inputs (or outgoing frames) moved per wake-up without waiting again.
const BURST: usize = 32;

pub(crate) async fn run<P: Port>(mut port: P, mut w: Wiring) {
    loop {
        let step = tokio::select! {
            cmd = w.from_core.recv() => match cmd {
                None => Step::Stop,
                Some(cmd) => {
                    let mut step = command(&mut port, &w, cmd).await;
                    for _ in 1..BURST {
                        if !matches!(step, Step::Continue) {
                            break;
                        }
                        match w.from_core.try_recv() {
                            Ok(cmd) => step = command(&mut port, &w, cmd).await,
                            Err(_) => break,
                        }
                    }
                    step
                }
            },
            r = port.recv() => {
                let mut step = input(&w, r).await;
                for _ in 1..BURST {
                    if !matches!(step, Step::Continue) {
                        break;
                    }
                    match port.try_recv() {
                        Some(r) => step = input(&w, r).await,
                        None => break,
                    }
                }
                step
            }
        };
        match step {
            Step::Continue => {}
            Step::Stop => return,
            Step::Failed(cause) => {
                if !recover(&mut port, &mut w, cause).await {
                    return;
                }
            }
        }
    }
}

async fn input(w: &Wiring, r: Result<PortInput, crate::port::PortError>) -> Step {
    match r {
        Ok(x) => {
            if w.to_core.send((w.index, x, w.clock.now())).await.is_err() {
                Step::Stop
            } else {
                Step::Continue
            }
        }
        Err(e) => {
            tracing::warn!(error = %e, "receive failed");
            report(w, PortStatus::Down(e.cause())).await;
            Step::Failed(e.cause())
        }
    }
}

async fn command<P: Port>(port: &mut P, w: &Wiring, cmd: PortCmd) -> Step {
    match cmd {
        PortCmd::Send(f) => match port.send(&f).await {
            Ok(()) => Step::Continue,
            Err(e) => {
                tracing::warn!(error = %e, "send failed");
                let down = matches!(
                    e.kind,
                    PortErrorKind::InterfaceDown
                        | PortErrorKind::NoSuchInterface
                        | PortErrorKind::Closed
                );
                if down {
                    report(w, PortStatus::Down(e.cause())).await;
                    Step::Failed(e.cause())
                } else {
                    report(w, PortStatus::TxFailed(e.cause())).await;
                    Step::Continue
                }
            }
        },
        PortCmd::Request(PortRequest::Reinit) => match port.reopen().await {
            Ok(()) => {
                report(w, PortStatus::Up).await;
                Step::Continue
            }
            Err(e) => {
                tracing::warn!(error = %e, "re-init failed");
                report(w, PortStatus::Down(e.cause())).await;
                Step::Failed(e.cause())
            }
        },
    }
}

async fn report(w: &Wiring, s: PortStatus) {
    let _ = w
        .to_core
        .send((w.index, PortInput::Status(s), w.clock.now()))
        .await;
}

/// Re-opens with backoff; frames the device sends meanwhile are dropped and counted, and a
/// re-initialisation the device asks for meanwhile is answered with the port still down (so
/// that it does not count on a port that cannot carry anything yet).
/// Returns false when the runtime is shutting down.
async fn recover<P: Port>(port: &mut P, w: &mut Wiring, cause: ErrorCause) -> bool {
    let counters = port.counters();
    let mut wait = BACKOFF_MIN;
    let mut attempts = 0u32;
    loop {
        let until = tokio::time::Instant::now() + wait;
        loop {
            tokio::select! {
                cmd = w.from_core.recv() => match cmd {
                    None => return false,
                    Some(PortCmd::Send(_)) => counters.tx_dropped(),
                    Some(PortCmd::Request(_)) => report(w, PortStatus::Down(cause)).await,
                },
                () = tokio::time::sleep_until(until) => break,
            }
        }
        attempts += 1;
        match port.reopen().await {
            Ok(()) => {
                tracing::info!(attempts, "port re-opened");
                report(w, PortStatus::Up).await;
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
mod tests {
    use super::*;
    use crate::port::{PortCounters, PortError};
    use crate::{Id, Instant};

    /// A port whose interface is down: every send and re-open fails, nothing arrives.
    struct DeadPort(PortCounters);

    impl Port for DeadPort {
        fn name(&self) -> &str {
            "dead0"
        }
        fn counters(&self) -> PortCounters {
            self.0.clone()
        }
        async fn recv(&mut self) -> Result<PortInput, PortError> {
            std::future::pending().await
        }
        async fn send(&mut self, _: &Frame) -> Result<(), PortError> {
            Err(PortError::new(
                "dead0",
                PortErrorKind::InterfaceDown,
                "send",
            ))
        }
        async fn reopen(&mut self) -> Result<(), PortError> {
            Err(PortError::new(
                "dead0",
                PortErrorKind::InterfaceDown,
                "reopen",
            ))
        }
    }

    #[tokio::test]
    async fn a_re_init_request_while_the_port_is_down_is_answered_with_down() {
        let (to_core, mut inputs) = mpsc::channel::<Arrival>(16);
        let (cmds, from_core) = mpsc::channel(16);
        let wiring = Wiring {
            index: 1,
            net: "test".into(),
            clock: super::super::Clock::start(),
            to_core,
            from_core,
        };
        tokio::spawn(run(DeadPort(PortCounters::new()), wiring));
        let f = Frame::from_array(Id::Standard(0x705), [5]);
        cmds.send(PortCmd::Send(f)).await.unwrap();
        let down = |x: Option<Arrival>| {
            matches!(
                x,
                Some((1, PortInput::Status(PortStatus::Down(ErrorCause::InterfaceDown)), at))
                    if at >= Instant::ZERO
            )
        };
        assert!(
            down(inputs.recv().await),
            "the failed send reports the port down"
        );
        // While it keeps trying to re-open, the device asks for a re-initialisation: it hears
        // at once that the port is still down (not silence, which it would take for success).
        cmds.send(PortCmd::Request(PortRequest::Reinit))
            .await
            .unwrap();
        assert!(down(inputs.recv().await));
    }
}
