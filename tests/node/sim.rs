//! Nodes on the simulated bus: exact timing with real frame durations, and determinism.

use duocan::machine::StationEvent;
use duocan::node::NodeEventKind;
use duocan::od::{comm, DynamicDictionary};
use duocan::sim::{timing, BusConfig, FaultRates, SimNetwork, TraceRecord};
use duocan::{Duration, Frame, Id, Instant, Node, NodeConfig, NodeId, Station};

type Dev = Station<duocan::machine::SinglePort, Node<DynamicDictionary>>;

fn station(id: u8, master: bool) -> Dev {
    let nid = NodeId::must(id);
    let od = comm::standard_dictionary(id, comm::Identity::default());
    Station::single(Node::new(
        if master {
            NodeConfig::master(nid)
        } else {
            NodeConfig::slave(nid)
        },
        od,
    ))
}

/// A master watching three slaves that beat every 20 ms; returns the network and the master.
fn network(
    seed: u64,
    faults: FaultRates,
) -> (
    SimNetwork,
    duocan::sim::DevId<Dev>,
    Vec<duocan::sim::DevId<Dev>>,
) {
    let mut sim = SimNetwork::new(seed);
    let bus = sim.add_bus(BusConfig::new("can0", 250_000));
    sim.set_bus_faults(bus, faults);
    let m = sim.add_device("master", station(1, true), &[bus]).unwrap();
    let mut slaves = Vec::new();
    for id in 2..=4u8 {
        let s = sim
            .add_device(format!("s{id}"), station(id, false), &[bus])
            .unwrap();
        let n = &mut sim.device_mut(s).machine;
        n.boot(Instant::ZERO);
        n.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, 20u16)
            .unwrap();
        sim.device_mut(m)
            .machine
            .set(
                Instant::ZERO,
                comm::HEARTBEAT_CONSUMER,
                id - 1,
                ((id as u32) << 16) | 50,
            )
            .unwrap();
        slaves.push(s);
    }
    sim.device_mut(m).machine.boot(Instant::ZERO);
    (sim, m, slaves)
}

#[test]
fn heartbeat_timeout_is_exact_with_real_frame_times() {
    let (mut sim, m, slaves) = network(1, FaultRates::NONE);
    sim.run_until(Instant::from_millis(1_001));
    sim.power_off(slaves[1].erased());
    sim.run_until(Instant::from_millis(2_000));
    // The last heartbeat of node 3 ended on the wire at some instant t; the timeout is t + 50 ms.
    let last_rx = sim
        .trace()
        .iter()
        .rev()
        .find_map(|r| match r {
            TraceRecord::Tx(t) if t.frame.id() == Id::Standard(0x703) => Some(t.end),
            _ => None,
        })
        .unwrap();
    let hb = Frame::from_array(Id::Standard(0x703), [0x7F]);
    // 44 + 8 frame bits, 3 intermission and 4 stuff bits (two in the identifier and control
    // field, one in the data, the rest in the CRC): 59 bits of 4 µs.
    assert_eq!(timing::frame_bits(&hb), 59);
    assert_eq!(
        timing::frame_duration(&hb, 250_000),
        Duration::from_micros(236)
    );
    let timeouts: Vec<_> = sim
        .events(m)
        .iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Machine(ev) => match ev.kind {
                NodeEventKind::HeartbeatTimeout { node, last } => Some((node, last, ev.at)),
                _ => None,
            },
            _ => None,
        })
        .collect();
    assert_eq!(
        timeouts,
        [(
            NodeId::must(3),
            last_rx,
            last_rx + Duration::from_millis(50)
        )]
    );
}

#[test]
fn same_seed_same_trace_other_seed_differs() {
    let faults = FaultRates::NONE
        .with_drop(0.05)
        .with_duplicate(0.02)
        .with_corrupt_detected(0.02);
    let run = |seed| {
        let (mut sim, m, _) = network(seed, faults);
        sim.run_until(Instant::from_secs(2));
        let events: Vec<_> = sim
            .events(m)
            .iter()
            .map(|(t, e)| format!("{t} {e:?}"))
            .collect();
        (sim.trace().to_vec(), events)
    };
    let (a, ea) = run(7);
    let (b, eb) = run(7);
    let (c, _) = run(8);
    assert!(a.len() > 300);
    assert_eq!(a, b, "same seed, same trace");
    assert_eq!(ea, eb, "same seed, same events");
    assert_ne!(a, c, "another seed, another trace");
}
