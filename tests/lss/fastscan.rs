//! Fastscan: every non-configured slave found one after another and given its node-ID from the
//! plan, at the exact cost the protocol predicts; and each way a scan stops.

use super::wire::{addr, ans, slave, Wire};
use duocan::cia305::{
    fastscan_cost, LssAddress, LssError, LssMaster, LssMasterConfig, LssMasterEventKind as K,
    LssMode, LssPlan, LssService,
};
use duocan::{Duration, Instant, Machine, NodeId};

/// The model's cost as (requests, answers, µs): answers arrive at the instant of their request
/// here, so the time is exactly the waiting.
pub fn cost(
    ids: &[LssAddress],
    timeout: Duration,
    settle: Duration,
    store: bool,
) -> (u32, u32, u64) {
    let cfg = LssMasterConfig::default()
        .with_timeout(timeout)
        .with_settle(settle);
    let c = fastscan_cost(&mut ids.to_vec(), &cfg, store);
    (c.requests, c.answers, c.waiting.as_micros())
}

pub fn cfg() -> LssMasterConfig {
    LssMasterConfig::default()
        .with_timeout(Duration::from_millis(10))
        .with_settle(Duration::from_millis(1))
}

pub fn counts(w: &Wire) -> (u32, u32, u64) {
    let req = w.log.iter().filter(|(_, f)| f.id().raw() == 0x7E5).count() as u32;
    (req, w.log.len() as u32 - req, w.now.as_micros())
}

#[test]
fn three_slaves_by_identity_and_next_free_at_the_predicted_cost() {
    let low = addr(0x2A, 7, 1, 0x100);
    let mid = addr(0x2A, 7, 1, 0x101);
    let high = addr(0x2A, 9, 0, 5);
    // One already configured board that must not take part.
    let slaves = vec![
        slave(high, 0xFF),
        slave(mid, 0xFF),
        slave(addr(0x2A, 7, 1, 0), 5),
        slave(low, 0xFF),
    ];
    let mut w = Wire::new(LssMaster::new(cfg()), slaves);
    let plan = LssPlan::new()
        .with_identity(mid, NodeId::must(10))
        .with_free((2..=4).map(NodeId::must));
    w.master.fastscan(Instant::ZERO, plan).unwrap();
    w.run(2000);
    let n = NodeId::must;
    assert_eq!(
        w.take_events(),
        [
            K::Found(low),
            K::Assigned {
                address: low,
                node: n(2)
            },
            K::Found(mid),
            K::Assigned {
                address: mid,
                node: n(10)
            },
            K::Found(high),
            K::Assigned {
                address: high,
                node: n(3)
            },
            K::ScanFinished { assigned: 3 },
        ]
    );
    let ids: Vec<_> = w
        .slaves
        .iter()
        .map(|s| s.node_id().map(|n| n.raw()))
        .collect();
    assert_eq!(ids, [Some(3), Some(10), Some(5), Some(2)]);
    assert!(w.slaves.iter().all(|s| s.mode() == LssMode::Waiting));
    let predicted = cost(&[low, mid, high], cfg().timeout, cfg().settle, false);
    assert_eq!(counts(&w), predicted);
    // 3 × 135 requests and the final reset.
    assert_eq!(predicted.0, 406);
    assert_eq!(w.master.stats().unsolicited, 0);
}

#[test]
fn a_plan_that_stores_leaves_each_node_id_on_its_board() {
    let a = addr(1, 2, 3, 4);
    let mut w = Wire::new(LssMaster::new(cfg()), vec![slave(a, 0xFF)]);
    w.master
        .fastscan(
            Instant::ZERO,
            LssPlan::new()
                .with_identity(a, NodeId::must(33))
                .with_store(true),
        )
        .unwrap();
    w.run(1000);
    assert_eq!(counts(&w), cost(&[a], cfg().timeout, cfg().settle, true));
    let image = w.slaves[0].storage().unwrap().image().unwrap().to_vec();
    let mut medium = duocan::od::parameters::MemoryStorage::<16>::new();
    duocan::od::parameters::ParameterStorage::store(&mut medium, &image).unwrap();
    let mut reborn = duocan::cia305::LssSlave::new(a, 0xFF).with_storage(medium);
    assert_eq!(reborn.load_stored().unwrap().unwrap().node_id, 33);
}

