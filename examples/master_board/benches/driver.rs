//! CPU per frame of the master's firmware path on the host: the same station the image runs,
//! under duocan's `EmbeddedDriver` on two in-memory `embedded-can` controllers
//! (`safety_gateway::mock`, made for driving any `EmbeddedDriver` off the board). Each
//! iteration is a millisecond of bus time: the six pair members' heartbeats arrive on both
//! buses (twelve frames, merged into six), the board polls once (receive, merge, supervise,
//! its own heartbeat, SYNC and boot processes when due, transmit) and what it sent is drained.
//! The figure is per received frame.
//!
//! ```text
//! cargo bench -p master-board --bench driver
//! ```

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use duocan::{Frame, Id, Instant};
use embedded_can::nb::Can;
use master_board::dictionary::Od;
use master_board::{build, Computer, MasterBoard, PAIRS};
use safety_gateway::mock::{MockCan, Wire};
use std::hint::black_box;

fn master_driver(c: &mut Criterion) {
    let od: &'static mut Od = Box::leak(Box::new(Od::new()));
    let station = Box::leak(Box::new(
        build(Computer::One, od, Instant::ZERO).expect("the board's station builds"),
    ));
    let wires: &'static [Wire; 2] = Box::leak(Box::new([Wire::new(), Wire::new()]));
    let [board1, mut peer1] = wires[0].ends();
    let [board2, mut peer2] = wires[1].ends();
    let mut board = MasterBoard::new(station, [board1, board2]);
    let beats: Vec<Frame> = PAIRS
        .iter()
        .flat_map(|(a, b)| [a, b])
        .map(|n| Frame::from_array(Id::Standard(0x700 + u16::from(n.raw())), [0x7F]))
        .collect();
    let mut now = 0u64;
    let mut step = |board: &mut MasterBoard<MockCan<'static>>| {
        now += 1_000;
        for f in &beats {
            // A full wire (the board not reading) is a dropped frame, as on a bus.
            let _ = peer1.transmit(f);
            let _ = peer2.transmit(f);
        }
        let next = board.poll(Instant::from_micros(now));
        while peer1.receive().is_ok() {}
        while peer2.receive().is_ok() {}
        next
    };
    // Past the negotiation and the first boot attempts: the board is the active master.
    for _ in 0..2_000 {
        step(&mut board);
    }
    assert!(board.indication().active, "the board is the active master");
    let mut g = c.benchmark_group("master_driver");
    g.throughput(Throughput::Elements(2 * beats.len() as u64));
    g.bench_function("per_frame", |b| b.iter(|| black_box(step(&mut board))));
    g.finish();
}

criterion_group!(benches, master_driver);
criterion_main!(benches);
