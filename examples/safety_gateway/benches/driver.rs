//! CPU per frame of the gateway's firmware path on the host: the same `Gateway` the image
//! runs (duocan's `EmbeddedDriver` on the interlocking's two buses, the field bus read by the
//! gateway itself), on the in-memory controllers of [`safety_gateway::mock`]. Each iteration
//! is a millisecond of bus time: the interlocking master's heartbeat arrives on both buses and
//! the track-circuit board's SRDO (its four codes plain and inverted) on the field bus (four
//! frames), the gateway polls once (receive, merge, check, mirror, its TPDOs, SRDO and heartbeat
//! when due) and what it sent is drained. The figure is per received frame.
//!
//! ```text
//! cargo bench -p safety-gateway --bench driver
//! ```

#[path = "../tests/harness/mod.rs"]
mod harness;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use duocan::profile::railway::RailwayProfile;
use duocan::profile::IdProfile;
use duocan::{Frame, Instant, NmtState};
use embedded_can::nb::Can;
use harness::{MASTER, NETWORK};
use safety_gateway::mirror::field_pair;
use safety_gateway::mock::{MockCan, Wire};
use safety_gateway::{Gateway, Storage, NODE_ID, TRACKS};
use std::hint::black_box;

/// The gateway, the master's ends of the two buses and the field board's end of the field bus.
struct Rig {
    gw: &'static mut Gateway<MockCan<'static>>,
    buses: [MockCan<'static>; 2],
    field: MockCan<'static>,
    heartbeat: Frame,
    reports: Vec<Frame>,
    now: u64,
}

impl Rig {
    fn new() -> Rig {
        let storage = Box::leak(Box::new(Storage::new()));
        let wires: &'static [Wire; 3] =
            Box::leak(Box::new([Wire::new(), Wire::new(), Wire::new()]));
        let [gw1, m1] = wires[0].ends();
        let [gw2, m2] = wires[1].ends();
        let [gwf, field] = wires[2].ends();
        let gw = storage
            .install(&NETWORK, [gw1, gw2, gwf], Instant::ZERO)
            .expect("install the gateway");
        let profile = RailwayProfile::with(&NETWORK).expect("network table");
        let mut rig = Rig {
            gw,
            buses: [m1, m2],
            field,
            heartbeat: Frame::new(profile.heartbeat(MASTER), &[0x05]).expect("heartbeat"),
            reports: field_pair([0x55; TRACKS as usize]).to_vec(),
            now: 0,
        };
        // NMT start of the gateway from the master, on both buses.
        let start = Frame::new(profile.nmt(), &[0x01, NODE_ID.raw()]).expect("NMT start");
        for bus in &mut rig.buses {
            let _ = bus.transmit(&start);
        }
        rig
    }

    fn step(&mut self) -> Option<Instant> {
        self.now += 1_000;
        for bus in &mut self.buses {
            // A full wire (the gateway not reading) is a dropped frame, as on a bus.
            let _ = bus.transmit(&self.heartbeat);
        }
        for f in &self.reports {
            let _ = self.field.transmit(f);
        }
        let next = self.gw.poll(Instant::from_micros(self.now));
        while self.gw.poll_event().is_some() {}
        for bus in &mut self.buses {
            while bus.receive().is_ok() {}
        }
        next
    }
}

fn gateway_driver(c: &mut Criterion) {
    let mut rig = Rig::new();
    for _ in 0..1_000 {
        rig.step();
    }
    assert_eq!(
        rig.gw.node().nmt_state(),
        NmtState::Operational,
        "the gateway runs"
    );
    let mut g = c.benchmark_group("gateway_driver");
    g.throughput(Throughput::Elements(2 + rig.reports.len() as u64));
    g.bench_function("per_frame", |b| b.iter(|| black_box(rig.step())));
    g.finish();
}

criterion_group!(benches, gateway_driver);
criterion_main!(benches);
