//! Every fault has an observable effect.

use super::probe::{std_frame, Probe};
use super::{network, tx_records};
use crate::frame::instant::{Duration, Instant};
use crate::frame::Frame;
use crate::machine::{ErrorCause, PortRequest, PortStatus};
use crate::sim::timing::{bits_duration, error_frame_bits, frame_duration};
use crate::sim::{FaultRates, RxFault, TraceRecord, TxOutcome};

const RATE: u32 = 500_000;
const MS: Duration = Duration::from_millis(1);
const LONG: Duration = Duration::from_secs(100);

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

fn rx_faults(sim: &crate::sim::SimNetwork) -> Vec<(crate::sim::PortRef, RxFault)> {
    sim.trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Rx(r) => Some((r.port, r.fault)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_bus_down_reaches_nobody_and_senders_get_no_ack_after_the_frame_time() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1, 2]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, Instant::ZERO, MS), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.bus_down(b[0]);
    sim.run_until(Instant::from_micros(500));
    let d = frame_duration(&f, RATE);
    assert_eq!(
        sim.device(x).status_on(0),
        vec![(Instant::ZERO + d, PortStatus::TxFailed(ErrorCause::NoAck))]
    );
    assert!(sim.device(l).rx.is_empty());
    assert_eq!(tx_records(&sim)[0].outcome, TxOutcome::BusDown);
    assert_eq!(sim.bus_stats(b[0]).lost, 1);

    sim.bus_up(b[0]);
    sim.run_until(ms(2));
    assert_eq!(sim.device(l).rx_on(0), vec![(ms(1) + d, f)]);
}

#[test]
fn a_disconnected_port_is_alone_while_the_rest_of_the_bus_carries_on() {
    let (mut sim, b) = network(1, 1, RATE);
    let fx = std_frame(0x100, &[1]);
    let fy = std_frame(0x200, &[2]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, fx, Instant::ZERO, MS), &[b[0]])
        .unwrap();
    let y = sim
        .add_device("y", Probe::new(1).every(0, fy, Instant::ZERO, MS), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.disconnect(x.port(0));
    assert!(!sim.is_connected(x.port(0)));
    sim.run_until(Instant::from_micros(900));
    // x no longer wins arbitration: y starts at once.
    let (dx, dy) = (frame_duration(&fx, RATE), frame_duration(&fy, RATE));
    assert_eq!(sim.device(l).rx_on(0), vec![(Instant::ZERO + dy, fy)]);
    assert!(sim.device(x).rx.is_empty());
    assert_eq!(
        sim.device(x).status_on(0),
        vec![(Instant::ZERO + dx, PortStatus::TxFailed(ErrorCause::NoAck))]
    );
    let tx = tx_records(&sim);
    assert_eq!(
        tx.iter()
            .filter(|t| t.outcome == TxOutcome::SenderDisconnected)
            .count(),
        1
    );
    assert!(sim.device(y).rx.is_empty());

    sim.reconnect(x.port(0));
    sim.run_until(ms(2) - Duration::from_micros(100));
    assert_eq!(
        sim.device(l).rx_on(0)[1..],
        [(ms(1) + dx, fx), (ms(1) + dx + dy, fy)]
    );
    assert_eq!(sim.device(x).rx_on(0), vec![(ms(1) + dx + dy, fy)]);
}

#[test]
fn partitions_run_their_own_arbitration_until_healed() {
    let (mut sim, b) = network(1, 1, RATE);
    let f1 = std_frame(0x101, &[1]);
    let f2 = std_frame(0x102, &[2]);
    let w = sim
        .add_device("w", Probe::new(1).every(0, f1, Instant::ZERO, MS), &[b[0]])
        .unwrap();
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let y = sim
        .add_device("y", Probe::new(1).every(0, f2, Instant::ZERO, MS), &[b[0]])
        .unwrap();
    let z = sim.add_device("z", Probe::new(1), &[b[0]]).unwrap();
    sim.partition(b[0], &[&[w.port(0), x.port(0)]]);
    sim.run_until(Instant::from_micros(900));
    let (d1, d2) = (frame_duration(&f1, RATE), frame_duration(&f2, RATE));
    // Both frames start at 0, each on its own side.
    assert_eq!(sim.device(x).rx_on(0), vec![(Instant::ZERO + d1, f1)]);
    assert_eq!(sim.device(z).rx_on(0), vec![(Instant::ZERO + d2, f2)]);
    assert!(sim.device(w).rx.is_empty());
    assert!(sim.device(y).rx.is_empty());
    let segments: Vec<_> = tx_records(&sim).iter().map(|t| t.segment).collect();
    // Equal lengths: both end together, completed in segment order.
    assert_eq!(d1, d2);
    assert_eq!(segments, vec![0, 1]);

    sim.heal(b[0]);
    sim.run_until(ms(2) - Duration::from_micros(100));
    assert_eq!(
        sim.device(z).rx_on(0)[1..],
        [(ms(1) + d1, f1), (ms(1) + d1 + d2, f2)]
    );
    assert_eq!(sim.device(w).rx_on(0), vec![(ms(1) + d1 + d2, f2)]);
}

