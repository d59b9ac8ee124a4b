//! The backplane's rules (see its module docs), with probe devices on its two buses.

use super::backplane::{Backplane, BUS_QUEUE, LEAD, TURN_WORK};
use alloc::boxed::Box;
use alloc::vec::Vec;
use duocan::machine::{Device, PortStatus};
use duocan::sim::timing::frame_duration;
use duocan::{Frame, Id, Instant};

const RATE: u32 = 1_000_000;

/// Records what it hears, at which of its own instants; sends what it is given; takes a
/// timeout at `due`.
#[derive(Default)]
struct Probe {
    heard: Vec<(Instant, usize, Frame)>,
    /// The instant of every input, frames and timeouts.
    inputs: Vec<Instant>,
    outbox: Vec<(usize, Frame)>,
    due: Option<Instant>,
    timeouts: Vec<Instant>,
    /// Frames handed over without a receive timestamp, and stamps other than the instant.
    unstamped: usize,
    misstamped: usize,
}

impl Device for Probe {
    type Event = ();
    fn port_count(&self) -> usize {
        2
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.unstamped += 1;
        self.heard.push((now, port, *frame));
        self.inputs.push(now);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.misstamped += usize::from(at != now);
        self.heard.push((now, port, *frame));
        self.inputs.push(now);
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        self.timeouts.push(now);
        self.inputs.push(now);
        self.due = None;
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        (!self.outbox.is_empty()).then(|| self.outbox.remove(0))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        self.due
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

fn frame(n: u8) -> Frame {
    Frame::new(Id::Standard(0x180 + u16::from(n & 0x7F)), &[n; 8]).unwrap()
}

fn probe() -> Box<Probe> {
    Box::default()
}

fn heard(bp: &mut Backplane, tag: u8) -> Vec<(Instant, usize, Frame)> {
    bp.with::<Probe, _>(tag, |p| p.heard.clone()).unwrap()
}

fn out(bp: &mut Backplane) -> Vec<(usize, Frame)> {
    core::iter::from_fn(|| bp.poll_out())
        .map(|(p, f, _)| (p, f))
        .collect()
}

/// A member's frame on both buses takes them at the same instant and reaches every other
/// member on both ports together, and the outside on both; never its sender.
#[test]
fn both_copies_of_a_frame_arrive_together() {
    let mut bp = Backplane::new(RATE);
    bp.power_on(1, probe());
    bp.power_on(2, probe());
    bp.with::<Probe, _>(1, |p| p.outbox = vec![(0, frame(1)), (1, frame(1))]);
    bp.advance(Instant::from_millis(1));
    let t = heard(&mut bp, 2);
    assert_eq!(t.len(), 2, "{t:?}");
    assert_eq!(t[0].0, t[1].0, "the twins at one instant");
    assert_eq!((t[0].1, t[1].1), (0, 1));
    assert!(heard(&mut bp, 1).is_empty(), "not its own frames");
    let stamps = bp.with::<Probe, _>(2, |p| (p.unstamped, p.misstamped));
    assert_eq!(
        stamps,
        Some((0, 0)),
        "stamped with the instant the bus took them"
    );
    assert_eq!(out(&mut bp), [(0, frame(1)), (1, frame(1))]);
}

/// Frames queued at once follow each other a wire time apart (the exact duration of each at
/// the bit rate), in the order sent; a call reaches at most [`LEAD`] ahead of its clock.
#[test]
fn a_burst_takes_the_bus_a_wire_time_apart() {
    let mut bp = Backplane::new(RATE);
    bp.power_on(1, probe());
    bp.power_on(2, probe());
    let burst: Vec<(usize, Frame)> = (0..40).map(|n| (0, frame(n))).collect();
    bp.with::<Probe, _>(1, |p| p.outbox = burst.clone());
    bp.advance(Instant::ZERO);
    let t = heard(&mut bp, 2);
    let mut at = Instant::ZERO;
    for (i, (when, port, f)) in t.iter().enumerate() {
        assert_eq!((*when, *port, *f), (at, 0, frame(i as u8)));
        at += frame_duration(f, RATE);
    }
    // Up to LEAD ahead of the caller's clock, and no further.
    assert!(at <= Instant::ZERO + LEAD + frame_duration(&frame(0), RATE));
    assert!(t.len() < 40 && t.len() >= 10, "{} frames in 2 ms", t.len());
    bp.advance(Instant::from_millis(100));
    assert_eq!(heard(&mut bp, 2).len(), 40);
    // The outside gets each frame stamped with the instant the bus took it, also those carried
    // in a later call than their bus time.
    let mut at = Instant::ZERO;
    let stamped: Vec<_> = core::iter::from_fn(|| bp.poll_out()).collect();
    assert_eq!(stamped.len(), 40);
    for (i, (p, f, wire)) in stamped.into_iter().enumerate() {
        assert_eq!((p, f, wire), (0, frame(i as u8), at));
        at += frame_duration(&f, RATE);
    }
}

/// A frame from outside reaches every member on its bus, once, and is not sent back out.
#[test]
fn a_frame_from_outside_reaches_every_member() {
    let mut bp = Backplane::new(RATE);
    bp.power_on(1, probe());
    bp.power_on(2, probe());
    bp.send(1, frame(9), Instant::from_millis(3));
    bp.send(7, frame(9), Instant::from_millis(3)); // no such bus: ignored
    bp.advance(Instant::from_millis(3));
    for tag in [1, 2] {
        assert_eq!(
            heard(&mut bp, tag),
            [(Instant::from_millis(3), 1, frame(9))]
        );
    }
    assert!(out(&mut bp).is_empty());
}

/// A member powered on later sees its own clock from zero; deadlines and frames reach it in
/// time order, its clock never stepping back, also when it is far behind the caller.
#[test]
fn members_clocks_start_at_power_on_and_never_step_back() {
    let mut bp = Backplane::new(RATE);
    bp.power_on(1, probe());
    bp.advance(Instant::from_millis(10));
    bp.power_on(2, probe());
    bp.with::<Probe, _>(2, |p| p.due = Some(Instant::from_millis(5)));
    bp.send(0, frame(1), Instant::from_millis(10));
    bp.advance(Instant::from_millis(10));
    bp.with::<Probe, _>(1, |p| {
        p.outbox = (0..200).map(|n| (1, frame(n as u8))).collect();
    });
    bp.send(0, frame(2), Instant::from_millis(11));
    // Far behind: each call handles at most TURN_WORK, and the backplane is due at once.
    let mut calls = 0;
    while bp.wake_at().is_some_and(|t| t <= Instant::from_millis(200)) {
        bp.advance(Instant::from_millis(200));
        calls += 1;
        assert!(calls < 100, "it catches up");
    }
    assert!(calls >= 200 / TURN_WORK, "the catch-up took {calls} turns");
    assert!(bp.stats().behind > 0);
    let t = heard(&mut bp, 2);
    assert_eq!(t.len(), 202);
    assert_eq!(
        t[0],
        (Instant::ZERO, 0, frame(1)),
        "its clock starts at power-on"
    );
    let (timeouts, inputs) = bp
        .with::<Probe, _>(2, |p| (p.timeouts.clone(), p.inputs.clone()))
        .unwrap();
    assert_eq!(timeouts, [Instant::from_millis(5)]);
    assert!(inputs.windows(2).all(|w| w[0] <= w[1]), "{inputs:?}");
    assert!(inputs.iter().any(|t| *t > Instant::from_millis(5)));
}

/// What a member queued still goes out after it is powered off; it hears nothing more. A bus
/// queue holds at most [`BUS_QUEUE`] frames, the rest dropped and counted.
#[test]
fn power_off_and_a_full_queue() {
    let mut bp = Backplane::new(RATE);
    bp.power_on(1, probe());
    bp.power_on(2, probe());
    let many: Vec<(usize, Frame)> = (0..BUS_QUEUE + 10).map(|n| (0, frame(n as u8))).collect();
    bp.with::<Probe, _>(1, |p| p.outbox = many);
    bp.send(1, frame(1), Instant::ZERO);
    bp.advance(Instant::ZERO);
    assert_eq!(bp.stats().dropped, 10);
    bp.power_off(1);
    assert!(!bp.is_on(1));
    for ms in 1..=200 {
        bp.advance(Instant::from_millis(ms));
    }
    assert_eq!(heard(&mut bp, 2).len(), BUS_QUEUE + 1);
    bp.power_off(2);
    bp.send(0, frame(3), Instant::from_millis(201));
    bp.advance(Instant::from_millis(300));
    assert_eq!(bp.with::<Probe, _>(2, |p| p.heard.len()), None);
}
