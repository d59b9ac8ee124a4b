//! Simulator speed: wall time to simulate a dual-bus network of heartbeat-like producers.
//! Long soaks (an hour of a 40-device network) and the demo depend on this staying fast.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use duocan::machine::{Device, PortStatus};
use duocan::sim::{BusConfig, SimNetwork};
use duocan::{Duration, Frame, Id, Instant};

/// Sends one frame on every port each period and counts what it hears (flat memory).
struct Counter {
    frame: Frame,
    period: Duration,
    next: Instant,
    pending: usize,
    heard: u64,
}

impl Device for Counter {
    type Event = ();
    fn port_count(&self) -> usize {
        2
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {
        self.heard += 1;
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        if now >= self.next {
            self.pending = 2;
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

/// Simulates `span` of `devices` producers at `period`; returns frames on the wires.
fn soak(devices: u16, period: Duration, span: Duration) -> u64 {
    let mut sim = SimNetwork::new(1);
    let b = [
        sim.add_bus(BusConfig::new("can0", 500_000)),
        sim.add_bus(BusConfig::new("can1", 500_000)),
    ];
    for i in 0..devices {
        let c = Counter {
            frame: Frame::from_array(Id::Standard(0x700 + (i % 127) + 1), [5]),
            period,
            next: Instant::from_micros(u64::from(i) * 997 % period.as_micros()),
            pending: 0,
            heard: 0,
        };
        sim.add_device(format!("n{i}"), c, &b)
            .expect("two ports, two buses");
    }
    sim.set_recording(false);
    sim.run_for(span);
    sim.bus_stats(b[0]).attempts + sim.bus_stats(b[1]).attempts
}

fn simulator(c: &mut Criterion) {
    let mut g = c.benchmark_group("sim");
    g.sample_size(10);
    let frames = soak(40, Duration::from_millis(100), Duration::from_secs(60));
    g.throughput(Throughput::Elements(frames));
    g.bench_function("40_devices_100ms_heartbeat_1_simulated_minute", |b| {
        b.iter(|| soak(40, Duration::from_millis(100), Duration::from_secs(60)))
    });
    g.finish();
}

criterion_group!(benches, simulator);
criterion_main!(benches);
