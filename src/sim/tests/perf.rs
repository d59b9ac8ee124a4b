//! Wall-clock budget of long runs (ignored by default; run with `--release -- --ignored`).

use super::network;
use crate::frame::{Frame, Id};
use crate::machine::{Device, PortStatus};
use crate::time::{Duration, Instant};

/// Sends a heartbeat-like frame on every port each period and only counts what it hears, so
/// memory stays flat however long the run.
struct Counter {
    ports: usize,
    frame: Frame,
    period: Duration,
    next: Instant,
    pending: usize,
    heard: u64,
}

impl Device for Counter {
    type Event = ();
    fn port_count(&self) -> usize {
        self.ports
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {
        self.heard += 1;
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        if now >= self.next {
            self.pending = self.ports;
            self.next = now + self.period;
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.pending = self.pending.checked_sub(1)?;
        Some((self.pending, self.frame))
    }
    fn poll_timeout(&self) -> Option<Instant> {
        Some(self.next)
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

fn soak(devices: u16, period: Duration, span: Duration) {
    let (mut sim, b) = network(1, 2, 500_000);
    let mut ids = Vec::new();
    for i in 0..devices {
        let c = Counter {
            ports: 2,
            frame: Frame::new(Id::Standard(0x700 + (i % 127) + 1), &[5]).unwrap(),
            period,
            next: Instant::from_micros(u64::from(i) * 997 % period.as_micros()),
            pending: 0,
            heard: 0,
        };
        ids.push(sim.add_device(format!("n{i}"), c, &[b[0], b[1]]).unwrap());
    }
    sim.set_recording(false);
    let wall = std::time::Instant::now();
    sim.run_for(span);
    let frames = sim.bus_stats(b[0]).attempts + sim.bus_stats(b[1]).attempts;
    let heard: u64 = ids.iter().map(|&id| sim.device(id).heard).sum();
    println!(
        "{devices} devices, {span}: {frames} frames, {heard} deliveries, load {:.2}, {:?} wall",
        sim.bus_load(b[0]),
        wall.elapsed()
    );
}

#[test]
#[ignore]
fn soak_40_devices_for_an_hour() {
    soak(40, Duration::from_millis(100), Duration::from_secs(3600));
}

#[test]
#[ignore]
fn demo_450_devices_for_a_minute() {
    soak(450, Duration::from_secs(1), Duration::from_secs(60));
}
