//! What the runtime tests share (`fd.rs`, `shutdown.rs`, `reader_thread.rs`): one one-port test
//! device that keeps what it receives and sends what a command queues, and the waits on it. One
//! device, so that each test says only what its port or traffic does differently.
#![allow(dead_code)]

use duocan::machine::{Device, PortRequest, PortStatus};
use duocan::port::mem::MemBus;
use duocan::port::{AnyInput, Port};
use duocan::runtime::{Handle, Runtime};
use duocan::{FdFrame, Frame, Id, Instant};
use std::collections::VecDeque;
use std::time::Duration;

/// What the device received: a CAN FD frame with its instants, or a classic frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Got {
    Fd {
        frame: FdFrame,
        now: Instant,
        at: Instant,
    },
    Classic(Frame),
}

/// A one-port device that keeps what it receives and sends what it is given; on request it
/// answers frames of one identifier with frames of another, and asks for a re-initialisation.
#[derive(Default)]
pub struct Probe {
    /// Whether it speaks CAN FD.
    pub fd: bool,
    pub got: Vec<Got>,
    pub out: VecDeque<Frame>,
    pub out_fd: VecDeque<FdFrame>,
    /// Set: it asks once for its port to be re-initialised.
    pub reinit: bool,
    /// `(ping, pong)`: every frame of `ping` is answered by one of `pong` with the same data.
    pub echo: Option<(Id, Id)>,
}

impl Probe {
    pub fn new(fd: bool) -> Self {
        Probe {
            fd,
            ..Probe::default()
        }
    }

    /// A classic device answering every `ping` with a `pong` of the same data.
    pub fn echo(ping: u16, pong: u16) -> Self {
        Probe {
            echo: Some((Id::Standard(ping), Id::Standard(pong))),
            ..Probe::default()
        }
    }
}

impl Device for Probe {
    type Event = ();
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, _: Instant, _: usize, frame: &Frame) {
        self.got.push(Got::Classic(*frame));
        if let Some((ping, pong)) = self.echo {
            if frame.id() == ping {
                self.out.push_back(Frame::new(pong, frame.data()).unwrap());
            }
        }
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop_front().map(|f| (0, f))
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
        self.fd
    }
    fn handle_rx_fd(&mut self, now: Instant, _: usize, frame: &FdFrame, at: Instant) {
        self.got.push(Got::Fd {
            frame: *frame,
            now,
            at,
        });
    }
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        self.out_fd.pop_front().map(|f| (0, f))
    }
}

/// `probe` under the runtime, on a port of `bus`.
pub fn on_bus(bus: &MemBus, probe: Probe) -> Handle<Probe> {
    Runtime::new(probe).port(bus.port()).spawn().unwrap()
}

/// Has `h`'s device send `frames`, in order, queued by one command.
pub async fn queue(h: &Handle<Probe>, frames: impl IntoIterator<Item = Frame> + Send + 'static) {
    h.call(move |d, _| d.out.extend(frames)).await.unwrap();
}

/// What `h`'s device has received so far, once it has `n` of it (a test gives up after 5 s).
pub async fn received(h: &Handle<Probe>, n: usize) -> Vec<Got> {
    tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            let got = h.call(|d, _| d.got.clone()).await.unwrap();
            if got.len() >= n {
                return got;
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await
    .expect("the device received too little")
}

/// The next input of a tester's port (a test gives up after 5 s).
pub async fn next(port: &mut impl Port) -> AnyInput {
    tokio::time::timeout(Duration::from_secs(5), port.recv_any())
        .await
        .expect("nothing came")
        .unwrap()
}

/// Nothing more comes to a tester's port within 50 ms.
pub async fn nothing_more(port: &mut impl Port) {
    assert!(
        tokio::time::timeout(Duration::from_millis(50), port.recv_any())
            .await
            .is_err()
    );
}
