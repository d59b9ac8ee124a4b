//! A bridge between two buses: its copies, their delay, its direction, its filter, its queue,
//! the origin the receive hook is told.

use super::network;
use super::probe::{std_frame, Probe};
use crate::frame::instant::{Duration, Instant};
use crate::sim::timing::frame_duration;
use crate::sim::{BridgeConfig, BridgeDirection, Bridged, RxNote};
use std::cell::RefCell;
use std::rc::Rc;

const RATE: u32 = 500_000;
const LONG: Duration = Duration::from_secs(10);

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

#[test]
fn a_bridge_copies_a_frame_onto_the_other_bus_its_delay_after_it_ended_one_way_only() {
    let (mut sim, b) = network(1, 2, RATE);
    let f = std_frame(0x181, &[1, 2, 3]);
    let g = std_frame(0x182, &[4]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let y = sim
        .add_device("y", Probe::new(1).every(0, g, Instant::ZERO, LONG), &[b[1]])
        .unwrap();
    let delay = Duration::from_micros(2_500);
    sim.set_bridge(
        b[0],
        b[1],
        BridgeConfig::new(BridgeDirection::FirstToSecond, delay),
    );
    sim.run_until(ms(20));
    // x's frame ends, the bridge holds it for the delay, then sends it on the idle bus 2.
    let end = Instant::ZERO + frame_duration(&f, RATE);
    let copy_end = end + delay + frame_duration(&f, RATE);
    assert_eq!(sim.device(y).rx_on(0), vec![(copy_end, f)]);
    // y's frame is not copied onto bus 1: x hears nothing.
    assert!(sim.device(x).rx_on(0).is_empty());
    let stats = sim.bridge_stats().unwrap();
    assert_eq!(
        (stats.heard, stats.taken, stats.sent, stats.overflow),
        (2, 1, 1, 0)
    );
}

#[test]
fn a_bridge_both_ways_never_copies_a_frame_it_sent_itself() {
    let (mut sim, b) = network(1, 2, RATE);
    let f = std_frame(0x181, &[1]);
    let g = std_frame(0x282, &[2]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let y = sim
        .add_device("y", Probe::new(1).every(0, g, ms(1), LONG), &[b[1]])
        .unwrap();
    sim.set_bridge(
        b[0],
        b[1],
        BridgeConfig::new(BridgeDirection::Both, Duration::from_millis(1)),
    );
    sim.run_until(ms(100));
    // Each bus carried its own node's frame and the other's copy, once.
    assert_eq!(sim.bus_stats(b[0]).delivered, 2);
    assert_eq!(sim.bus_stats(b[1]).delivered, 2);
    let got = |p: &Probe| p.rx_on(0).into_iter().map(|r| r.1).collect::<Vec<_>>();
    assert_eq!(got(sim.device(x)), vec![g]);
    assert_eq!(got(sim.device(y)), vec![f]);
}

#[test]
fn a_bridge_copies_only_the_identifiers_of_its_range() {
    let (mut sim, b) = network(1, 2, RATE);
    let x = sim
        .add_device(
            "x",
            Probe::new(1)
                .every(0, std_frame(0x080, &[]), Instant::ZERO, LONG)
                .every(0, std_frame(0x181, &[1]), Instant::ZERO, LONG)
                .every(0, std_frame(0x701, &[5]), Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    let y = sim.add_device("y", Probe::new(1), &[b[1]]).unwrap();
    let mut config = BridgeConfig::new(BridgeDirection::Both, Duration::from_millis(1));
    config.ids = Some((0x100, 0x6FF));
    sim.set_bridge(b[0], b[1], config);
    sim.run_until(ms(50));
    let ids: Vec<_> = sim.device(y).rx_on(0).iter().map(|r| r.1.id()).collect();
    assert_eq!(ids, vec![std_frame(0x181, &[]).id()]);
    assert_eq!(sim.device(x).rx_on(0), vec![]);
}

#[test]
fn a_full_bridge_drops_what_it_receives_and_counts_it() {
    let (mut sim, b) = network(1, 2, RATE);
    let mut probe = Probe::new(1);
    for k in 0..10u8 {
        probe.send(0, std_frame(0x200 + u16::from(k), &[k; 8]));
    }
    sim.add_device("x", probe, &[b[0]]).unwrap();
    let y = sim.add_device("y", Probe::new(1), &[b[1]]).unwrap();
    let mut config = BridgeConfig::new(BridgeDirection::FirstToSecond, Duration::from_millis(5));
    config.queue = 3;
    sim.set_bridge(b[0], b[1], config);
    sim.run_until(ms(50));
    // The ten frames take 2.5 ms on bus 1: the bridge held the first three for 5 ms.
    let stats = sim.bridge_stats().unwrap();
    assert_eq!(
        (stats.heard, stats.taken, stats.overflow, stats.sent),
        (10, 3, 7, 3)
    );
    let data: Vec<u8> = sim
        .device(y)
        .rx_on(0)
        .iter()
        .map(|r| r.1.data()[0])
        .collect();
    assert_eq!(data, vec![0, 1, 2]);
}

#[test]
fn the_receive_hook_is_told_where_a_bridged_copy_came_from() {
    let (mut sim, b) = network(1, 2, RATE);
    let f = std_frame(0x181, &[1]);
    let x = sim
        .add_device("x", Probe::new(2).every(0, f, ms(1), LONG), &[b[0], b[1]])
        .unwrap();
    let y = sim.add_device("y", Probe::new(2), &[b[0], b[1]]).unwrap();
    let notes: Rc<RefCell<Vec<RxNote>>> = Rc::default();
    let n = notes.clone();
    sim.set_rx_hook(Some(Box::new(move |note| n.borrow_mut().push(*note))));
    let bridge = sim.set_bridge(
        b[0],
        b[1],
        BridgeConfig::new(BridgeDirection::FirstToSecond, Duration::from_millis(1)),
    );
    sim.run_until(ms(20));
    let notes = notes.borrow();
    let at_y: Vec<_> = notes
        .iter()
        .filter(|n| n.receiver.device == y.erased())
        .collect();
    // On bus 1 x's frame; on bus 2 the bridge's copy of it, naming x's port and serial.
    assert_eq!(at_y.len(), 2, "{at_y:?}");
    assert_eq!((at_y[0].sender, at_y[0].bridged), (x.port(0), None));
    assert_eq!(at_y[1].sender, bridge.port(1));
    let end = ms(1) + frame_duration(&f, RATE);
    let want = Bridged {
        sender: x.port(0),
        serial: Some(0),
        wire: end,
    };
    assert_eq!(at_y[1].bridged, Some(want));
}

#[test]
fn a_cleared_bridge_copies_and_acknowledges_nothing() {
    let (mut sim, b) = network(1, 2, RATE);
    let f = std_frame(0x181, &[1]);
    sim.add_device(
        "x",
        Probe::new(1).every(0, f, Instant::ZERO, Duration::from_millis(10)),
        &[b[0]],
    )
    .unwrap();
    let y = sim.add_device("y", Probe::new(1), &[b[1]]).unwrap();
    sim.set_bridge(
        b[0],
        b[1],
        BridgeConfig::new(BridgeDirection::FirstToSecond, Duration::from_millis(1)),
    );
    sim.run_until(ms(15));
    assert_eq!(sim.device(y).rx_on(0).len(), 2);
    sim.clear_bridge();
    sim.run_until(ms(45));
    assert_eq!(sim.device(y).rx_on(0).len(), 2);
    // x alone on bus 1 now: nobody acknowledges its frames.
    assert!(sim.bus_stats(b[0]).lost > 0);
}
