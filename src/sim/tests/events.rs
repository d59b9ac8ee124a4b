//! The device event log: bounded while recording is off, complete while it is on.

use super::network;
use crate::frame::instant::{Duration, Instant};
use crate::frame::{Frame, Id};
use crate::machine::{Device, PortStatus};
use crate::sim::{BusId, DevId, SimNetwork, DEFAULT_EVENT_CAPACITY};

/// Sends one frame every `period` and reports every frame it hears; keeps nothing itself.
struct Chatter {
    id: u16,
    period: Duration,
    next: Instant,
    out: Option<Frame>,
    heard: u32,
    pending: u32,
}

impl Chatter {
    fn new(id: u16, period: Duration) -> Self {
        Chatter {
            id,
            period,
            next: Instant::ZERO,
            out: None,
            heard: 0,
            pending: 0,
        }
    }
}

impl Device for Chatter {
    type Event = u32;
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {
        self.heard += 1;
        self.pending += 1;
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        while self.next <= now {
            self.out = Some(Frame::from_array(Id::Standard(self.id), [1, 2]));
            self.next += self.period;
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.take().map(|f| (0, f))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        Some(self.next)
    }
    fn poll_event(&mut self) -> Option<u32> {
        if self.pending == 0 {
            return None;
        }
        self.pending -= 1;
        Some(self.heard - self.pending)
    }
}

/// A talker sending every `period` and a listener (which sends once an hour) on `bus`.
fn talker_and_listener(sim: &mut SimNetwork, bus: BusId, period: Duration) -> DevId<Chatter> {
    sim.add_device("talker", Chatter::new(0x181, period), &[bus])
        .unwrap();
    let hourly = Chatter::new(0x182, Duration::from_secs(3600));
    sim.add_device("listener", hourly, &[bus]).unwrap()
}

/// An hour of a frame every 10 ms with recording off: the listener's log stops at its capacity,
/// everything past it is counted, and taking the events makes room again.
#[test]
fn an_hour_without_recording_keeps_the_event_log_bounded() {
    let (mut sim, b) = network(3, 1, 500_000);
    sim.set_recording(false);
    let l = talker_and_listener(&mut sim, b[0], Duration::from_millis(10));
    let mut longest = 0;
    for minute in 1..=60 {
        sim.run_until(Instant::from_secs(60 * minute));
        longest = longest.max(sim.events(l).len());
    }
    let heard = u64::from(sim.device(l).heard);
    // Sent at 0, 10 ms, …, 3599.99 s; the one sent at 3600 s is still on the wire.
    assert_eq!(heard, 360_000);
    assert_eq!(longest, DEFAULT_EVENT_CAPACITY);
    assert_eq!(sim.events(l).len(), DEFAULT_EVENT_CAPACITY);
    // The first events are the ones kept, in order.
    assert_eq!(sim.events(l)[0].1, 1);
    assert_eq!(
        sim.events(l).last().unwrap().1 as usize,
        DEFAULT_EVENT_CAPACITY
    );
    assert_eq!(sim.events_dropped(l), heard - DEFAULT_EVENT_CAPACITY as u64);
    assert!(sim.trace().is_empty());

    // A consumer that keeps up loses nothing: take, run, take.
    let dropped = sim.events_dropped(l);
    assert_eq!(sim.take_events(l).len(), DEFAULT_EVENT_CAPACITY);
    sim.set_event_capacity(100);
    sim.run_until(Instant::from_secs(3600) + Duration::from_millis(985));
    assert_eq!(sim.events(l).len(), 99);
    sim.run_until(Instant::from_secs(3601));
    assert_eq!(sim.events(l).len(), 100);
    assert_eq!(sim.events_dropped(l), dropped);
    sim.run_until(Instant::from_secs(3601) + Duration::from_millis(5));
    assert_eq!(sim.events(l).len(), 100);
    assert_eq!(sim.events_dropped(l), dropped + 1);
}

/// Recording on: every event is kept, nothing is dropped.
#[test]
fn recording_keeps_every_event() {
    let (mut sim, b) = network(4, 1, 500_000);
    sim.set_event_capacity(10);
    let l = talker_and_listener(&mut sim, b[0], Duration::from_millis(1));
    sim.run_until(Instant::from_millis(100));
    // Sent at 0, 1 ms, …, 99 ms: all delivered and kept past the capacity of 10.
    assert_eq!(sim.events(l).len(), 100);
    assert_eq!(sim.events_dropped(l), 0);
}
