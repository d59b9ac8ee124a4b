//! The order of frames, deadlines and receive timestamps in the device's state.

use super::*;
use crate::machine::{PortRequest, PortStatus};
use crate::runtime::outbox::move_into;
use crate::{Duration, Frame, Id, Instant};
use tokio::sync::broadcast;

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
    fn handle_rx_at(&mut self, now: Instant, _: usize, frame: &Frame, at: Instant) {
        self.seen
            .push(format!("frame {} at {now} stamped {at}", frame.data()[0]));
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

/// A frame read at 8 ms, before the deadline of 10 ms, goes first and pushes the deadline
/// to 18 ms; a frame read at 25 ms comes after the timeout, which runs at its own 18 ms
/// (not at the 25 ms when the port task found it due), and at 30 ms nothing more is due.
#[tokio::test(start_paused = true)]
async fn a_deadline_falls_between_the_frames_read_before_and_after_it() {
    let mut st = State::new(
        Box::new(Timer {
            deadline: Some(Instant::from_millis(10)),
            seen: vec![],
        }),
        crate::runtime::Clock::start(),
        vec![],
        broadcast::channel(4).0,
        None,
    );
    let frame = |b: u8| PortInput::Frame(Frame::new(Id::Standard(0x100), &[b]).unwrap(), None);
    st.input(0, frame(1), Instant::from_millis(8));
    st.input(0, frame(2), Instant::from_millis(25));
    st.timeouts(Instant::from_millis(30));
    assert_eq!(
        st.device.seen,
        [
            "frame 1 at 0.008000s",
            "timeout at 0.018000s",
            "frame 2 at 0.025000s"
        ]
    );
}

/// A frame with a receive timestamp reaches the device through `handle_rx_at`, the stamp
/// on the runtime's clock (time since the clock started): read 35 ms after it arrived, it
/// keeps its arrival time. A stamp later than the instant it is handled at (a clock the
/// port read after the runtime's) is that instant; a frame without one goes through
/// `handle_rx`.
#[tokio::test(start_paused = true)]
async fn a_stamped_frame_keeps_its_arrival_time() {
    let clock = crate::runtime::Clock::start();
    let origin = tokio::time::Instant::now().into_std();
    let mut st = State::new(
        Box::new(Timer {
            deadline: None,
            seen: vec![],
        }),
        clock,
        vec![],
        broadcast::channel(4).0,
        None,
    );
    let ms = std::time::Duration::from_millis;
    let frame = |b: u8, at| PortInput::Frame(Frame::new(Id::Standard(0x100), &[b]).unwrap(), at);
    st.input(0, frame(1, Some(origin + ms(5))), Instant::from_millis(40));
    st.input(0, frame(2, Some(origin + ms(90))), Instant::from_millis(50));
    st.input(0, frame(3, None), Instant::from_millis(60));
    assert_eq!(
        st.device.seen,
        [
            "frame 1 at 0.040000s stamped 0.005000s",
            "frame 2 at 0.050000s stamped 0.050000s",
            "frame 3 at 0.060000s"
        ]
    );
}

/// A classic command is a classic frame and its tag: the CAN FD frames wait beside the queue.
#[test]
fn a_port_command_is_the_size_of_a_classic_frame() {
    assert!(std::mem::size_of::<PortCmd>() <= std::mem::size_of::<Frame>() + 8);
}

/// A device that speaks CAN FD and yields what it is given, all on port 0.
#[derive(Default)]
struct FdOut {
    classic: Vec<Frame>,
    fd: Vec<crate::FdFrame>,
    reinit: bool,
}

impl Device for FdOut {
    type Event = ();
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {}
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.classic.pop().map(|f| (0, f))
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        std::mem::take(&mut self.reinit).then_some((0, PortRequest::Reinit))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
    fn fd_capable(&self) -> bool {
        true
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, crate::FdFrame)> {
        self.fd.pop().map(|f| (0, f))
    }
}

/// FD frames are queued beside the port's commands and taken with them, in order; a
/// re-initialisation drops them with the classic frames, counted.
#[tokio::test]
async fn fd_frames_move_with_their_commands_and_go_with_a_re_init() {
    let fd = |b: u8| crate::FdFrame::new(Id::Standard(0x200), &[b; 20]).unwrap();
    let counters = crate::port::PortCounters::new();
    let mut st = State::new(
        Box::new(FdOut {
            classic: vec![Frame::from_array(Id::Standard(0x100), [9])],
            fd: vec![fd(2), fd(1)],
            reinit: false,
        }),
        crate::runtime::Clock::start(),
        vec![counters.clone()],
        broadcast::channel(4).0,
        None,
    );
    assert_eq!(st.flush(), 1);
    let mut out = Outbox::new();
    move_into(&mut st.queues[0], &mut st.fd_queues[0], &mut out);
    assert!(matches!(out.pop_front(), Some(PortCmd::Send(f)) if f.data() == [9]));
    for b in [1, 2] {
        assert!(matches!(out.pop_front(), Some(PortCmd::SendFd)));
        assert_eq!(out.pop_fd(), Some(fd(b)));
    }
    assert!(out.is_empty() && st.fd_queues[0].is_empty());

    st.device.fd = vec![fd(4), fd(3)];
    st.device.classic = vec![Frame::from_array(Id::Standard(0x100), [5])];
    st.device.reinit = true;
    st.flush();
    assert!(matches!(
        st.queues[0].iter().collect::<Vec<_>>()[..],
        [PortCmd::Request(PortRequest::Reinit)]
    ));
    assert!(st.fd_queues[0].is_empty());
    assert_eq!(counters.snapshot().tx_dropped, 3);
}
