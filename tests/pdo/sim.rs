//! PDO timing on the simulated bus (real frame durations, arbitration): inhibit time never
//! violated, event timer period exact, every n-th SYNC exact over 1,000 SYNCs, SYNC start value
//! honoured, synchronous RPDOs applied at the next SYNC.

use duocan::machine::{SinglePort, StationEvent};
use duocan::node::NodeEventKind;
use duocan::od::{comm, Access, DefaultValue, DynamicDictionary, ObjectDef, ObjectDictionary};
use duocan::pdo::{params, PdoEvent};
use duocan::sim::{BusConfig, DevId, FaultRates, SimNetwork, TraceRecord, TxOutcome};
use duocan::{Duration, Frame, Id, Instant, Node, NodeConfig, NodeId, Station};

type Dev = Station<SinglePort, Node<DynamicDictionary>>;

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}
fn us(v: u64) -> Instant {
    Instant::from_micros(v)
}

/// A node that starts itself (so PDOs run from boot), with extra dictionary tables.
fn station(id: u8, tables: &[&[ObjectDef]]) -> Dev {
    let nid = NodeId::must(id);
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    od.insert_all(&[
        ObjectDef::u8(0x6000, 0, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x6001, 0, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x2000, 0, Access::Rw, 0).mappable(),
    ])
    .unwrap();
    for t in tables {
        od.insert_all(t).unwrap();
    }
    let cfg = NodeConfig::slave(nid).with_auto_start(true);
    Station::single(Node::new(cfg, od))
}

fn tpdo(pdo: u16, ttype: u8, inhibit: u16, timer: u16, map: &[u32]) -> Vec<ObjectDef> {
    let mut v =
        params::tpdo_comm(pdo, params::predefined_tpdo_cob(pdo), ttype, inhibit, timer).to_vec();
    v.extend(params::tpdo_mapping::<9>(pdo, map));
    v
}

fn network(devs: Vec<(&str, Dev)>) -> (SimNetwork, Vec<DevId<Dev>>) {
    let mut sim = SimNetwork::new(1);
    let bus = sim.add_bus(BusConfig::new("can0", 500_000));
    sim.set_bus_faults(bus, FaultRates::NONE);
    let ids = devs
        .into_iter()
        .map(|(name, d)| {
            let id = sim.add_device(name, d, &[bus]).unwrap();
            sim.device_mut(id).machine.boot(Instant::ZERO);
            id
        })
        .collect();
    (sim, ids)
}

/// Delivered frames on `id`: (start, end, frame).
fn on_wire(sim: &SimNetwork, id: u16) -> Vec<(Instant, Instant, Frame)> {
    sim.trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(t)
                if t.frame.id() == Id::Standard(id)
                    && matches!(t.outcome, TxOutcome::Delivered { .. }) =>
            {
                Some((t.start, t.end, t.frame))
            }
            _ => None,
        })
        .collect()
}

fn u16_of(f: &Frame) -> u16 {
    u16::from_le_bytes([f.data()[0], f.data()[1]])
}

/// When an event-driven TPDO with inhibit time `inhibit` must be queued, given the writes to its
/// mapped entry (entering operational at 0 counts as the first event). A write at the instant the
/// inhibit time ends is sent by the write itself (the simulator runs actions before timeouts).
fn inhibit_model(writes: &[Instant], inhibit: Duration) -> Vec<Instant> {
    let mut out = vec![Instant::ZERO];
    let mut last = Instant::ZERO;
    let mut pending = false;
    for &w in writes {
        if pending && last + inhibit < w {
            last += inhibit;
            out.push(last);
        }
        if w >= last + inhibit {
            out.push(w);
            last = w;
            pending = false;
        } else {
            pending = true;
        }
    }
    if pending {
        out.push(last + inhibit);
    }
    out
}

#[test]
fn inhibit_time_is_never_violated_under_random_writes() {
    // TPDO1: type 255, inhibit 10 ms (100 × 100 µs).
    let (mut sim, ids) = network(vec![
        ("master", station(1, &[])),
        (
            "slave",
            station(5, &[&tpdo(1, 255, 100, 0, &[0x6001_0010])]),
        ),
    ]);
    let s = ids[1];
    let mut rng = fastrand::Rng::with_seed(42);
    let mut writes = vec![];
    let mut t = ms(1);
    let mut v = 0u16;
    while t < ms(3_000) {
        v = v.wrapping_add(1);
        writes.push((t, v));
        let value = v;
        sim.at(t, move |sim| {
            let now = sim.now();
            sim.device_mut(s)
                .machine
                .set(now, 0x6001, 0, value)
                .unwrap();
        });
        t += Duration::from_micros(rng.u64(100..15_000));
    }
    sim.run_until(ms(3_100));
    let frames = on_wire(&sim, 0x185);
    let starts: Vec<Instant> = frames.iter().map(|(s, _, _)| *s).collect();
    let expected = inhibit_model(
        &writes.iter().map(|(t, _)| *t).collect::<Vec<_>>(),
        Duration::from_millis(10),
    );
    assert!(starts[0] < ms(1), "first frame right after the boot-ups");
    assert_eq!(
        starts[1..],
        expected[1..],
        "exactly when the inhibit time allows"
    );
    // The inhibit time counts from the instant the TPDO is queued. The start-up frame is queued
    // at 0 but waits on the wire behind the boot-up messages; every later frame starts when queued.
    let gaps: Vec<Duration> = starts[1..].windows(2).map(|p| p[1] - p[0]).collect();
    assert!(
        gaps.iter().all(|g| *g >= Duration::from_millis(10)),
        "never two frames closer than the inhibit time"
    );
    assert!(
        gaps.contains(&Duration::from_millis(10)),
        "and exactly it when inhibited"
    );
    assert!(starts.len() > 200);
    // Each frame carries the latest value written before it.
    for (start, _, f) in &frames[1..] {
        let latest = writes.iter().rev().find(|(t, _)| t <= start).unwrap().1;
        assert_eq!(u16_of(f), latest, "frame at {start}");
    }
}

