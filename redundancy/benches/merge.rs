//! Merge throughput on one core: the active-active merger with 50/50 duplicates (every
//! occurrence arrives on both ports) and a realistic key spread (110 nodes, four TPDOs with
//! changing data and a heartbeat each), arrivals interleaved with up to 2 ms of inter-bus skew.
//!
//! Target: ≥ 10 million frames/s. For scale, two 1 Mbit/s buses carry at most ~17,600 frames/s
//! together.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use duocan::machine::BusLink;
use duocan::{Duration, Frame, Id, Instant};
use duocan_redundancy::link::merge::{Merger, Verdict};
use duocan_redundancy::{DualBus, DualBusConfig};
use std::hint::black_box;
use std::time::Instant as WallClock;

/// `occurrences` frames, each arriving on both ports: (time µs, port, frame), in time order.
fn traffic(occurrences: usize) -> Vec<(u64, usize, Frame)> {
    let mut rng = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        rng
    };
    let mut v = Vec::with_capacity(occurrences * 2);
    // Two saturated 1 Mbit/s buses: ~8,800 occurrences/s, one every ~113 µs.
    for i in 0..occurrences {
        let t = i as u64 * 113;
        let node = (next() % 110) as u16 + 1;
        let f = match next() % 5 {
            4 => Frame::from_array(Id::Standard(0x700 + node), [5]),
            k => {
                let data = (next() % 4).to_le_bytes(); // values change rarely: many repeats
                Frame::from_array(Id::Standard(0x180 + 0x100 * k as u16 + node), data)
            }
        };
        let skew = next() % 2_000;
        let (first, second) = if next() % 2 == 0 { (0, 1) } else { (1, 0) };
        v.push((t, first, f));
        v.push((t + skew, second, f));
    }
    v.sort_by_key(|x| x.0);
    v
}

fn merge_throughput(c: &mut Criterion) {
    let arrivals = traffic(500_000);
    let mut g = c.benchmark_group("merge");
    g.throughput(Throughput::Elements(arrivals.len() as u64));
    g.bench_function("merger_50_50_duplicates", |b| {
        b.iter(|| {
            let mut m: Merger<1024> = Merger::new(Duration::from_millis(10));
            let mut delivered = 0u32;
            for (t, p, f) in &arrivals {
                if m.arrive(Instant::from_micros(*t), *p, f) == Verdict::Deliver {
                    delivered += 1;
                }
            }
            black_box(delivered)
        })
    });
    g.bench_function("dual_bus_handle_rx", |b| {
        b.iter(|| {
            let mut l = DualBus::new(DualBusConfig::default());
            let mut delivered = 0u32;
            for (t, p, f) in &arrivals {
                if l.handle_rx(Instant::from_micros(*t), *p, f).is_some() {
                    delivered += 1;
                }
            }
            black_box(delivered)
        })
    });
    g.finish();

    // The headline number, printed plainly.
    let mut best = f64::MAX;
    for _ in 0..5 {
        let mut m: Merger<1024> = Merger::new(Duration::from_millis(10));
        let start = WallClock::now();
        let mut delivered = 0u32;
        for (t, p, f) in &arrivals {
            if m.arrive(Instant::from_micros(*t), *p, f) == Verdict::Deliver {
                delivered += 1;
            }
        }
        black_box(delivered);
        assert_eq!(delivered as usize, arrivals.len() / 2, "exactly once");
        best = best.min(start.elapsed().as_secs_f64());
    }
    println!(
        "merger: {:.1} million frames/s on one core ({} arrivals, 50/50 duplicates)",
        arrivals.len() as f64 / best / 1e6,
        arrivals.len()
    );
}

criterion_group!(benches, merge_throughput);
criterion_main!(benches);
