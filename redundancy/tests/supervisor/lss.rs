//! Board replacement by LSS: a pair member that arrives without a node-ID is given its slot's
//! node-ID by the active supervisor, boots, and joins as standby through the normal boot.

use duocan::cia305::{fastscan_cost, LssAddress, LssMasterConfig, LssMasterEventKind, LssSlave};
use duocan::machine::StationEvent;
use duocan::master::{objects, ExpectedIdentity, Master, MasterConfig, SlaveConfig};
use duocan::node::LssNode;
use duocan::od::comm;
use duocan::sim::{BusConfig, SimNetwork};
use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::supervisor::audit::{AuditEntry, BoardAddressed};
use duocan_redundancy::supervisor::pairs::PairsEvent;
use duocan_redundancy::{
    DualBus, DualBusConfig, Member, PairId, PairSpec, SupervisedStation, Supervisor,
    SupervisorConfig, SupervisorEvent,
};

const VENDOR: u32 = 0x2A;
const PRODUCT: u32 = 7;

fn identity(serial: u32) -> comm::Identity {
    comm::Identity {
        vendor: VENDOR,
        product: PRODUCT,
        serial,
        ..Default::default()
    }
}

fn run(
    lss: bool,
    replacement_vendor: u32,
    other_lss_master: bool,
) -> (
    SimNetwork,
    duocan::sim::DevId<SupervisedStation<duocan::od::DynamicDictionary>>,
) {
    let ms = Duration::from_millis;
    let t0 = Instant::ZERO;
    let mut sim = SimNetwork::new(3);
    let buses = [
        sim.add_bus(BusConfig::new("can1", 1_000_000)),
        sim.add_bus(BusConfig::new("can2", 1_000_000)),
    ];
    let master = Master::new(
        NodeId::must(1),
        objects::master_dictionary(1, comm::Identity::default()),
        MasterConfig::new(),
    )
    .unwrap();
    let mut cfg = SupervisorConfig::new(0, NodeId::must(1), ms(20), ms(50), ms(10));
    if lss {
        cfg = cfg.with_lss(ms(200));
    }
    let mut sup = Supervisor::new(master, cfg, t0);
    // Both slots expect vendor 0x2A, product 7; any serial number.
    let expect = ExpectedIdentity {
        vendor: VENDOR,
        product: PRODUCT,
        ..Default::default()
    };
    let (a, b) = (NodeId::must(0x10), NodeId::must(0x50));
    sup.add_pair_with(
        t0,
        PairSpec::new(a, b, ms(20), ms(50)),
        SlaveConfig::new(a).identity(expect),
        SlaveConfig::new(b).identity(expect),
    )
    .unwrap();
    let link = || DualBus::new(DualBusConfig::default());
    let m = sim
        .add_device(
            "master",
            SupervisedStation::new(link(), sup).unwrap(),
            &buses,
        )
        .unwrap();
    // Board A, configured.
    let mut n = Node::new(
        NodeConfig::slave(a),
        comm::standard_dictionary(0x10, identity(1)),
    );
    n.boot(t0);
    sim.add_device("board A", Station::new(link(), n), &buses)
        .unwrap();
    // Board B, the replacement, without node-ID.
    let address = LssAddress {
        vendor: replacement_vendor,
        product: PRODUCT,
        revision: 0,
        serial: 0xBEEF,
    };
    let board = LssNode::new(t0, LssSlave::new(address, 0xFF), move |id: NodeId, now| {
        let ident = comm::Identity {
            vendor: replacement_vendor,
            ..identity(0xBEEF)
        };
        let mut n = Node::new(
            NodeConfig::slave(id),
            comm::standard_dictionary(id.raw(), ident),
        );
        n.boot(now);
        n
    });
    sim.add_device("board B", Station::new(link(), board), &buses)
        .unwrap();
    if other_lss_master {
        // Another LSS master (a tool, or this station's front door) asks every 100 ms what
        // no slave answers unless selected: "inquire vendor-ID".
        let mut d = [0u8; 8];
        d[0] = 0x5A;
        let request = duocan::Frame::from_array(duocan::cia305::codec::MASTER_TO_SLAVE, d);
        let other = crate::impostor::injector(2, request, Some(t0), ms(100));
        sim.add_device("other LSS master", other, &buses).unwrap();
    }
    sim.run_until(Instant::from_secs(3));
    (sim, m)
}

fn events(
    sim: &SimNetwork,
    m: duocan::sim::DevId<SupervisedStation<duocan::od::DynamicDictionary>>,
) -> Vec<SupervisorEvent> {
    sim.events(m)
        .iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Machine(s) => Some(s.clone()),
            _ => None,
        })
        .collect()
}

