//! PDO cost in the stack itself: building a TPDO from a 5-entry bit-granular mapping, applying
//! an RPDO of the same layout, and a railway-scale master receiving the TPDOs of 108 boards
//! (432 RPDOs). Prints PDOs per second; the requirement is ≥ 100,000 per second on one core.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use duocan::node::ALL_NODES;
use duocan::od::{comm, Access, DataType, DefaultValue, DynamicDictionary, ObjectDef};
use duocan::pdo::params;
use duocan::profile::Predefined;
use duocan::{Frame, Id, Instant, Machine, NmtState, Node, NodeConfig, NodeId};
use std::hint::black_box;

/// 8 + 12 + 20 + 1 + 23 = 64 bits: five entries, three of them straddling byte boundaries.
const MAP: [u32; 5] = [
    0x6000_0008,
    0x6001_000C,
    0x6002_0014,
    0x6003_0001,
    0x6004_0017,
];

fn app(access: Access) -> Vec<ObjectDef> {
    [
        (0x6000, DataType::Unsigned8),
        (0x6001, DataType::Unsigned16),
        (0x6002, DataType::Integer32),
        (0x6003, DataType::Boolean),
        (0x6004, DataType::Unsigned32),
    ]
    .iter()
    .map(|(i, t)| ObjectDef::new(*i, 0, *t).mappable().access(access))
    .collect()
}

/// A slave with TPDO1 (type 254) or RPDO1 (type 255) of the [`MAP`] layout.
fn slave(transmit: bool) -> Node<DynamicDictionary> {
    let mut od = comm::standard_dictionary(5, comm::Identity::default());
    od.insert_all(&app(Access::Rw)).unwrap();
    let cob = params::predefined_tpdo_cob(1);
    if transmit {
        od.insert_all(&params::tpdo_comm(1, cob, 254, 0, 0))
            .unwrap();
        od.insert_all(&params::tpdo_mapping::<9>(1, &MAP)).unwrap();
    } else {
        let cob = params::predefined_rpdo_cob(1);
        od.insert_all(&params::rpdo_comm(1, cob, 255, 0)).unwrap();
        od.insert_all(&params::rpdo_mapping::<9>(1, &MAP)).unwrap();
    }
    let mut n = Node::new(NodeConfig::slave(NodeId::must(5)), od);
    n.boot(Instant::ZERO);
    n.set_nmt_state(Instant::ZERO, NmtState::Operational);
    n.set_rpdo_events(false);
    n.set(Instant::ZERO, 0x6002, 0, -123_456i32).unwrap();
    while n.poll_transmit().is_some() {}
    while n.poll_event().is_some() {}
    n
}

/// TPDO1–4 of 108 boards, each into an RPDO of the master.
const RPDOS: usize = 4 * 108;
/// The master's own TPDOs (the default).
const TPDOS: usize = 4;
type Master = Node<DynamicDictionary, Predefined, ALL_NODES, TPDOS, RPDOS>;

/// A master with 432 RPDOs: TPDO1–4 of boards 1–108, each into four entries of its own.
fn railway_master() -> (Box<Master>, Vec<Frame>) {
    let mut od = comm::standard_dictionary(120, comm::Identity::default());
    let mut frames = vec![];
    for board in 1..=108u32 {
        for k in 0..4u32 {
            let pdo = (board - 1) * 4 + k + 1;
            let index = 0x4000 + pdo as u16;
            let cob = 0x180 + k * 0x100 + board;
            for (sub, t) in [
                (1, DataType::Unsigned16),
                (2, DataType::Unsigned16),
                (3, DataType::Unsigned16),
                (4, DataType::Unsigned16),
            ] {
                od.insert(ObjectDef::new(index, sub, t).mappable()).unwrap();
            }
            od.insert_all(&params::rpdo_comm(
                pdo as u16,
                DefaultValue::Unsigned(cob as u64),
                255,
                0,
            ))
            .unwrap();
            let map: Vec<u32> = (1..=4)
                .map(|s| ((index as u32) << 16) | (s << 8) | 16)
                .collect();
            od.insert_all(&params::rpdo_mapping::<5>(pdo as u16, &map))
                .unwrap();
            frames.push(Frame::from_array(
                Id::Standard(cob as u16),
                [board as u8, k as u8, 1, 2, 3, 4, 5, 6],
            ));
        }
    }
    let mut m = Box::new(Master::with_profile(
        NodeConfig::master(NodeId::must(120)),
        od,
        Predefined,
    ));
    m.boot(Instant::ZERO);
    m.set_rpdo_events(false);
    while m.poll_transmit().is_some() {}
    while m.poll_event().is_some() {}
    assert_eq!(m.rpdo_status(432).map(|s| s.running), Some(true));
    (m, frames)
}

/// PDOs per second from a plain timing loop.
fn rate(n: u64, mut f: impl FnMut(u64)) -> f64 {
    let start = std::time::Instant::now();
    for i in 0..n {
        f(i);
    }
    n as f64 / start.elapsed().as_secs_f64()
}

fn pdo(c: &mut Criterion) {
    let mut tx = slave(true);
    let mut rx = slave(false);
    let frame = Frame::from_array(Id::Standard(0x205), [1, 2, 3, 4, 5, 6, 7, 8]);
    let (mut master, frames) = railway_master();
    let now = Instant::from_millis(1);

    let mut g = c.benchmark_group("pdo");
    g.throughput(Throughput::Elements(1));
    g.bench_function("tpdo_build_5_entries_64_bits", |b| {
        b.iter(|| {
            tx.tpdo_request(now, 1).unwrap();
            black_box(tx.poll_transmit())
        })
    });
    let mut v = 0u16;
    g.bench_function("write_mapped_entry_sends_tpdo", |b| {
        b.iter(|| {
            v = v.wrapping_add(1) & 0x0FFF;
            tx.set(now, 0x6001, 0, black_box(v)).unwrap();
            while tx.poll_event().is_some() {}
            black_box(tx.poll_transmit())
        })
    });
    g.bench_function("rpdo_apply_5_entries_64_bits", |b| {
        b.iter(|| rx.handle_frame(now, black_box(&frame)))
    });
    let mut i = 0usize;
    g.bench_function("master_432_rpdos_per_frame", |b| {
        b.iter(|| {
            i = (i + 1) % frames.len();
            master.handle_frame(now, black_box(&frames[i]))
        })
    });
    g.finish();

    let n = 2_000_000;
    let build = rate(n, |_| {
        let _ = tx.tpdo_request(now, 1);
        black_box(tx.poll_transmit());
    });
    let apply = rate(n, |_| rx.handle_frame(now, black_box(&frame)));
    let railway = rate(n, |i| {
        master.handle_frame(now, black_box(&frames[i as usize % frames.len()]))
    });
    println!(
        "PDOs per second on one core: TPDO build {build:.0}, RPDO apply {apply:.0}, \
         railway master (432 RPDOs) {railway:.0}; required ≥ 100,000"
    );
    assert_eq!(rx.rpdo_status(1).map(|s| s.received > 0), Some(true));
}

criterion_group!(benches, pdo);
criterion_main!(benches);
