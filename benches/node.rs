//! Node frame handling: a master consuming heartbeats of 127 producers; cost per heartbeat.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use duocan::od::comm;
use duocan::{Frame, Id, Instant, Machine, Node, NodeConfig, NodeId};
use std::hint::black_box;

fn heartbeat_consumer(c: &mut Criterion) {
    let od = comm::standard_dictionary(1, comm::Identity::default());
    let mut node = Node::new(NodeConfig::master(NodeId::must(1)), od);
    let t0 = Instant::ZERO;
    node.boot(t0);
    for n in 2..=127u32 {
        node.set(t0, comm::HEARTBEAT_CONSUMER, (n - 1) as u8, (n << 16) | 100)
            .expect("consumer entry");
    }
    while node.poll_transmit().is_some() {}
    while node.poll_event().is_some() {}
    let frames: Vec<Frame> = (2..=127u16)
        .map(|n| Frame::from_array(Id::Standard(0x700 + n), [0x05]))
        .collect();
    // Every producer heard once, so each later beat is a state-unchanged heartbeat.
    for f in &frames {
        node.handle_frame(t0, f);
    }
    while node.poll_event().is_some() {}

    let mut g = c.benchmark_group("heartbeat_consumer_127");
    g.throughput(Throughput::Elements(1));
    let mut i = 0usize;
    let mut now = 1_000u64;
    g.bench_function("per_heartbeat", |b| {
        b.iter(|| {
            i = (i + 1) % frames.len();
            now += 1;
            node.handle_frame(Instant::from_micros(now), black_box(&frames[i]));
            black_box(node.poll_timeout())
        })
    });
    g.finish();
}

criterion_group!(benches, heartbeat_consumer);
criterion_main!(benches);