#[test]
fn a_replacement_board_without_node_id_gets_its_slot_and_joins_as_standby() {
    let (sim, m) = run(true, VENDOR, false);
    let ev = events(&sim, m);
    let addressed: Vec<BoardAddressed> = ev
        .iter()
        .filter_map(|e| match e {
            SupervisorEvent::Addressed(b) => Some(*b),
            _ => None,
        })
        .collect();
    assert_eq!(addressed.len(), 1, "{ev:?}");
    let b = addressed[0];
    // The scan, from the answer to identify non-configured to its end, took what the protocol
    // predicts for this identity (default timing: 50 ms timeout, 2 ms settle) plus frame times.
    let lss: Vec<_> = ev
        .iter()
        .filter_map(|e| match e {
            SupervisorEvent::Lss(l) => Some((l.at, l.kind)),
            _ => None,
        })
        .collect();
    let (started, _) = lss
        .iter()
        .find(|(_, k)| matches!(k, LssMasterEventKind::Done(_)))
        .unwrap();
    let (ended, _) = lss
        .iter()
        .find(|(_, k)| matches!(k, LssMasterEventKind::ScanFinished { assigned: 1 }))
        .unwrap();
    let cost = fastscan_cost(&mut [b.address], &LssMasterConfig::default(), false);
    let frame = Duration::from_micros(135);
    let elapsed = *ended - *started;
    assert!(
        elapsed >= cost.waiting
            && elapsed
                <= cost.waiting + frame.saturating_mul(u64::from(cost.requests + cost.answers)),
        "{elapsed} vs {}",
        cost.waiting
    );
    assert_eq!(
        (b.pair, b.member, b.node.raw(), b.address.serial),
        (PairId(0), Member::B, 0x50, 0xBEEF)
    );
    // Then it joined through the normal boot, after being addressed; A stays active.
    let joined = ev.iter().find_map(|e| match e {
        SupervisorEvent::Pairs(PairsEvent::Joined {
            at,
            member: Member::B,
            ..
        }) => Some(*at),
        _ => None,
    });
    assert!(joined.is_some_and(|t| t > b.at), "{joined:?} vs {}", b.at);
    let sup = sim.device(m).sup();
    let pair = sup.pair_supervisor().pair(PairId(0)).unwrap();
    assert_eq!(pair.active, Some(Member::A));
    assert!(pair.member(Member::B).joined());
    // The audit trail says so, in text and CSV.
    let rec = sup
        .audit()
        .iter()
        .find(|r| matches!(r.entry, AuditEntry::Addressed(_)))
        .unwrap();
    let line = rec.to_string();
    assert!(
        line.contains("pair 0 member B") && line.contains("given node 0x50 by LSS"),
        "{line}"
    );
    let mut csv = String::new();
    sup.audit().write_csv(&mut csv).unwrap();
    assert!(
        csv.lines().any(|l| l.contains(",lss,pair 0 (B),none,")),
        "{csv}"
    );
}

#[test]
fn a_board_of_another_vendor_is_not_given_the_slot_and_without_lss_nothing_is_sent() {
    let (sim, m) = run(true, 0x99, false);
    let ev = events(&sim, m);
    assert!(!ev
        .iter()
        .any(|e| matches!(e, SupervisorEvent::Addressed(_))));
    // It was looked for (identify non-configured answered) but the scan found no slot for it.
    assert!(ev.iter().any(|e| matches!(e, SupervisorEvent::Lss(_))));
    let (sim, _) = run(false, VENDOR, false);
    let lss_frames = sim.trace().iter().filter(|r| match r {
        duocan::sim::TraceRecord::Tx(x) => matches!(x.frame.id().raw(), 0x7E4 | 0x7E5),
        _ => false,
    });
    assert_eq!(lss_frames.count(), 0);
}

#[test]
fn the_replacement_waits_while_another_lss_master_makes_requests() {
    // The same station, with another LSS master's request on the bus every 100 ms for the
    // whole run: the supervisor starts none of its own (each request holds it off for its
    // period, 200 ms), so the slot stays vacant and board B without its node-ID.
    let (sim, m) = run(true, VENDOR, true);
    let ev = events(&sim, m);
    assert!(
        !ev.iter()
            .any(|e| matches!(e, SupervisorEvent::Lss(_) | SupervisorEvent::Addressed(_))),
        "{ev:?}"
    );
    let sup = sim.device(m).sup();
    let pair = sup.pair_supervisor().pair(PairId(0)).unwrap();
    assert!(!pair.member(Member::B).joined());
}