#[test]
fn event_timer_period_is_exact_and_restarts_on_writes() {
    let (mut sim, ids) = network(vec![
        ("master", station(1, &[])),
        ("slave", station(5, &[&tpdo(1, 254, 0, 25, &[0x6001_0010])])),
    ]);
    let s = ids[1];
    for (t, v) in [(us(1_010_300), 1u16), (us(1_020_700), 2)] {
        sim.at(t, move |sim| {
            let now = sim.now();
            sim.device_mut(s).machine.set(now, 0x6001, 0, v).unwrap();
        });
    }
    sim.run_until(ms(2_000));
    let starts: Vec<Instant> = on_wire(&sim, 0x185).iter().map(|(s, _, _)| *s).collect();
    let mut expected: Vec<Instant> = (1..=40).map(|k| ms(25 * k)).collect();
    expected.extend([us(1_010_300), us(1_020_700)]);
    expected.extend((1..=39).map(|k| us(1_020_700 + 25_000 * k)));
    assert_eq!(starts[1..], expected[..]);
}

#[test]
fn every_nth_sync_start_value_and_sync_rpdo_over_1000_syncs() {
    // Slave: TPDO1 every 3rd SYNC (0x6001), TPDO2 every 4th SYNC from counter 7 (0x6000).
    let mut slave_tables = tpdo(1, 3, 0, 0, &[0x6001_0010]);
    slave_tables.extend(tpdo(2, 4, 0, 0, &[0x6000_0008]));
    // Master: RPDO1 takes the slave's TPDO1 into 0x2000, synchronously.
    let mut master_tables = params::rpdo_comm(1, DefaultValue::Unsigned(0x185), 1, 0).to_vec();
    master_tables.extend(params::rpdo_mapping::<2>(1, &[0x2000_0010]));
    let (mut sim, ids) = network(vec![
        ("master", station(1, &[&master_tables])),
        ("slave", station(5, &[&slave_tables])),
    ]);
    let (m, s) = (ids[0], ids[1]);
    {
        let slave = &mut sim.device_mut(s).machine;
        slave.set(ms(0), 0x1801, 1, 0x8000_0285u32).unwrap();
        slave
            .set(ms(0), 0x1801, params::sub::SYNC_START, 7u8)
            .unwrap();
        slave.set(ms(0), 0x1801, 1, 0x285u32).unwrap();
        slave.set(ms(0), comm::SYNC_OVERFLOW, 0, 10u8).unwrap();
    }
    {
        let master = &mut sim.device_mut(m).machine;
        master.set(ms(0), comm::SYNC_OVERFLOW, 0, 10u8).unwrap();
        master
            .set(ms(0), comm::SYNC_COB_ID, 0, 0x4000_0080u32)
            .unwrap();
        master.set(ms(0), comm::SYNC_PERIOD, 0, 1_000u32).unwrap();
    }
    // The slave's value changes half-way between SYNCs: value k from k ms + 500 µs.
    for k in 0..1000u64 {
        sim.at(us(k * 1000 + 500), move |sim| {
            let now = sim.now();
            sim.device_mut(s)
                .machine
                .set(now, 0x6001, 0, k as u16)
                .unwrap();
        });
    }
    sim.run_until(us(1_000_900));

    let syncs = on_wire(&sim, 0x80);
    assert_eq!(syncs.len(), 1000);
    for (k, (start, _, f)) in syncs.iter().enumerate() {
        assert_eq!(*start, ms(k as u64 + 1), "SYNC {} on its grid", k + 1);
        assert_eq!(f.data(), [(k % 10) as u8 + 1]);
    }
    // The SYNC (1-based number) a frame answers: the last one that ended before it started.
    let sync_of = |start: Instant| syncs.iter().rposition(|(_, end, _)| *end <= start).unwrap() + 1;

    let t1 = on_wire(&sim, 0x185);
    assert_eq!(t1.len(), 333);
    for (j, (start, _, f)) in t1.iter().enumerate() {
        let n = 3 * (j + 1);
        assert_eq!(sync_of(*start), n);
        assert_eq!(*start, syncs[n - 1].1, "sent the instant SYNC {n} ends");
        assert_eq!(u16_of(f) as usize, n - 1, "sampled at SYNC {n}");
    }

    let t2 = on_wire(&sim, 0x285);
    let answered: Vec<usize> = t2.iter().map(|(s, _, _)| sync_of(*s)).collect();
    let expected: Vec<usize> = (7..=1000).step_by(4).collect();
    assert_eq!(
        answered, expected,
        "first at counter 7, then every 4th SYNC"
    );
    assert_eq!(syncs[answered[0] - 1].2.data(), [7]);

    // The master applies each TPDO1 at the SYNC it produces next.
    let applied: Vec<Instant> = sim
        .events(m)
        .iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Machine(ev) => match ev.kind {
                NodeEventKind::Pdo(PdoEvent::RpdoReceived { pdo: 1 }) => Some(ev.at),
                _ => None,
            },
            _ => None,
        })
        .collect();
    let expected: Vec<Instant> = (1..=333).map(|j| ms(3 * j + 1)).collect();
    assert_eq!(applied, expected);
    assert_eq!(
        sim.device(m).machine.od().get_value::<u16>(0x2000, 0),
        Ok(998)
    );
}
