//! The core task: the only owner of the device.

use super::port_task::{Arrival, PortCmd};
use super::{Clock, RuntimeEvent};
use crate::capture::recorder::{Tap, TapDirection, TapPoint};
use crate::machine::{Device, PortStatus};
use crate::port::{PortCounters, PortInput};
use std::sync::Arc;
use tokio::sync::{broadcast, mpsc};

/// A closure run on the device inside the core task.
pub(crate) type Call<D> = Box<dyn FnOnce(&mut D, crate::Instant) + Send>;

/// Sees every event of the device until it returns true (it got what it waited for).
pub(crate) type Watcher<E> = Box<dyn FnMut(&E) -> bool + Send>;

/// Starts something and returns the watcher that completes it, if it started.
pub(crate) type Start<D, E> = Box<dyn FnOnce(&mut D, crate::Instant) -> Option<Watcher<E>> + Send>;

pub(crate) enum Command<D: Device> {
    Call(Call<D>),
    Watch(Start<D, D::Event>),
    Shutdown,
}

/// Port inputs handled per wake-up before the device's outputs are flushed.
const RX_BATCH: usize = 64;

pub(crate) struct Core<D: Device> {
    pub device: Box<D>,
    pub clock: Clock,
    pub ports: Vec<mpsc::Sender<PortCmd>>,
    pub counters: Vec<PortCounters>,
    pub events: broadcast::Sender<RuntimeEvent<D::Event>>,
    pub tap: Option<Arc<dyn Tap>>,
    pub watchers: Vec<Watcher<D::Event>>,
    /// The latest instant handed to the device: inputs stamped earlier (read before the
    /// device's last call) are handed over at this instant, so that its time never goes back.
    pub last: crate::Instant,
}

