//! The supervisor at railway scale: 4 dual-bus networks × 54 board pairs (108 boards each) with a
//! 10 ms heartbeat on both buses, fed to 4 master stations (dual-bus layer + CiA 302-2 master +
//! supervisor, active, every pair joined). One simulated second is 86,400 port arrivals.
//!
//! Target: one simulated second in ≤ 10 ms of CPU on one core (≥ 100× real time).

use criterion::{criterion_group, criterion_main, Criterion};
use duocan::master::{objects, Master, MasterConfig};
use duocan::od::comm;
use duocan::{Device, Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::PairSpec;
use duocan_redundancy::{
    DualBus, DualBusConfig, LinkMode, RedundantMaster, SupervisedStation, Supervisor,
    SupervisorConfig,
};
use std::hint::black_box;
use std::time::Instant as WallClock;

const NETWORKS: usize = 4;
const PAIRS: u8 = 54;
const HB: Duration = Duration::from_millis(10);

type Station = RedundantMaster;

fn board(i: u8) -> u8 {
    // A boards 2..=55, B boards 66..=119.
    if i < PAIRS {
        2 + i
    } else {
        66 + (i - PAIRS)
    }
}

fn master() -> Station {
    let od = objects::master_dictionary(1, comm::Identity::default());
    let master = Master::new(NodeId::must(1), od, MasterConfig::new()).unwrap();
    let mut cfg = SupervisorConfig::new(
        0,
        NodeId::must(1),
        Duration::from_millis(20),
        Duration::from_millis(50),
        Duration::from_millis(10),
    )
    .with_peer(1, NodeId::must(127));
    cfg.pairs.holdoff = Duration::from_millis(20);
    let mut sup = Supervisor::new(master, cfg, Instant::ZERO);
    for i in 0..PAIRS {
        sup.add_pair(
            Instant::ZERO,
            PairSpec::new(
                NodeId::must(board(i)),
                NodeId::must(board(i + PAIRS)),
                HB,
                Duration::from_millis(25),
            ),
        )
        .unwrap();
    }
    let link = DualBus::new(DualBusConfig::with_guard_period(LinkMode::ActiveActive, HB));
    SupervisedStation::new(link, sup).unwrap()
}

/// Heartbeats of the 108 boards from `from` for `len`, staggered over the period, the bus-2 copy
/// 40 µs after the bus-1 copy: (µs, port, frame), in time order.
fn heartbeats(from: Instant, len: Duration, state: impl Fn(u8) -> u8) -> Vec<(u64, usize, Frame)> {
    let mut v = vec![];
    let step = HB.as_micros() / 108;
    let mut t = from.as_micros();
    while t < from.as_micros() + len.as_micros() {
        for i in 0..108u8 {
            let id = board(i);
            let f = Frame::from_array(Id::Standard(0x700 + id as u16), [state(i)]);
            let at = t + i as u64 * step;
            v.push((at, 0, f));
            v.push((at + 40, 1, f));
        }
        t += HB.as_micros();
    }
    v.sort_by_key(|x| x.0);
    v
}

/// The slave's answer to an expedited SDO request of the master's boot process: an upload
/// (identity check) gets 0 (nothing is checked), a download is confirmed.
fn sdo_answer(f: &Frame) -> Frame {
    let d = f.data();
    let head = if d[0] & 0xE0 == 0x40 { 0x43 } else { 0x60 };
    Frame::from_array(
        Id::Standard(f.id().raw() as u16 - 0x80),
        [head, d[1], d[2], d[3], 0, 0, 0, 0],
    )
}

/// Drives a station with `arrivals`, running its timeouts on time and answering its SDO
/// requests once (the slaves' side of the boot process; the station sends every frame on both
/// ports). Returns frames sent.
fn drive(m: &mut Station, arrivals: &[(u64, usize, Frame)], answer_sdo: bool) -> u64 {
    let mut sent = 0u64;
    let mut answers: Vec<Frame> = vec![];
    for (t, p, f) in arrivals {
        let now = Instant::from_micros(*t);
        while let Some(d) = m.poll_timeout().filter(|d| *d <= now) {
            m.handle_timeout(d);
            while let Some((port, f)) = m.poll_transmit() {
                sent += 1;
                if answer_sdo && port == 0 && (0x601..=0x67F).contains(&f.id().raw()) {
                    answers.push(sdo_answer(&f));
                }
            }
            while m.poll_event().is_some() {}
        }
        m.handle_rx(now, *p, f);
        for a in answers.drain(..) {
            m.handle_rx(now, 0, &a);
        }
        while let Some((port, f)) = m.poll_transmit() {
            sent += 1;
            if answer_sdo && port == 0 && (0x601..=0x67F).contains(&f.id().raw()) {
                answers.push(sdo_answer(&f));
            }
        }
        while m.poll_event().is_some() {}
    }
    sent
}

/// Four active masters with every pair joined (A active), at 2 s.
fn warm() -> Vec<Station> {
    // Boards already running: adopted and configured, the A boards started.
    let warmup = heartbeats(Instant::ZERO, Duration::from_millis(2000), |i| {
        if i < PAIRS {
            0x05
        } else {
            0x7F
        }
    });
    (0..NETWORKS)
        .map(|_| {
            let mut m = master();
            drive(&mut m, &warmup, true);
            assert!(m.sup().is_active());
            assert!(m
                .sup()
                .pairs()
                .all(|(_, p)| p.active.is_some() && p.members.iter().all(|s| s.joined())));
            m
        })
        .collect()
}

fn supervisor_scale(c: &mut Criterion) {
    let second = heartbeats(Instant::from_millis(2000), Duration::from_secs(1), |i| {
        if i < PAIRS {
            0x05
        } else {
            0x7F
        }
    });
    assert_eq!(second.len(), 2 * 108 * 100);
    let mut g = c.benchmark_group("supervisor");
    g.sample_size(10);
    g.bench_function("railway_4x54_pairs_one_simulated_second", |b| {
        b.iter_custom(|iters| {
            let mut total = std::time::Duration::ZERO;
            for _ in 0..iters {
                let mut ms = warm();
                let start = WallClock::now();
                for m in ms.iter_mut() {
                    black_box(drive(m, &second, false));
                }
                total += start.elapsed();
            }
            total
        })
    });
    g.finish();

    let mut best = f64::MAX;
    for _ in 0..5 {
        let mut ms = warm();
        let start = WallClock::now();
        for m in ms.iter_mut() {
            black_box(drive(m, &second, false));
        }
        best = best.min(start.elapsed().as_secs_f64());
        for m in &ms {
            assert!(m
                .sup()
                .pairs()
                .all(|(_, p)| p.active == Some(duocan_redundancy::Member::A)));
        }
    }
    println!(
        "supervisor: one simulated second of 4 × 108 boards at 10 ms on both buses \
         ({} arrivals) in {:.2} ms: {:.0}× real time",
        NETWORKS * second.len(),
        best * 1e3,
        1.0 / best
    );
}

criterion_group!(benches, supervisor_scale);
criterion_main!(benches);
