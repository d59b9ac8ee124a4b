//! LSS over the dual-bus layer: 20 non-configured boards on two simulated buses found by
//! fastscan and configured, with the frames on each bus and the simulated time against what
//! the protocol predicts; a board heard on one bus only still counts, and fails no port in
//! the quiet steps between.

use duocan::cia305::{
    fastscan_cost, LssAddress, LssMaster, LssMasterConfig, LssMasterEvent, LssMasterEventKind as K,
    LssPlan, LssSlave,
};
use duocan::machine::StationEvent;
use duocan::sim::{timing, BusConfig, BusId, DevId, SimNetwork, TraceRecord, TxOutcome};
use duocan::{Duration, Instant, NodeId, Station};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEventKind, PortState};

type MasterDev = Station<DualBus, LssMaster<32>>;
type SlaveDev = Station<DualBus, LssSlave>;

const BITRATE: u32 = 1_000_000;

fn cfg() -> LssMasterConfig {
    LssMasterConfig::default()
        .with_timeout(Duration::from_millis(10))
        .with_settle(Duration::from_millis(1))
}

/// Board `i`: one vendor and product, two revisions, scattered serial numbers.
fn board(i: u32) -> LssAddress {
    LssAddress {
        vendor: 0x0000_02A0,
        product: 0x0013,
        revision: 1 + (i % 2),
        serial: 0x5000_0000 ^ i.wrapping_mul(0x9E37_79B9) >> 4,
    }
}

struct Scan {
    sim: SimNetwork,
    buses: [BusId; 2],
    master: DevId<MasterDev>,
    slaves: Vec<DevId<SlaveDev>>,
}

fn network(boards: &[LssAddress]) -> Scan {
    let mut sim = SimNetwork::new(7);
    let buses = [
        sim.add_bus(BusConfig::new("can1", BITRATE)),
        sim.add_bus(BusConfig::new("can2", BITRATE)),
    ];
    let link = || DualBus::new(DualBusConfig::default());
    let master = sim
        .add_device(
            "master",
            Station::new(link(), LssMaster::new(cfg())),
            &buses,
        )
        .unwrap();
    let slaves = boards
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let s = Station::new(link(), LssSlave::new(*b, 0xFF));
            sim.add_device(format!("board{i}"), s, &buses).unwrap()
        })
        .collect();
    Scan {
        sim,
        buses,
        master,
        slaves,
    }
}

impl Scan {
    /// Runs the scan from 0 to its end; returns the master's events.
    fn run(&mut self, plan: LssPlan<32>) -> Vec<LssMasterEvent> {
        let now = self.sim.now();
        self.sim
            .device_mut(self.master)
            .machine
            .fastscan(now, plan)
            .unwrap();
        for _ in 0..10_000 {
            self.sim.run_for(Duration::from_millis(100));
            if self.sim.device(self.master).machine.is_idle() {
                break;
            }
        }
        assert!(
            self.sim.device(self.master).machine.is_idle(),
            "the scan did not end"
        );
        self.sim
            .events(self.master)
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Machine(m) => Some(*m),
                _ => None,
            })
            .collect()
    }

    /// Frames delivered on bus `b` with identifier `id`.
    fn delivered(&self, b: usize, id: u32) -> u32 {
        let bus = self.buses[b];
        let n = self.sim.trace().iter().filter(|r| {
            matches!(r, TraceRecord::Tx(x) if x.bus == bus && x.frame.id().raw() == id
                && matches!(x.outcome, TxOutcome::Delivered { .. }))
        });
        n.count() as u32
    }
}

