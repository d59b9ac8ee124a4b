//! The supervisor's queues and tables: their capacities are configuration values, allocated
//! once; an event beyond the queue is dropped and counted, never stored, a pair beyond the
//! table refused, an audit record beyond the trail overwrites the oldest.

use duocan::master::{objects, Master, MasterConfig};
use duocan::od::comm;
use duocan::{Duration, Frame, Id, Instant, Machine, NodeId};
use duocan_redundancy::{Supervisor, SupervisorConfig};

/// The events a supervisor reports for the same input, and how many it dropped.
fn run(capacity: Option<usize>) -> (usize, u32) {
    let od = objects::master_dictionary(1, comm::Identity::default());
    let master = Master::new(NodeId::must(1), od, MasterConfig::new()).expect("master");
    let ms = Duration::from_millis;
    let mut cfg = SupervisorConfig::new(0, NodeId::must(1), ms(20), ms(50), ms(10));
    if let Some(c) = capacity {
        cfg = cfg.with_event_queue(c);
    }
    let t = Instant::from_millis(1);
    let mut sup = Supervisor::new(master, cfg, t);
    // Boot-ups of twenty nodes that are neither pair members nor assigned slaves.
    for n in 2..22u16 {
        sup.handle_frame(t, &Frame::from_array(Id::Standard(0x700 + n), [0x00]));
    }
    let mut held = 0;
    while sup.poll_event().is_some() {
        held += 1;
    }
    (held, sup.stats().events_dropped)
}

#[test]
fn event_queue_capacity_is_configured_and_overflow_is_counted() {
    let (all, dropped) = run(None);
    assert_eq!(dropped, 0, "the default capacity holds them all");
    assert!(
        all > 4,
        "the input makes more events ({all}) than the small queue holds"
    );
    let (held, dropped) = run(Some(4));
    assert_eq!(held, 4);
    assert_eq!(dropped as usize, all - 4);
}

/// A supervisor with `cfg` on a fresh master, at 1 ms.
fn supervisor(cfg: SupervisorConfig) -> Supervisor<duocan::od::DynamicDictionary> {
    let od = objects::master_dictionary(1, comm::Identity::default());
    let master = Master::new(NodeId::must(1), od, MasterConfig::new()).expect("master");
    Supervisor::new(master, cfg, Instant::from_millis(1))
}

#[test]
fn the_pair_table_and_the_audit_trail_have_the_room_configured() {
    use duocan_redundancy::supervisor::pairs::PairsError;
    use duocan_redundancy::{AddPairError, PairSpec};
    let ms = Duration::from_millis;
    let cfg = SupervisorConfig::new(0, NodeId::must(1), ms(20), ms(50), ms(10))
        .with_pair_capacity(2)
        .with_pair_queue(8)
        .with_audit_capacity(1);
    let mut sup = supervisor(cfg);
    let t = Instant::from_millis(1);
    let spec = |a: u8| PairSpec::new(NodeId::must(a), NodeId::must(a + 0x40), ms(20), ms(50));
    assert!(sup.add_pair(t, spec(0x10)).is_ok());
    assert!(sup.add_pair(t, spec(0x11)).is_ok());
    // The third pair finds the table full, and nothing of it reaches the master.
    assert!(matches!(
        sup.add_pair(t, spec(0x12)),
        Err(AddPairError::Pairs(PairsError::Full))
    ));
    assert_eq!(sup.pair_supervisor().capacity(), 2);
    assert!(!sup.master().slave(NodeId::must(0x12)).assignment.is_slave());
    // Alone on the bus the master negotiates and becomes active: more than one role change,
    // of which a one-record trail keeps the last.
    let mut full = supervisor(SupervisorConfig::new(
        0,
        NodeId::must(1),
        ms(20),
        ms(50),
        ms(10),
    ));
    for s in [&mut sup, &mut full] {
        let mut now = t;
        while now < Instant::from_secs(2) {
            now = s
                .poll_timeout()
                .unwrap_or(Instant::MAX)
                .min(Instant::from_secs(2));
            s.handle_timeout(now);
            while s.poll_transmit().is_some() {}
            while s.poll_event().is_some() {}
        }
    }
    assert!(full.audit().len() > 1, "{:?}", full.audit());
    assert_eq!(sup.audit().capacity(), 1);
    assert_eq!(sup.audit().len(), 1);
    assert_eq!(sup.audit().overwritten() as usize, full.audit().len() - 1);
    assert_eq!(
        sup.audit().iter().next().map(|r| r.entry),
        full.audit().iter().last().map(|r| r.entry)
    );
}