#[test]
fn a_slave_the_plan_has_no_node_id_for_stops_the_scan_back_in_waiting() {
    let a = addr(1, 2, 3, 4);
    let mut w = Wire::new(LssMaster::new(cfg()), vec![slave(a, 0xFF)]);
    // The only free node-ID is planned for another identity.
    let plan = LssPlan::new()
        .with_identity(addr(9, 9, 9, 9), NodeId::must(7))
        .with_free([NodeId::must(7)]);
    w.master.fastscan(Instant::ZERO, plan).unwrap();
    w.run(1000);
    assert_eq!(
        w.take_events(),
        [K::Found(a), K::Failed(LssError::NoNodeId(a))]
    );
    assert_eq!(w.log.last().unwrap().1.data(), [0x04, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(
        (w.slaves[0].mode(), w.slaves[0].node_id()),
        (LssMode::Waiting, None)
    );
    assert!(w.master.is_idle());
}

#[test]
fn a_slave_that_leaves_mid_scan_is_missed_at_its_confirmation_and_not_found_again() {
    let a = addr(0x2A, 7, 1, 0x100);
    let mut w = Wire::new(LssMaster::new(cfg()), vec![slave(a, 0xFF)]);
    w.master
        .fastscan(Instant::ZERO, LssPlan::new().with_free([NodeId::must(1)]))
        .unwrap();
    w.exchange();
    // Reset and the first ten bit steps, then the board is pulled.
    for _ in 0..11 {
        w.now = w.deadline().unwrap();
        w.master.handle_timeout(w.now);
        w.exchange();
    }
    w.slaves.clear();
    w.run(1000);
    // The scan starts over (the mistake could have been a stray answer) and its reset finds
    // nobody.
    assert_eq!(
        w.take_events(),
        [K::ScanRestarted { sub: 0 }, K::ScanFinished { assigned: 0 }]
    );
}

/// A fastscan for one node-ID started at 0, its reset step sent.
fn scan_waiting_for_its_reset() -> LssMaster {
    let mut m: LssMaster = LssMaster::new(cfg());
    m.fastscan(Instant::ZERO, LssPlan::new().with_free([NodeId::must(1)]))
        .unwrap();
    assert_eq!(
        m.poll_transmit().unwrap().data(),
        [0x51, 0, 0, 0, 0, 0x80, 0, 0]
    );
    m
}

#[test]
fn an_answer_of_another_service_during_the_scan_stops_it() {
    let (mut m, t) = (scan_waiting_for_its_reset(), Instant::ZERO);
    m.handle_frame(t, &ans([0x50, 0, 0, 0, 0, 0, 0, 0]));
    let e = m.poll_event().unwrap().kind;
    assert_eq!(
        e,
        K::Failed(LssError::WrongAnswer {
            service: LssService::Fastscan,
            cs: 0x50
        })
    );
    assert_eq!(
        m.poll_transmit().unwrap().data(),
        [0x04, 0, 0, 0, 0, 0, 0, 0]
    );
    // Nobody there: the scan ends at the first timeout with nothing assigned.
    let mut w = Wire::new(LssMaster::new(cfg()), vec![]);
    w.master.fastscan(t, LssPlan::new()).unwrap();
    w.run(10);
    assert_eq!(w.take_events(), [K::ScanFinished { assigned: 0 }]);
    assert_eq!((w.log.len(), w.now), (1, Instant::from_millis(10)));
}

#[test]
fn an_expected_identity_places_the_first_board_that_agrees_and_only_once() {
    // Two boards of vendor 0x2A product 7, serial numbers unknown beforehand; one of vendor 9.
    let (x, y, z) = (
        addr(0x2A, 7, 1, 0x50),
        addr(0x2A, 7, 2, 0x10),
        addr(9, 7, 1, 1),
    );
    let mut w = Wire::new(
        LssMaster::new(cfg()),
        vec![slave(x, 0xFF), slave(y, 0xFF), slave(z, 0xFF)],
    );
    let plan = LssPlan::new()
        .with_expected(addr(0x2A, 7, 0, 0), NodeId::must(20))
        .with_free([NodeId::must(30), NodeId::must(31)]);
    assert_eq!(plan.node_of(&y), Some(NodeId::must(20)));
    assert_eq!(plan.node_of(&z), None);
    w.master.fastscan(Instant::ZERO, plan).unwrap();
    w.run(2000);
    let ids: Vec<_> = w
        .slaves
        .iter()
        .map(|s| s.node_id().unwrap().raw())
        .collect();
    // Found in identity order: vendor 9 first (pool: 30), then x (rev 1: the slot, 20), then y
    // (the slot is used: pool, 31).
    assert_eq!(ids, [20, 31, 30]);
}

#[test]
fn a_late_call_still_gives_the_next_step_its_whole_timeout() {
    let mut m: LssMaster = LssMaster::new(cfg());
    m.fastscan(Instant::ZERO, LssPlan::new().with_free([NodeId::must(1)]))
        .unwrap();
    let _reset = m.poll_transmit();
    // A slave answers the reset at 1 ms; the step would end at 2 ms (settle) ...
    m.handle_frame(Instant::from_millis(1), &ans([0x4F, 0, 0, 0, 0, 0, 0, 0]));
    assert_eq!(m.poll_timeout(), Some(Instant::from_millis(2)));
    // ... but the driver calls only at 50 ms: the first bit step goes out then and waits until
    // 60 ms, not 12 ms (which would take the silence of a slave that had no time to answer).
    m.handle_timeout(Instant::from_millis(50));
    assert_eq!(
        m.poll_transmit().unwrap().data(),
        [0x51, 0, 0, 0, 0, 31, 0, 0]
    );
    assert_eq!(m.poll_timeout(), Some(Instant::from_millis(60)));
}

/// On a dual bus a slow host can deliver the other bus's copy of the configure answer after
/// the merge window, while the scan's next reset waits: it is the scan's own answer come late,
/// counted and dropped, and the scan goes on.
#[test]
fn a_late_copy_of_the_scans_own_configure_answer_is_dropped() {
    let (mut m, t) = (scan_waiting_for_its_reset(), Instant::ZERO);
    // Configure node-ID and store answers (no error) while the reset waits.
    m.handle_frame(t, &ans([0x11, 0, 0, 0, 0, 0, 0, 0]));
    m.handle_frame(t, &ans([0x17, 0, 0, 0, 0, 0, 0, 0]));
    assert_eq!(m.poll_event(), None);
    assert_eq!(m.stats().late, 2);
    // Nobody answers the reset: the scan ends at its timeout, as without them.
    m.handle_timeout(Instant::from_millis(10));
    assert_eq!(
        m.poll_event().unwrap().kind,
        K::ScanFinished { assigned: 0 }
    );
}