#[test]
fn twenty_boards_found_by_fastscan_on_the_dual_bus_at_the_predicted_cost() {
    let boards: Vec<LssAddress> = (0..20).map(board).collect();
    let mut net = network(&boards);
    let plan = LssPlan::new().with_free((2..=127).map(NodeId::must));
    let events = net.run(plan);
    let end = match events.last() {
        Some(LssMasterEvent {
            at,
            kind: K::ScanFinished { assigned: 20 },
        }) => *at,
        e => panic!("the scan ended with {e:?}"),
    };
    // In identity order, node-IDs 2, 3, … each on its board.
    let mut sorted = boards.clone();
    sorted.sort();
    let assigned: Vec<(LssAddress, u8)> = events
        .iter()
        .filter_map(|e| match e.kind {
            K::Assigned { address, node } => Some((address, node.raw())),
            _ => None,
        })
        .collect();
    assert_eq!(
        assigned,
        sorted.iter().copied().zip(2u8..).collect::<Vec<_>>()
    );
    for (i, s) in net.slaves.iter().enumerate() {
        let want = sorted.iter().position(|b| *b == boards[i]).unwrap() as u8 + 2;
        assert_eq!(net.sim.device(*s).machine.node_id(), NodeId::new(want));
    }

    let cost = fastscan_cost(&mut boards.clone(), &cfg(), false);
    // Every request and every answer on each bus, as predicted; each answer (twenty at each
    // reset, several at once at many bit steps) reached the master exactly once after the merge.
    for b in 0..2 {
        assert_eq!(net.delivered(b, 0x7E5), cost.requests, "bus {b}");
        assert_eq!(net.delivered(b, 0x7E4), cost.answers, "bus {b}");
    }
    let stats = net.sim.device(net.master).machine.stats();
    assert_eq!(
        (stats.requests, stats.answers, stats.unsolicited),
        (cost.requests, cost.answers, 0)
    );

    // Time: the waiting the protocol needs, plus the frames' own time on the wire.
    let frame = timing::bits_duration(timing::worst_case_bits(false, 8), BITRATE);
    let frames = cost.requests + cost.answers;
    let on_wire = frame.saturating_mul(u64::from(frames));
    let elapsed = end - Instant::ZERO;
    // The protocol's bound without knowing the identities: 133 steps per board, each at worst a
    // request and a timeout, plus the final reset, configure node-ID and the switch back.
    let n = boards.len() as u64;
    let bound = cfg().timeout.saturating_mul(133 * n + 1) + on_wire;
    println!(
        "fastscan, {n} boards on two {} kbit/s buses: {} requests + {} answers = {frames} frames per bus \
         ({} steps unanswered, {} answered); simulated time {elapsed} (waiting {}, frames at most {on_wire}); \
         worst-case bound {bound}",
        BITRATE / 1000,
        cost.requests,
        cost.answers,
        cost.unanswered,
        cost.answered,
        cost.waiting,
    );
    assert_eq!(cost.requests, 135 * 20 + 1);
    assert!(elapsed >= cost.waiting, "{elapsed} < {}", cost.waiting);
    assert!(
        elapsed <= cost.waiting + on_wire,
        "{elapsed} > {} + {on_wire}",
        cost.waiting
    );
    assert!(elapsed <= bound);
}

#[test]
fn a_board_heard_on_one_bus_only_is_configured_all_the_same() {
    let boards: Vec<LssAddress> = (0..3).map(board).collect();
    let mut net = network(&boards);
    // Board 1's port on the second bus is off the wire.
    let port = net.slaves[1].port(1);
    net.sim.disconnect(port);
    let events = net.run(LssPlan::new().with_free((10..=12).map(NodeId::must)));
    assert!(matches!(
        events.last().unwrap().kind,
        K::ScanFinished { assigned: 3 }
    ));
    assert!(net.sim.device(net.slaves[1]).machine.node_id().is_some());
    let cost = fastscan_cost(&mut boards.clone(), &cfg(), false);
    // Its answers came on one bus only and counted once, like everyone else's.
    assert_eq!(
        net.sim.device(net.master).machine.stats().answers,
        cost.answers
    );
    assert!(net.delivered(1, 0x7E4) < net.delivered(0, 0x7E4));
}

/// As the vcan tier runs it: the answer timeout 300 ms, two boards whose serial numbers differ,
/// the second on bus 2 only. Many steps are answered by both boards (two answers on bus 2, one
/// on bus 1: bus 1 misses a frame bus 2 carries) and followed by steps nobody answers (both
/// buses quiet for the timeout). A quiet network fails no port: bus 1 stays in use for the
/// requests, and every answer is delivered once. (The same pattern behind a late reader:
/// `lag::a_node_on_one_bus_answering_beside_one_on_both_is_no_lag`.)
#[test]
fn a_board_on_one_bus_and_long_quiet_steps_fail_no_port() {
    let id = |serial| LssAddress {
        vendor: 0x00d0_ca00,
        product: 0x305,
        revision: 1,
        serial,
    };
    let boards = [id(7), id(8)];
    let mut net = network(&boards);
    let slow = LssMasterConfig::default()
        .with_timeout(Duration::from_millis(300))
        .with_settle(Duration::from_millis(30));
    net.sim.device_mut(net.master).machine = LssMaster::new(slow);
    let port = net.slaves[1].port(0);
    net.sim.disconnect(port);
    let events = net.run(LssPlan::new().with_free((0x30..=0x31).map(NodeId::must)));
    assert!(matches!(
        events.last().unwrap().kind,
        K::ScanFinished { assigned: 2 }
    ));
    let cost = fastscan_cost(&mut boards.to_vec(), &slow, false);
    let stats = net.sim.device(net.master).machine.stats();
    assert_eq!(
        (stats.requests, stats.answers, stats.restarts),
        (cost.requests, cost.answers, 0)
    );
    // Every request on both buses: bus 1 was never failed.
    assert_eq!(net.delivered(0, 0x7E5), cost.requests);
    assert_eq!(net.delivered(1, 0x7E5), cost.requests);
    let wrong: Vec<_> = net
        .sim
        .events(net.master)
        .iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Link(l) => Some(l.kind),
            _ => None,
        })
        .filter(|k| {
            matches!(
                k,
                LinkEventKind::Lag { .. }
                    | LinkEventKind::Port {
                        to: PortState::Failed,
                        ..
                    }
            )
        })
        .collect();
    assert!(wrong.is_empty(), "{wrong:?}");
}
