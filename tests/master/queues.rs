//! The master's queues: their capacities are configuration values, allocated once; an event
//! beyond the capacity is dropped and counted, never stored.

use duocan::master::{objects, Master, MasterConfig};
use duocan::od::comm;
use duocan::{Frame, Id, Instant, Machine, NodeId};

/// The events a master reports for the same input, and how many it dropped.
fn run(config: MasterConfig) -> (usize, u32) {
    let od = objects::master_dictionary(1, comm::Identity::default());
    let mut m = Master::new(NodeId::must(1), od, config).expect("master");
    let t = Instant::from_millis(1);
    m.boot(t);
    // Boot-ups of twenty nodes nobody assigned: each is an event of the master's node.
    for n in 2..22u16 {
        m.handle_frame(t, &Frame::from_array(Id::Standard(0x700 + n), [0x00]));
    }
    let mut held = 0;
    while m.poll_event().is_some() {
        held += 1;
    }
    (held, m.stats().events_dropped)
}

#[test]
fn event_queue_capacity_is_configured_and_overflow_is_counted() {
    let (all, dropped) = run(MasterConfig::new());
    assert_eq!(dropped, 0, "the default capacity holds them all");
    assert!(
        all > 4,
        "the input makes more events ({all}) than the small queue holds"
    );
    let (held, dropped) = run(MasterConfig::new().event_queue(4));
    assert_eq!(held, 4);
    assert_eq!(dropped as usize, all - 4);
}
