//! A port task's sends against its port's re-initialisation and failure.

use super::*;
use crate::frame::Frame;
use crate::port::{PortCounters, PortError};
use crate::{Id, Instant};

/// A port whose interface is down (`dead`: every send and re-open fails), or whose bus
/// takes no frames (a send waits for room forever, re-opening works); nothing arrives.
struct TestPort {
    counters: PortCounters,
    dead: bool,
}

impl TestPort {
    fn down(&self, what: &str) -> PortError {
        PortError::new("test0", PortErrorKind::InterfaceDown, what)
    }
}

impl Port for TestPort {
    fn name(&self) -> &str {
        "test0"
    }
    fn counters(&self) -> PortCounters {
        self.counters.clone()
    }
    async fn recv(&mut self) -> Result<PortInput, PortError> {
        std::future::pending().await
    }
    async fn send(&mut self, _: &Frame) -> Result<(), PortError> {
        if self.dead {
            return Err(self.down("send"));
        }
        std::future::pending().await
    }
    async fn reopen(&mut self) -> Result<(), PortError> {
        if self.dead {
            return Err(self.down("reopen"));
        }
        self.counters.reopened();
        Ok(())
    }
}

/// The device's side, as the port task sees it: what is queued for the port, and what the
/// port handed over.
struct FakeHub {
    queue: std::sync::Mutex<std::collections::VecDeque<PortCmd>>,
    inputs: tokio::sync::mpsc::UnboundedSender<(usize, PortInput, Instant)>,
}

impl Hub for FakeHub {
    fn input(&self, port: usize, x: PortInput, at: Instant) -> bool {
        self.inputs.send((port, x, at)).is_ok()
    }
    fn take(&self, _: usize, into: &mut Outbox) -> bool {
        let mut no_fd = std::collections::VecDeque::new();
        super::super::outbox::move_into(&mut self.queue.lock().unwrap(), &mut no_fd, into);
        true
    }
    fn input_fd(
        &self,
        _: usize,
        _: &crate::FdFrame,
        _: Option<std::time::Instant>,
        _: Instant,
    ) -> bool {
        unreachable!("the test port is classic")
    }
    fn finished(&self, _: usize) {}
    fn take_frames(&self, _: usize, _: &mut Outbox) -> Option<bool> {
        unreachable!("the test port has no reader thread")
    }
    fn input_take(&self, _: usize, _: PortInput, _: Instant, _: &mut Outbox) -> Option<bool> {
        unreachable!("the test port has no reader thread")
    }
    fn is_open(&self) -> bool {
        true
    }
    fn reinit_queued(&self, _: usize) -> bool {
        self.queue
            .lock()
            .unwrap()
            .iter()
            .any(|c| matches!(c, PortCmd::Request(PortRequest::Reinit)))
    }
}

/// A port task running `port` as port `index`, its queue and what it hands over.
struct Rig {
    hub: Arc<FakeHub>,
    wake: Arc<Notify>,
    inputs: tokio::sync::mpsc::UnboundedReceiver<(usize, PortInput, Instant)>,
}

impl Rig {
    fn start(port: TestPort, index: usize) -> Rig {
        let (to_test, inputs) = tokio::sync::mpsc::unbounded_channel();
        let hub = Arc::new(FakeHub {
            queue: Default::default(),
            inputs: to_test,
        });
        let wake = Arc::new(Notify::new());
        let wiring = Wiring {
            index,
            net: "test".into(),
            clock: super::super::Clock::start(),
            fd: false,
            hub: hub.clone(),
            wake: wake.clone(),
        };
        tokio::spawn(run(port, wiring));
        Rig { hub, wake, inputs }
    }
    fn queue(&self, c: PortCmd) {
        self.hub.queue.lock().unwrap().push_back(c);
        self.wake.notify_one();
    }
}

/// A re-initialisation the device asks for while a send waits for room is not queued
/// behind it: the send is given up (counted as dropped) and the port re-opened.
#[tokio::test]
async fn a_re_init_request_gives_up_a_send_that_waits_for_room() {
    let counters = PortCounters::new();
    let port = TestPort {
        counters: counters.clone(),
        dead: false,
    };
    let mut rig = Rig::start(port, 0);
    rig.queue(PortCmd::Send(Frame::from_array(Id::Standard(0x181), [1])));
    // The task has taken the frame and waits in its send.
    while !rig.hub.queue.lock().unwrap().is_empty() {
        tokio::task::yield_now().await;
    }
    // Something else queued does not end the wait; the re-initialisation does.
    rig.queue(PortCmd::Send(Frame::from_array(Id::Standard(0x182), [2])));
    tokio::task::yield_now().await;
    let dropped = counters.snapshot().tx_dropped;
    assert_eq!(dropped, 0, "waits while no re-init is queued");
    rig.hub.queue.lock().unwrap().clear();
    rig.queue(PortCmd::Request(PortRequest::Reinit));
    let up = tokio::time::timeout(std::time::Duration::from_secs(5), rig.inputs.recv()).await;
    assert!(
        matches!(up, Ok(Some((0, PortInput::Status(PortStatus::Up), _)))),
        "re-opened: {up:?}"
    );
    let c = counters.snapshot();
    assert_eq!((c.tx_dropped, c.reopened), (1, 1));
}

#[tokio::test]
async fn a_re_init_request_while_the_port_is_down_is_answered_with_down() {
    let port = TestPort {
        counters: PortCounters::new(),
        dead: true,
    };
    let mut rig = Rig::start(port, 1);
    rig.queue(PortCmd::Send(Frame::from_array(Id::Standard(0x705), [5])));
    let down = |x: Option<(usize, PortInput, Instant)>| {
        matches!(
            x,
            Some((1, PortInput::Status(PortStatus::Down(ErrorCause::InterfaceDown)), at))
                if at >= Instant::ZERO
        )
    };
    assert!(
        down(rig.inputs.recv().await),
        "the failed send reports the port down"
    );
    // While it keeps trying to re-open, the device asks for a re-initialisation: it hears
    // at once that the port is still down (not silence, which it would take for success).
    rig.queue(PortCmd::Request(PortRequest::Reinit));
    assert!(down(rig.inputs.recv().await));
}