#[test]
fn a_partition_cuts_frames_on_the_wire_short_and_they_are_resent() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x101, &[1]);
    let w = sim
        .add_device("w", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let bus = b[0];
    sim.at(Instant::from_micros(20), move |s| {
        s.partition(bus, &[&[w.port(0), x.port(0)]]);
    });
    sim.run_until(ms(1));
    let tx = tx_records(&sim);
    assert_eq!(tx[0].outcome, TxOutcome::Aborted);
    assert_eq!(tx[0].end, Instant::from_micros(20));
    let end = Instant::from_micros(20) + frame_duration(&f, RATE);
    assert_eq!(sim.device(x).rx_on(0), vec![(end, f)]);
}

#[test]
fn a_dropping_port_misses_the_frame_and_reports_rx_overflow() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1]);
    sim.add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let l1 = sim.add_device("l1", Probe::new(1), &[b[0]]).unwrap();
    let l2 = sim.add_device("l2", Probe::new(1), &[b[0]]).unwrap();
    sim.set_port_faults(l1.port(0), FaultRates::NONE.with_drop(1.0));
    sim.run_until(ms(1));
    let end = Instant::ZERO + frame_duration(&f, RATE);
    assert!(sim.device(l1).rx.is_empty());
    assert_eq!(
        sim.device(l1).status,
        vec![(end, 0, PortStatus::Error(ErrorCause::RxOverflow))]
    );
    assert_eq!(sim.device(l2).rx_on(0), vec![(end, f)]);
    assert_eq!(sim.port_stats(l1.port(0)).rx_dropped, 1);
    assert_eq!(rx_faults(&sim), vec![(l1.port(0), RxFault::Dropped)]);
}

#[test]
fn every_nth_frame_is_lost_at_the_port_or_for_the_whole_bus() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1]);
    sim.add_device("x", Probe::new(1).every(0, f, Instant::ZERO, MS), &[b[0]])
        .unwrap();
    let l1 = sim.add_device("l1", Probe::new(1), &[b[0]]).unwrap();
    let l2 = sim.add_device("l2", Probe::new(1), &[b[0]]).unwrap();
    // Frames at 0, 1, …, 8 ms: l1 misses the 3rd, 6th and 9th; l2 all of them.
    sim.drop_every(l1.port(0), 3);
    sim.run_until(Instant::from_micros(8_500));
    assert_eq!(sim.device(l1).rx.len(), 6);
    assert_eq!(sim.device(l2).rx.len(), 9);
    assert_eq!(sim.port_stats(l1.port(0)).rx_dropped, 3);
    let overflow = sim
        .device(l1)
        .status
        .iter()
        .filter(|s| s.2 == PortStatus::Error(ErrorCause::RxOverflow))
        .count();
    assert_eq!(overflow, 3);
    // On the bus: every 2nd frame from now on is lost for both.
    sim.drop_every(l1.port(0), 0);
    sim.drop_every_on_bus(b[0], 2);
    sim.run_until(Instant::from_micros(12_500));
    assert_eq!(sim.device(l1).rx.len(), 8);
    assert_eq!(sim.device(l2).rx.len(), 11);
    assert_eq!(sim.port_stats(l2.port(0)).rx_dropped, 2);
}

#[test]
fn a_duplicating_bus_hands_every_receiver_the_frame_twice() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1]);
    sim.add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.set_bus_faults(b[0], FaultRates::NONE.with_duplicate(1.0));
    sim.run_until(ms(1));
    let end = Instant::ZERO + frame_duration(&f, RATE);
    assert_eq!(sim.device(l).rx_on(0), vec![(end, f), (end, f)]);
    assert_eq!(sim.port_stats(l.port(0)).rx_duplicated, 1);
    assert_eq!(sim.port_stats(l.port(0)).rx, 2);
    assert_eq!(rx_faults(&sim), vec![(l.port(0), RxFault::Duplicated)]);
}

