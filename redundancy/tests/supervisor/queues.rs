//! The supervisor's event queue: its capacity is a configuration value, allocated once; an
//! event beyond it is dropped and counted, never stored.

use duocan::master::{objects, Master, NetworkConfig};
use duocan::od::comm;
use duocan::{Duration, Frame, Id, Instant, Machine, NodeId};
use duocan_redundancy::{Supervisor, SupervisorConfig};

/// The events a supervisor reports for the same input, and how many it dropped.
fn run(capacity: Option<usize>) -> (usize, u32) {
    let od = objects::master_dictionary(1, comm::Identity::default());
    let master = Master::new(NodeId::must(1), od, NetworkConfig::new()).expect("master");
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
