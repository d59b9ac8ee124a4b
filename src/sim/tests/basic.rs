//! Wire timing, arbitration, scheduling and the driver contract.

use super::probe::{std_frame, Probe, ProbeEvent};
use super::{network, tx_records};
use crate::frame::instant::{Duration, Instant};
use crate::frame::{Frame, Id};
use crate::machine::{ErrorCause, PortRequest, PortStatus};
use crate::sim::timing::frame_duration;
use crate::sim::{SimError, TxOutcome};
use std::cell::RefCell;
use std::rc::Rc;

const MBIT: u32 = 1_000_000;
const LONG: Duration = Duration::from_secs(100);

fn at(us: u64) -> Instant {
    Instant::from_micros(us)
}

#[test]
fn lower_identifier_wins_and_the_loser_follows_back_to_back() {
    let (mut sim, b) = network(1, 1, MBIT);
    let hi = std_frame(0x200, &[1, 2, 3, 4]);
    let lo = std_frame(0x100, &[5]);
    let x = sim
        .add_device(
            "x",
            Probe::new(1).every(0, hi, Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    let y = sim
        .add_device(
            "y",
            Probe::new(1).every(0, lo, Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.run_until(Instant::from_millis(1));

    let (d_lo, d_hi) = (frame_duration(&lo, MBIT), frame_duration(&hi, MBIT));
    let end_lo = Instant::ZERO + d_lo;
    let end_hi = end_lo + d_hi;
    assert_eq!(sim.device(l).rx_on(0), vec![(end_lo, lo), (end_hi, hi)]);
    assert_eq!(sim.device(x).rx_on(0), vec![(end_lo, lo)]);
    assert_eq!(sim.device(y).rx_on(0), vec![(end_hi, hi)]);
    assert_eq!(sim.device(y).status_on(0), vec![(end_lo, PortStatus::TxOk)]);
    assert_eq!(sim.device(x).status_on(0), vec![(end_hi, PortStatus::TxOk)]);

    let tx = tx_records(&sim);
    assert_eq!(tx.len(), 2);
    assert_eq!(
        (tx[0].start, tx[0].end, tx[0].sender),
        (Instant::ZERO, end_lo, y.port(0))
    );
    assert_eq!(
        (tx[1].start, tx[1].end, tx[1].sender),
        (end_lo, end_hi, x.port(0))
    );
    assert_eq!(&*tx[1].sender_name, "x");
    assert_eq!(tx[1].outcome, TxOutcome::Delivered { receivers: 2 });
    assert_eq!(sim.bus_stats(b[0]).busy_time, d_lo + d_hi);
}

#[test]
fn exact_microseconds_for_a_known_frame() {
    // 0x000 with no data is 53 bits: 53 µs at 1 Mbit/s, 106 µs at 500 kbit/s.
    for (rate, us) in [(MBIT, 53), (500_000, 106)] {
        let (mut sim, b) = network(1, 1, rate);
        let f = std_frame(0, &[]);
        sim.add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
            .unwrap();
        let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
        sim.run_until(Instant::from_millis(1));
        assert_eq!(sim.device(l).rx_on(0), vec![(at(us), f)]);
    }
}

#[test]
fn exact_ties_go_to_the_lower_device_and_standard_beats_extended() {
    let (mut sim, b) = network(1, 1, MBIT);
    let same = std_frame(0x300, &[]);
    let ext = Frame::new(Id::Extended(0x100 << 18), &[]).unwrap();
    let std_ = std_frame(0x100, &[]);
    let e = sim
        .add_device(
            "e",
            Probe::new(1).every(0, ext, Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    let x = sim
        .add_device(
            "x",
            Probe::new(1).every(0, same, Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    let y = sim
        .add_device(
            "y",
            Probe::new(1).every(0, same, Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    let s = sim
        .add_device(
            "s",
            Probe::new(1).every(0, std_, Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    sim.run_until(Instant::from_millis(1));
    let senders: Vec<_> = tx_records(&sim).iter().map(|t| t.sender).collect();
    assert_eq!(senders, vec![s.port(0), e.port(0), x.port(0), y.port(0)]);
}

#[test]
fn a_frame_nobody_else_hears_fails_with_no_ack() {
    let (mut sim, b) = network(1, 1, MBIT);
    let f = std_frame(0x181, &[1]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    sim.run_until(Instant::from_millis(1));
    let end = Instant::ZERO + frame_duration(&f, MBIT);
    assert_eq!(
        sim.device(x).status_on(0),
        vec![(end, PortStatus::TxFailed(ErrorCause::NoAck))]
    );
    assert_eq!(tx_records(&sim)[0].outcome, TxOutcome::NoAck);
}

#[test]
fn a_frame_queued_through_device_mut_goes_out_at_the_current_instant() {
    let (mut sim, b) = network(1, 1, MBIT);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.run_until(Instant::from_millis(5));
    let f = std_frame(0x701, &[0x05]);
    sim.device_mut(x).send(0, f);
    assert_eq!(sim.device(x).timeouts.last(), Some(&Instant::ZERO));
    sim.run_until(Instant::from_millis(6));
    // The touched device was driven at 5 ms before anything else.
    assert_eq!(
        sim.device(x).timeouts.last(),
        Some(&Instant::from_millis(5))
    );
    let tx = tx_records(&sim);
    assert_eq!(tx[0].start, Instant::from_millis(5));
    assert_eq!(
        sim.device(l).rx_on(0),
        vec![(Instant::from_millis(5) + frame_duration(&f, MBIT), f)]
    );
}

#[test]
fn actions_run_by_time_then_insertion_after_deliveries_before_timeouts() {
    let (mut sim, b) = network(1, 1, MBIT);
    let f = std_frame(0x100, &[]);
    let end = Instant::ZERO + frame_duration(&f, MBIT);
    sim.add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    // l has a timer exactly when x's frame ends.
    let l = sim
        .add_device(
            "l",
            Probe::new(1).every(0, std_frame(0x7FF, &[]), end, LONG),
            &[b[0]],
        )
        .unwrap();
    let log = Rc::new(RefCell::new(Vec::new()));
    let push = |log: &Rc<RefCell<Vec<String>>>, s: &str| log.borrow_mut().push(s.to_string());
    let (l1, l2, l3) = (log.clone(), log.clone(), log.clone());
    sim.at(end, move |s| {
        push(&l1, "a");
        // The frame ending now was delivered, l's timer has not run yet.
        assert_eq!(s.device(l).rx.len(), 1);
        assert!(!s.device(l).timeouts.contains(&end));
        let l4 = l1.clone();
        s.at(s.now(), move |_| push(&l4, "a2"));
    });
    sim.at(end, move |_| push(&l2, "b"));
    sim.at(Instant::from_micros(10), move |s| {
        assert_eq!(s.now(), Instant::from_micros(10));
        push(&l3, "c");
    });
    sim.run_until(Instant::from_millis(1));
    assert_eq!(*log.borrow(), vec!["c", "a", "b", "a2"]);
    assert!(sim.device(l).timeouts.contains(&end));
}

#[test]
fn step_processes_one_instant_at_a_time() {
    let (mut sim, b) = network(1, 1, MBIT);
    let f = std_frame(0x100, &[]);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    assert_eq!(sim.step(), None);
    sim.device_mut(x).send(0, f);
    sim.device_mut(x).send(0, f);
    let d = frame_duration(&f, MBIT);
    assert_eq!(sim.step(), Some(Instant::ZERO + d));
    assert_eq!(sim.now(), Instant::ZERO + d);
    assert_eq!(sim.step(), Some(Instant::ZERO + d + d));
    assert_eq!(sim.step(), None);
}

#[test]
fn events_are_logged_with_their_instant_and_can_be_taken() {
    let (mut sim, b) = network(1, 1, MBIT);
    let f = std_frame(0x100, &[9]);
    sim.add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.run_until(Instant::from_millis(1));
    let end = Instant::ZERO + frame_duration(&f, MBIT);
    assert_eq!(sim.events(l), &[(end, ProbeEvent::Rx(0, f))]);
    assert_eq!(sim.take_events(l).len(), 1);
    assert!(sim.events(l).is_empty());
}

#[test]
fn reinit_flushes_the_queue_and_reports_up() {
    let (mut sim, b) = network(1, 1, MBIT);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    let frames: Vec<_> = (0..3).map(|i| std_frame(0x200, &[i])).collect();
    for f in &frames {
        sim.device_mut(x).send(0, *f);
    }
    sim.run_until(at(10));
    sim.device_mut(x).request(0, PortRequest::Reinit);
    sim.run_until(Instant::from_millis(1));
    let end = Instant::ZERO + frame_duration(&frames[0], MBIT);
    // The frame on the wire completes; the two queued ones are gone.
    assert_eq!(sim.device(l).rx_on(0), vec![(end, frames[0])]);
    assert_eq!(
        sim.device(x).status_on(0),
        vec![(at(10), PortStatus::Up), (end, PortStatus::TxOk)]
    );
    // A disconnected port reopens without reporting Up.
    sim.disconnect(x.port(0));
    sim.device_mut(x).request(0, PortRequest::Reinit);
    sim.run_for(Duration::from_millis(1));
    assert_eq!(sim.device(x).status.len(), 2);
}

#[test]
fn a_device_needs_one_bus_per_port() {
    let (mut sim, b) = network(1, 1, MBIT);
    assert_eq!(
        sim.add_device("x", Probe::new(2), &[b[0]]).err(),
        Some(SimError::PortCount { ports: 2, buses: 1 })
    );
    assert_eq!(sim.device_count(), 0);
}

#[test]
fn frames_to_ports_a_device_lacks_are_counted_not_sent() {
    let (mut sim, b) = network(1, 1, MBIT);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    sim.device_mut(x).send(3, std_frame(1, &[]));
    sim.run_for(Duration::from_millis(1));
    assert_eq!(sim.misaddressed(x), 1);
    assert!(sim.trace().is_empty());
}