#[test]
fn delayed_frames_arrive_late_but_in_order() {
    let (mut sim, b) = network(3, 1, RATE);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let slow = sim.add_device("slow", Probe::new(1), &[b[0]]).unwrap();
    let fast = sim.add_device("fast", Probe::new(1), &[b[0]]).unwrap();
    let max = Duration::from_micros(2_000);
    sim.set_port_faults(slow.port(0), FaultRates::NONE.with_delay(0.5, max));
    for i in 0..40u8 {
        sim.device_mut(x).send(0, std_frame(0x200, &[i]));
    }
    sim.run_until(ms(20));
    let on_time = sim.device(fast).rx_on(0);
    let late = sim.device(slow).rx_on(0);
    assert_eq!(on_time.len(), 40);
    assert_eq!(
        late.iter().map(|(_, f)| *f).collect::<Vec<_>>(),
        on_time.iter().map(|(_, f)| *f).collect::<Vec<_>>()
    );
    let mut delayed = 0;
    for ((t_wire, _), (t_rx, _)) in on_time.iter().zip(&late) {
        assert!(t_rx >= t_wire && *t_rx <= *t_wire + max);
        delayed += usize::from(t_rx > t_wire);
    }
    assert!(delayed >= 10, "{delayed}");
    let untils: Vec<_> = rx_faults(&sim)
        .into_iter()
        .filter_map(|(_, f)| match f {
            RxFault::Delayed { until } => Some(until),
            _ => None,
        })
        .collect();
    assert_eq!(untils.len() as u64, sim.port_stats(slow.port(0)).rx_delayed);
    assert!(untils.iter().all(|u| late.iter().any(|(t, _)| t == u)));
}

#[test]
fn a_port_whose_sends_are_corrupted_has_only_its_own_frames_destroyed() {
    // A ground shift at one node: every frame it sends is destroyed until it stops, each
    // retried; another sender on the same bus goes through at its first attempt.
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1, 2, 3]);
    let g = std_frame(0x182, &[4]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    sim.add_device("y", Probe::new(1).every(0, g, ms(2), LONG), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.set_port_faults(x.port(0), FaultRates::NONE.with_corrupt_sent(1.0));
    let port = x.port(0);
    sim.at(ms(1), move |s| s.set_port_faults(port, FaultRates::NONE));
    sim.run_until(ms(4));
    hit_until_1ms_then_through(&sim, f, g);
    assert_eq!(sim.device(l).rx_on(0).len(), 2);
}

/// `hit` was destroyed at every attempt that started before 1 ms, then delivered; `spared` went
/// through at its first attempt.
fn hit_until_1ms_then_through(sim: &crate::sim::SimNetwork, hit: Frame, spared: Frame) {
    let tx = tx_records(sim);
    let of = |frame: Frame| {
        tx.iter()
            .filter(move |t| t.frame == frame)
            .collect::<Vec<_>>()
    };
    let (xs, ys) = (of(hit), of(spared));
    assert!(xs.len() > 2, "{xs:?}");
    assert!(xs[..xs.len() - 1]
        .iter()
        .all(|t| t.outcome == TxOutcome::ErrorFrame && t.start < ms(1)));
    assert!(matches!(
        xs.last().unwrap().outcome,
        TxOutcome::Delivered { .. }
    ));
    assert_eq!(ys.len(), 1);
    assert!(matches!(ys[0].outcome, TxOutcome::Delivered { .. }));
}

#[test]
fn a_bus_that_destroys_long_frames_lets_short_ones_pass() {
    // Reflections: every frame of 5 data bytes or more is destroyed until 1 ms, each retried;
    // a one-byte frame on the same bus goes through at its first attempt.
    let (mut sim, b) = network(1, 1, RATE);
    let long = std_frame(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]);
    let short = std_frame(0x701, &[5]);
    sim.add_device(
        "x",
        Probe::new(1).every(0, long, Instant::ZERO, LONG),
        &[b[0]],
    )
    .unwrap();
    sim.add_device("y", Probe::new(1).every(0, short, ms(2), LONG), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.set_bus_faults(b[0], FaultRates::NONE.with_corrupt_long(1.0, 5));
    let bus = b[0];
    sim.at(ms(1), move |s| s.set_bus_faults(bus, FaultRates::NONE));
    sim.run_until(ms(4));
    hit_until_1ms_then_through(&sim, long, short);
    assert_eq!(sim.device(l).rx_on(0).len(), 2);
    // Four bytes are short of the threshold: never destroyed.
    let (mut sim, b) = network(1, 1, RATE);
    let four = std_frame(0x182, &[1, 2, 3, 4]);
    sim.add_device(
        "x",
        Probe::new(1).every(0, four, Instant::ZERO, LONG),
        &[b[0]],
    )
    .unwrap();
    sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.set_bus_faults(b[0], FaultRates::NONE.with_corrupt_long(1.0, 5));
    sim.run_until(ms(1));
    let tx = tx_records(&sim);
    assert_eq!(tx.len(), 1);
    assert!(matches!(tx[0].outcome, TxOutcome::Delivered { .. }));
}

#[test]
fn detected_corruption_makes_error_frames_and_the_sender_retries() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1, 2, 3]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.set_bus_faults(b[0], FaultRates::NONE.with_corrupt_detected(1.0));
    let bus = b[0];
    sim.at(ms(1), move |s| s.set_bus_faults(bus, FaultRates::NONE));
    sim.run_until(ms(3));

    let err = bits_duration(error_frame_bits(&f), RATE);
    let tx = tx_records(&sim);
    let errors = tx.len() - 1;
    // Every attempt that started before 1 ms is destroyed; each costs the error frame's time.
    assert_eq!(errors as u64, (ms(1).as_micros() - 1) / err.as_micros() + 1);
    for (i, t) in tx[..errors].iter().enumerate() {
        assert_eq!(t.outcome, TxOutcome::ErrorFrame);
        assert_eq!(t.start, Instant::ZERO + err.saturating_mul(i as u64));
    }
    let last = &tx[errors];
    assert_eq!(last.outcome, TxOutcome::Delivered { receivers: 1 });
    assert_eq!(last.end, last.start + frame_duration(&f, RATE));
    assert_eq!(sim.device(l).rx_on(0), vec![(last.end, f)]);
    let crc = PortStatus::Error(ErrorCause::Crc);
    assert_eq!(
        sim.device(l).status.iter().filter(|s| s.2 == crc).count(),
        errors
    );
    assert_eq!(
        sim.device(x).status.iter().filter(|s| s.2 == crc).count(),
        errors
    );
    assert_eq!(
        sim.device(x).status.last(),
        Some(&(last.end, 0, PortStatus::TxOk))
    );
    assert_eq!(sim.bus_stats(b[0]).error_frames, errors as u64);
}