impl<D> Core<D>
where
    D: Device + Send + 'static,
    D::Event: Clone + Send + std::fmt::Debug + 'static,
{
    pub async fn run(
        mut self,
        mut commands: mpsc::UnboundedReceiver<Command<D>>,
        mut input: mpsc::Receiver<Arrival>,
    ) {
        tracing::info!(ports = self.ports.len(), "runtime started");
        loop {
            self.flush();
            let deadline = self.device.poll_timeout();
            let sleep = async {
                match deadline {
                    Some(t) => tokio::time::sleep_until(self.clock.to_tokio(t)).await,
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                cmd = commands.recv() => match cmd {
                    Some(Command::Call(f)) => {
                        let now = self.now();
                        f(&mut *self.device, now)
                    }
                    Some(Command::Watch(start)) => {
                        let now = self.now();
                        if let Some(w) = start(&mut *self.device, now) {
                            self.watchers.push(w);
                        }
                    }
                    Some(Command::Shutdown) | None => break,
                },
                first = input.recv() => {
                    if let Some((port, x, at)) = first {
                        self.input(port, x, at);
                        for _ in 1..RX_BATCH {
                            match input.try_recv() {
                                Ok((port, x, at)) => self.input(port, x, at),
                                Err(_) => break,
                            }
                        }
                    }
                },
                () = sleep => {}
            }
            self.timeouts(&mut input);
        }
        tracing::info!("runtime stopped");
    }

    /// Runs the device's timeout if it is due, after the frames that were read before it: a
    /// task that was not scheduled in time finds them queued, and a deadline must not pass for
    /// what had already arrived (an SDO sub-block timer would acknowledge segments that were
    /// waiting). The first input read after the deadline follows the timeout. Bounded: the
    /// queue is.
    fn timeouts(&mut self, input: &mut mpsc::Receiver<Arrival>) {
        let clock = self.clock.now().max(self.last);
        let Some(due) = self.device.poll_timeout().filter(|t| *t <= clock) else {
            return;
        };
        let mut after = None;
        while let Ok((port, x, at)) = input.try_recv() {
            if at > due {
                after = Some((port, x, at));
                break;
            }
            self.input(port, x, at);
        }
        let now = self.now();
        if self.device.poll_timeout().is_some_and(|t| t <= now) {
            self.device.handle_timeout(now);
        }
        if let Some((port, x, at)) = after {
            self.input(port, x, at);
        }
    }

    /// The clock's time, as the device's next instant.
    fn now(&mut self) -> crate::Instant {
        self.at(self.clock.now())
    }

    /// `t`, or the device's last instant if that is later.
    fn at(&mut self, t: crate::Instant) -> crate::Instant {
        self.last = self.last.max(t);
        self.last
    }

    fn input(&mut self, port: usize, x: PortInput, read_at: crate::Instant) {
        let now = self.at(read_at);
        match x {
            PortInput::Frame(f) => {
                if let Some(t) = &self.tap {
                    t.frame(now, TapPoint::Port(port), TapDirection::Rx, &f);
                }
                self.device.handle_rx(now, port, &f);
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

    /// Moves everything the device has to the ports and the subscribers.
    fn flush(&mut self) {
        let now = self.clock.now();
        while let Some((port, f)) = self.device.poll_transmit() {
            let Some(tx) = self.ports.get(port) else {
                tracing::error!(port, "device sent on a port it does not have");
                continue;
            };
            if let Some(t) = &self.tap {
                t.frame(now, TapPoint::Port(port), TapDirection::Tx, &f);
            }
            if tx.try_send(PortCmd::Send(f)).is_err() {
                // The port cannot keep up (or is down): drop rather than stall the device.
                self.counters[port].tx_dropped();
                tracing::debug!(port, frame = %f, "port queue full, frame dropped");
            }
        }
        while let Some((port, req)) = self.device.poll_port_request() {
            if let Some(tx) = self.ports.get(port) {
                tracing::info!(port, ?req, "port request");
                let _ = tx.try_send(PortCmd::Request(req));
            }
        }
        while let Some(e) = self.device.poll_event() {
            tracing::debug!(event = ?e, "event");
            // Watchers see every event, losslessly, before subscribers (who may lag).
            self.watchers.retain_mut(|w| !w(&e));
            // No subscriber is fine: events are then only logged.
            let _ = self.events.send(RuntimeEvent::Device(e));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::PortRequest;
    use crate::{Duration, Frame, Id, Instant};

    /// A timer that each frame pushes back by 10 ms (as an SDO sub-block timer does), and the
    /// order in which it saw frames and its timeout.
    struct Timer {
        deadline: Option<Instant>,
        seen: Vec<String>,
    }

    impl Device for Timer {
        type Event = ();
        fn port_count(&self) -> usize {
            1
        }
        fn handle_rx(&mut self, now: Instant, _: usize, frame: &Frame) {
            self.seen
                .push(format!("frame {} at {now}", frame.data()[0]));
            self.deadline = Some(now + Duration::from_millis(10));
        }
        fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
        fn handle_timeout(&mut self, now: Instant) {
            self.seen.push(format!("timeout at {now}"));
            self.deadline = None;
        }
        fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
            None
        }
        fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
            None
        }
        fn poll_timeout(&self) -> Option<Instant> {
            self.deadline
        }
        fn poll_event(&mut self) -> Option<()> {
            None
        }
    }

    /// The core was not scheduled from 5 ms to 30 ms: a frame read at 8 ms was waiting when it
    /// ran again. It goes first and pushes the deadline back, so no timeout; a frame read at
    /// 25 ms, after the new deadline of 18 ms, comes after that timeout.
    #[tokio::test(start_paused = true)]
    async fn frames_read_before_a_deadline_are_handled_before_it() {
        let clock = crate::runtime::Clock::start();
        let mut core = Core {
            device: Box::new(Timer {
                deadline: Some(Instant::from_millis(10)),
                seen: vec![],
            }),
            clock,
            ports: vec![],
            counters: vec![],
            events: broadcast::channel(4).0,
            tap: None,
            watchers: vec![],
            last: Instant::ZERO,
        };
        let (tx, mut rx) = mpsc::channel(8);
        let frame = |b: u8| PortInput::Frame(Frame::new(Id::Standard(0x100), &[b]).unwrap());
        tx.try_send((0, frame(1), Instant::from_millis(8))).unwrap();
        tx.try_send((0, frame(2), Instant::from_millis(25)))
            .unwrap();
        tokio::time::advance(std::time::Duration::from_millis(30)).await;
        core.timeouts(&mut rx);
        assert_eq!(
            core.device.seen,
            [
                "frame 1 at 0.008000s",
                "timeout at 0.030000s",
                "frame 2 at 0.030000s"
            ]
        );
    }
}
