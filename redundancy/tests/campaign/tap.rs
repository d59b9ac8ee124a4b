//! What the oracle needs to know of every device: which logical frame each copy it put on a
//! port belongs to, and which copies its stack got.
//!
//! [`Tap`] wraps a device's dual-bus layer. A frame the stack sends is one *occurrence*; the
//! layer numbers its logical frames and every copy it hands a port carries its frame's number
//! (`DualBus::poll_numbered`: a copy held back by a port's pending re-initialisation comes out
//! later, the number says whose it is). The tap hands the copies to the simulator in order,
//! which numbers them again in the same order (the serial of `duocan::sim::RxNote`). On the
//! receiving side, the simulator's receive hook tells the oracle which copy is being handed
//! over just before the device gets it, and the tap tells it whether the link delivered it.

use crate::oracle::Oracle;
use duocan::machine::{BusLink, LinkRequest, PortRequest, PortStatus};
use duocan::{Frame, Instant};
use duocan_redundancy::DualBus;
use std::cell::RefCell;
use std::rc::Rc;

/// Occurrences remembered by the layer's frame number (a copy held back that long is the
/// link's own as far as the oracle knows).
const NUMBERS: usize = 4096;

/// A frame handed over this long after its receive stamp came late (a port's receive lag).
const LATE: duocan::Duration = duocan::Duration::from_millis(1);

/// A layer that reports to the oracle (`node` is the device's index in the oracle).
pub struct Tap {
    pub inner: DualBus,
    pub node: usize,
    oracle: Rc<RefCell<Oracle>>,
    /// The occurrence of each recent frame number.
    occurrence: Vec<Option<(u32, u64)>>,
    now: Instant,
    /// When its layer's lag correction last changed.
    corrected: Option<Instant>,
}

impl Tap {
    pub fn new(inner: DualBus, node: usize, oracle: Rc<RefCell<Oracle>>) -> Self {
        Tap {
            inner,
            node,
            oracle,
            occurrence: vec![None; NUMBERS],
            now: Instant::ZERO,
            corrected: None,
        }
    }
    /// `CAMPAIGN_TRACE=name,id` (`s0x7a,80`; `*` for every identifier): every copy of that
    /// identifier the device named so gets, and whether its link delivered it, on stderr.
    fn trace(&self, now: Instant, port: usize, frame: &Frame, at: Instant, delivered: bool) {
        let Some((name, id)) = trace() else {
            return;
        };
        let o = self.oracle.borrow();
        if o.nodes[self.node].name == name
            && (id == "*"
                || u16::from_str_radix(id, 16).is_ok_and(|i| frame.id() == duocan::Id::Standard(i)))
        {
            let stats = self.inner.merger().stats();
            eprintln!(
                "{now} {name} p{port} stamped {at} {frame:?} delivered {delivered} states {:?} lag {:?}/{:?} {stats:?}",
                [0, 1].map(|p| self.inner.health().port(p).state()),
                self.inner.lag().lag(0),
                self.inner.lag().lag(1),
            );
        }
    }
    fn delivered(&self, now: Instant, f: Option<Frame>) -> Option<Frame> {
        let mut o = self.oracle.borrow_mut();
        o.handled(self.node, now);
        match &f {
            Some(f) => o.delivered(self.node, now, f),
            None => o.not_delivered(self.node, now),
        }
        f
    }
}

impl BusLink for Tap {
    type Event = <DualBus as BusLink>::Event;
    type Command = <DualBus as BusLink>::Command;
    fn port_count(&self) -> usize {
        self.inner.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) -> Option<Frame> {
        self.now = now;
        let f = self.inner.handle_rx(now, port, frame);
        self.delivered(now, f)
    }
    fn handle_rx_at(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        at: Instant,
    ) -> Option<Frame> {
        self.now = now;
        if now.saturating_since(at) > LATE {
            self.oracle.borrow_mut().late(self.node, port, now);
        }
        // The lags the layer had measured when the copy came (the one that measures a lag is
        // delivered before it corrects it).
        let lag = |l: &DualBus, p: usize| l.lag().lag(p).as_micros() as i64;
        let lags = [lag(&self.inner, 0), lag(&self.inner, 1)];
        let f = self.inner.handle_rx_at(now, port, frame, at);
        if lags != [lag(&self.inner, 0), lag(&self.inner, 1)] {
            self.corrected = Some(now);
        }
        if f.is_some() {
            // The records made before a correction changed keep their stamps: a run of
            // identical frames right after it still meets them (for up to a window).
            let settling = self
                .corrected
                .is_some_and(|c| now.saturating_since(c) < crate::oracle::SKEW_WINDOW);
            let mut o = self.oracle.borrow_mut();
            o.unmeasured(self.node, now, lags, settling);
        }
        self.trace(now, port, frame, at, f.is_some());
        self.delivered(now, f)
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.now = now;
        self.inner.handle_port_status(now, port, status);
    }
    fn send(&mut self, now: Instant, frame: &Frame) {
        self.now = now;
        let of = self.oracle.borrow_mut().sent(self.node, now, frame);
        self.inner.send(now, frame);
        let n = self.inner.frame_number();
        self.occurrence[n as usize % NUMBERS] = Some((n, of));
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        let (p, f, n) = self.inner.poll_numbered()?;
        if let Some((name, id)) = trace() {
            if self.oracle.borrow().nodes[self.node].name == name
                && u16::from_str_radix(id, 16).is_ok_and(|i| f.id() == duocan::Id::Standard(i))
            {
                eprintln!("{} {name} tx p{p} #{n} {f:?}", self.now);
            }
        }
        let of = self.occurrence[n as usize % NUMBERS]
            .filter(|o| o.0 == n)
            .map(|o| o.1);
        self.oracle.borrow_mut().copy(self.node, of, p);
        Some((p, f))
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.inner.poll_port_request()
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        self.inner.handle_timeout(now);
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.inner.poll_timeout()
    }
    fn poll_event(&mut self) -> Option<Self::Event> {
        self.inner.poll_event()
    }
    fn poll_machine_request(&mut self) -> Option<LinkRequest> {
        self.inner.poll_machine_request()
    }
    fn handle_command(&mut self, now: Instant, cmd: Self::Command) {
        self.inner.handle_command(now, cmd);
    }
}

/// `CAMPAIGN_TRACE=name,id`: the device and identifier to trace.
fn trace() -> Option<(&'static str, &'static str)> {
    static TRACE: std::sync::OnceLock<Option<(String, String)>> = std::sync::OnceLock::new();
    TRACE
        .get_or_init(|| {
            let v = std::env::var("CAMPAIGN_TRACE").ok()?;
            let (a, b) = v.split_once(',')?;
            Some((a.into(), b.into()))
        })
        .as_ref()
        .map(|(a, b)| (a.as_str(), b.as_str()))
}