#[test]
fn a_frame_a_reinit_flushed_while_on_the_wire_is_not_retried_after_its_error() {
    // Every attempt is destroyed; the port is re-initialised in the middle of one: that
    // attempt ends with its error frame, and nothing is sent after it (a controller reset
    // drops what it was sending; retried, a frame the layer flushed came out late).
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1, 2, 3]);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.set_bus_faults(b[0], FaultRates::NONE.with_corrupt_detected(1.0));
    sim.device_mut(x).send(0, f);
    let err = bits_duration(error_frame_bits(&f), RATE);
    let mid = Instant::ZERO + err.saturating_mul(3) + Duration::from_micros(err.as_micros() / 2);
    sim.at(mid, move |s| {
        s.device_mut(x).request(0, PortRequest::Reinit)
    });
    sim.run_until(ms(3));
    let tx = tx_records(&sim);
    assert_eq!(tx.len(), 4);
    assert!(tx.iter().all(|t| t.outcome == TxOutcome::ErrorFrame));
}

#[test]
fn undetected_corruption_flips_one_data_bit() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[0; 8]);
    sim.add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let l1 = sim.add_device("l1", Probe::new(1), &[b[0]]).unwrap();
    let l2 = sim.add_device("l2", Probe::new(1), &[b[0]]).unwrap();
    sim.set_bus_faults(b[0], FaultRates::NONE.with_corrupt_undetected(1.0));
    sim.run_until(ms(1));
    let got1 = sim.device(l1).rx[0].2;
    let got2 = sim.device(l2).rx[0].2;
    // A flip on the wire: everyone sees the same wrong frame.
    assert_eq!(got1, got2);
    assert_eq!(got1.id(), f.id());
    let flipped: u32 = got1.data().iter().map(|b| b.count_ones()).sum();
    assert_eq!(flipped, 1);
    assert_eq!(
        rx_faults(&sim),
        vec![
            (l1.port(0), RxFault::Corrupted { delivered: got1 }),
            (l2.port(0), RxFault::Corrupted { delivered: got1 })
        ]
    );

    // As a port rate, only that receiver is affected.
    let (mut sim, b) = network(1, 1, RATE);
    sim.add_device("x", Probe::new(1).every(0, f, Instant::ZERO, LONG), &[b[0]])
        .unwrap();
    let l1 = sim.add_device("l1", Probe::new(1), &[b[0]]).unwrap();
    let l2 = sim.add_device("l2", Probe::new(1), &[b[0]]).unwrap();
    sim.set_port_faults(l1.port(0), FaultRates::NONE.with_corrupt_undetected(1.0));
    sim.run_until(ms(1));
    assert_ne!(sim.device(l1).rx[0].2, f);
    assert_eq!(sim.device(l2).rx[0].2, f);
    assert_eq!(sim.port_stats(l1.port(0)).rx_corrupted, 1);
}

