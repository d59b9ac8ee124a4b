//! A configurable test device: sends periodically or on demand, records everything it is told.

use crate::frame::instant::{Duration, Instant};
use crate::frame::{Frame, Id};
use crate::machine::{Device, PortRequest, PortStatus};
use std::collections::VecDeque;

/// What a probe reports to its event log.
#[derive(Clone, Debug, PartialEq)]
pub enum ProbeEvent {
    Rx(usize, Frame),
    Status(usize, PortStatus),
}

struct Periodic {
    port: usize,
    frame: Frame,
    next: Instant,
    period: Duration,
}

pub struct Probe {
    ports: usize,
    out: VecDeque<(usize, Frame)>,
    requests: VecDeque<(usize, PortRequest)>,
    periodic: Vec<Periodic>,
    events: VecDeque<ProbeEvent>,
    /// Answer every received frame with this identifier on the same port.
    echo: Option<Id>,
    pub rx: Vec<(Instant, usize, Frame)>,
    /// The receive timestamp of each frame in `rx`.
    pub stamps: Vec<Instant>,
    pub status: Vec<(Instant, usize, PortStatus)>,
    pub timeouts: Vec<Instant>,
}

pub fn std_frame(id: u16, data: &[u8]) -> Frame {
    Frame::new(Id::Standard(id), data).unwrap()
}

impl Probe {
    pub fn new(ports: usize) -> Self {
        Probe {
            ports,
            out: VecDeque::new(),
            requests: VecDeque::new(),
            periodic: Vec::new(),
            events: VecDeque::new(),
            echo: None,
            rx: Vec::new(),
            stamps: Vec::new(),
            status: Vec::new(),
            timeouts: Vec::new(),
        }
    }
    /// Sends `frame` on `port` at `first`, then every `period`.
    pub fn every(mut self, port: usize, frame: Frame, first: Instant, period: Duration) -> Self {
        self.periodic.push(Periodic {
            port,
            frame,
            next: first,
            period,
        });
        self
    }
    pub fn echo(mut self, id: Id) -> Self {
        self.echo = Some(id);
        self
    }
    pub fn send(&mut self, port: usize, frame: Frame) {
        self.out.push_back((port, frame));
    }
    pub fn request(&mut self, port: usize, req: PortRequest) {
        self.requests.push_back((port, req));
    }
    pub fn rx_on(&self, port: usize) -> Vec<(Instant, Frame)> {
        self.rx
            .iter()
            .filter(|(_, p, _)| *p == port)
            .map(|(t, _, f)| (*t, *f))
            .collect()
    }
    pub fn status_on(&self, port: usize) -> Vec<(Instant, PortStatus)> {
        self.status
            .iter()
            .filter(|(_, p, _)| *p == port)
            .map(|(t, _, s)| (*t, *s))
            .collect()
    }
}

impl Device for Probe {
    type Event = ProbeEvent;
    fn port_count(&self) -> usize {
        self.ports
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.handle_rx(now, port, frame);
        self.stamps.push(at);
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.rx.push((now, port, *frame));
        self.events.push_back(ProbeEvent::Rx(port, *frame));
        if let Some(id) = self.echo {
            self.out
                .push_back((port, Frame::new(id, frame.data()).unwrap()));
        }
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.status.push((now, port, status));
        self.events.push_back(ProbeEvent::Status(port, status));
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.timeouts.push(now);
        for p in &mut self.periodic {
            while p.next <= now {
                self.out.push_back((p.port, p.frame));
                p.next += p.period;
            }
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop_front()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.requests.pop_front()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.periodic.iter().map(|p| p.next).min()
    }
    fn poll_event(&mut self) -> Option<ProbeEvent> {
        self.events.pop_front()
    }
}