#[test]
fn a_babbling_port_floods_its_bus_while_the_other_bus_carries_on() {
    let rate = 125_000;
    let (mut sim, b) = network(1, 2, rate);
    let f = std_frame(0x300, &[7]);
    let s = sim
        .add_device(
            "s",
            Probe::new(2)
                .every(0, f, Instant::ZERO, MS)
                .every(1, f, Instant::ZERO, MS),
            &[b[0], b[1]],
        )
        .unwrap();
    let l = sim.add_device("l", Probe::new(2), &[b[0], b[1]]).unwrap();
    let bab = sim.add_device("bab", Probe::new(1), &[b[0]]).unwrap();
    let junk = std_frame(0x001, &[0xFF; 8]);
    sim.babble(bab.port(0), Some(junk));
    sim.run_until(ms(20) - Duration::from_micros(1));

    let d = frame_duration(&f, rate);
    let expected: Vec<_> = (0..20).map(|k| (ms(k) + d, f)).collect();
    assert_eq!(sim.device(l).rx_on(1), expected);
    let on_a = sim.device(l).rx_on(0);
    assert!(on_a.len() > 15);
    assert!(on_a.iter().all(|(_, g)| *g == junk));
    assert_eq!(sim.tx_queue_len(s.port(0)), 20);
    // The babbling controller's frames are not the device's business.
    assert!(sim.device(bab).status.is_empty());
    let load = sim.bus_stats(b[0]).load(Duration::from_millis(20));
    assert!(load > 0.95, "{load}");

    sim.babble(bab.port(0), None);
    sim.run_until(ms(60));
    assert_eq!(
        sim.device(l)
            .rx_on(0)
            .iter()
            .filter(|(_, g)| *g == f)
            .count(),
        60
    );
}

#[test]
fn a_full_tx_queue_holds_the_device_back_and_loses_nothing() {
    let (mut sim, b) = network(1, 1, RATE);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.set_tx_capacity(x.port(0), 2);
    let frames: Vec<_> = (0..5).map(|i| std_frame(0x200, &[i])).collect();
    for f in &frames {
        sim.device_mut(x).send(0, *f);
    }
    sim.run_until(Instant::ZERO);
    // One frame on the wire, two queued, two still with the device.
    assert_eq!(sim.tx_queue_len(x.port(0)), 2);
    assert!(sim.port_stats(x.port(0)).tx_blocked >= 1);
    sim.run_until(ms(5));
    assert!(
        sim.device(x)
            .status
            .iter()
            .all(|s| !matches!(s.2, PortStatus::TxFailed(_))),
        "back-pressure, not failures"
    );
    let got: Vec<_> = sim.device(l).rx.iter().map(|r| r.2).collect();
    assert_eq!(got, frames, "every frame, in order");
    // Back to back: each frame starts when the previous one ends.
    let tx = tx_records(&sim);
    for w in tx.windows(2) {
        assert_eq!(w[1].start, w[0].end);
    }
}

#[test]
fn an_interface_down_fails_frames_at_once_and_hears_nothing() {
    let (mut sim, b) = network(1, 1, RATE);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let y = sim.add_device("y", Probe::new(1), &[b[0]]).unwrap();
    sim.run_until(ms(1));
    sim.port_down(x.port(0));
    sim.device_mut(x).send(0, std_frame(0x100, &[]));
    sim.device_mut(y).send(0, std_frame(0x200, &[]));
    sim.run_until(ms(2));
    assert_eq!(
        sim.device(x).status,
        vec![
            (ms(1), 0, PortStatus::Down(ErrorCause::InterfaceDown)),
            (ms(1), 0, PortStatus::TxFailed(ErrorCause::InterfaceDown)),
        ]
    );
    assert!(sim.device(x).rx.is_empty());
    // Alone on the bus now.
    assert_eq!(
        sim.device(y).status[0].2,
        PortStatus::TxFailed(ErrorCause::NoAck)
    );
    sim.port_up(x.port(0));
    assert_eq!(sim.device(x).status[2], (ms(2), 0, PortStatus::Up));
    sim.device_mut(y).send(0, std_frame(0x200, &[]));
    sim.run_until(ms(3));
    assert_eq!(sim.device(x).rx.len(), 1);
}
