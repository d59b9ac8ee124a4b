//! A controller held error passive: the suspend-transmission time after its own frames, its
//! passive error flags, the states its device is told of.

use super::probe::{std_frame, Probe};
use super::{network, tx_records};
use crate::frame::instant::{Duration, Instant};
use crate::machine::{ErrorCause, PortStatus};
use crate::sim::timing::{bits_duration, frame_duration};
use crate::sim::{FaultRates, TxOutcome};

const RATE: u32 = 500_000;
const LONG: Duration = Duration::from_secs(10);

fn us(n: u64) -> Instant {
    Instant::from_micros(n)
}

/// The suspend-transmission time at [`RATE`]: 8 bit times.
fn suspend() -> Duration {
    bits_duration(8, RATE)
}

#[test]
fn an_error_passive_sender_waits_the_suspend_time_between_its_own_frames() {
    // Two frames queued at once: error active, the second starts as the first ends; error
    // passive, 8 bit times later.
    for passive in [false, true] {
        let (mut sim, b) = network(1, 1, RATE);
        let (f1, f2) = (std_frame(0x100, &[1; 8]), std_frame(0x101, &[2; 8]));
        let x = sim
            .add_device(
                "x",
                Probe::new(1)
                    .every(0, f1, Instant::ZERO, LONG)
                    .every(0, f2, Instant::ZERO, LONG),
                &[b[0]],
            )
            .unwrap();
        sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
        if passive {
            sim.set_port_error_passive(x.port(0), Some(130));
        }
        sim.run_until(us(2_000));
        let tx = tx_records(&sim);
        assert_eq!(tx.len(), 2, "{tx:?}");
        let end1 = Instant::ZERO + frame_duration(&f1, RATE);
        assert_eq!((tx[0].frame, tx[0].end), (f1, end1));
        let want = if passive { end1 + suspend() } else { end1 };
        assert_eq!((tx[1].frame, tx[1].start), (f2, want));
        assert!(tx
            .iter()
            .all(|t| matches!(t.outcome, TxOutcome::Delivered { .. })));
    }
}

#[test]
fn a_frame_queued_during_the_suspend_time_wins_over_the_passive_senders_next_frame() {
    // x (error passive) has two high-priority frames; y queues a low-priority one 4 µs into
    // x's suspend time. The bus is idle then: y's frame starts at once, and x's second frame,
    // whose identifier would have won arbitration, waits until it ends.
    let (mut sim, b) = network(1, 1, RATE);
    let (f1, f2) = (std_frame(0x080, &[1; 8]), std_frame(0x081, &[2; 8]));
    let fy = std_frame(0x700, &[3]);
    let end1 = Instant::ZERO + frame_duration(&f1, RATE);
    let ty = end1 + Duration::from_micros(4);
    let x = sim
        .add_device(
            "x",
            Probe::new(1)
                .every(0, f1, Instant::ZERO, LONG)
                .every(0, f2, Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    sim.add_device("y", Probe::new(1).every(0, fy, ty, LONG), &[b[0]])
        .unwrap();
    sim.set_port_error_passive(x.port(0), Some(200));
    sim.run_until(us(2_000));
    let tx = tx_records(&sim);
    let order: Vec<_> = tx.iter().map(|t| (t.frame, t.start)).collect();
    let endy = ty + frame_duration(&fy, RATE);
    assert_eq!(order, [(f1, Instant::ZERO), (fy, ty), (f2, endy)]);
    // Error active, x's second frame is on the wire when y's arrives, and y's waits.
    let (mut sim, b) = network(1, 1, RATE);
    sim.add_device(
        "x",
        Probe::new(1)
            .every(0, f1, Instant::ZERO, LONG)
            .every(0, f2, Instant::ZERO, LONG),
        &[b[0]],
    )
    .unwrap();
    sim.add_device("y", Probe::new(1).every(0, fy, ty, LONG), &[b[0]])
        .unwrap();
    sim.run_until(us(2_000));
    let order: Vec<_> = tx_records(&sim).iter().map(|t| t.frame).collect();
    assert_eq!(order, [f1, f2, fy]);
}

#[test]
fn a_frame_pending_when_the_passive_senders_frame_ends_goes_first_whatever_its_identifier() {
    // Both ready while x's first frame is on the wire: y's lower priority frame wins the next
    // arbitration, x sitting out its suspend time.
    let (mut sim, b) = network(1, 1, RATE);
    let (f1, f2) = (std_frame(0x080, &[1; 8]), std_frame(0x081, &[2; 8]));
    let fy = std_frame(0x700, &[3]);
    let x = sim
        .add_device(
            "x",
            Probe::new(1)
                .every(0, f1, Instant::ZERO, LONG)
                .every(0, f2, Instant::ZERO, LONG),
            &[b[0]],
        )
        .unwrap();
    sim.add_device("y", Probe::new(1).every(0, fy, us(10), LONG), &[b[0]])
        .unwrap();
    sim.set_port_error_passive(x.port(0), Some(128));
    sim.run_until(us(2_000));
    let order: Vec<_> = tx_records(&sim).iter().map(|t| t.frame).collect();
    assert_eq!(order, [f1, fy, f2]);
}

#[test]
fn the_device_is_told_error_passive_at_once_and_error_active_once_its_counter_is_back_under_128() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1]);
    let period = Duration::from_millis(1);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, us(100), period), &[b[0]])
        .unwrap();
    sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.run_until(us(50));
    sim.set_port_error_passive(x.port(0), Some(130));
    assert!(sim.is_port_error_passive(x.port(0)));
    assert_eq!(sim.port_error_passive_hold(x.port(0)), Some(130));
    assert_eq!(
        sim.device(x).status_on(0),
        [
            (us(50), PortStatus::Error(ErrorCause::ErrorWarning)),
            (us(50), PortStatus::Error(ErrorCause::ErrorPassive)),
        ]
    );
    // Held: frames sent do not bring the counter down.
    sim.run_until(us(5_000));
    assert_eq!(sim.port_tx_errors(x.port(0)), 130);
    // Let go at 5 ms: 130 → 127 after three frames (5.1, 6.1, 7.1 ms), then error active.
    sim.set_port_error_passive(x.port(0), None);
    assert_eq!(sim.port_error_passive_hold(x.port(0)), None);
    sim.run_until(us(7_000));
    assert!(sim.is_port_error_passive(x.port(0)));
    assert_eq!(sim.port_tx_errors(x.port(0)), 128);
    sim.run_until(us(8_000));
    assert!(!sim.is_port_error_passive(x.port(0)));
    assert_eq!(sim.port_tx_errors(x.port(0)), 127);
    let end = us(7_100) + frame_duration(&f, RATE);
    let statuses = sim.device(x).status_on(0);
    assert_eq!(statuses.last(), Some(&(end, PortStatus::Up)));
    // Nothing else told on the way: every frame was a success.
    assert_eq!(
        statuses
            .iter()
            .filter(|(_, s)| *s != PortStatus::TxOk)
            .count(),
        3
    );
}

#[test]
fn an_error_passive_receivers_error_flag_loses_the_frame_for_it_alone() {
    // z detects an error in every frame it receives. Error active, its flag destroys each
    // frame for everybody and the sender retries; error passive, w gets every frame at the
    // first attempt and z none, each reported to z as a CRC error.
    for passive in [false, true] {
        let (mut sim, b) = network(1, 1, RATE);
        let f = std_frame(0x181, &[1, 2]);
        sim.add_device(
            "x",
            Probe::new(1).every(0, f, Instant::ZERO, Duration::from_millis(1)),
            &[b[0]],
        )
        .unwrap();
        let w = sim.add_device("w", Probe::new(1), &[b[0]]).unwrap();
        let z = sim.add_device("z", Probe::new(1), &[b[0]]).unwrap();
        sim.set_port_faults(z.port(0), FaultRates::NONE.with_corrupt_detected(1.0));
        if passive {
            sim.set_port_error_passive(z.port(0), Some(140));
        }
        sim.run_until(us(2_900));
        let tx = tx_records(&sim);
        if passive {
            assert_eq!(tx.len(), 3);
            assert!(tx
                .iter()
                .all(|t| matches!(t.outcome, TxOutcome::Delivered { .. })));
            assert_eq!(sim.device(w).rx_on(0).len(), 3);
            assert!(sim.device(z).rx_on(0).is_empty());
            let crc = sim
                .device(z)
                .status_on(0)
                .iter()
                .filter(|(_, s)| *s == PortStatus::Error(ErrorCause::Crc))
                .count();
            assert_eq!(crc, 3);
        } else {
            assert!(tx.iter().all(|t| t.outcome == TxOutcome::ErrorFrame));
            assert!(sim.device(w).rx_on(0).is_empty());
        }
    }
}

#[test]
fn a_controller_still_held_after_a_reboot_is_error_passive_again() {
    let (mut sim, b) = network(1, 1, RATE);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    sim.set_port_error_passive(x.port(0), Some(1_000));
    // Clamped short of bus-off.
    assert_eq!(sim.port_tx_errors(x.port(0)), 255);
    assert!(!sim.is_port_bus_off(x.port(0)));
    sim.power_off(x);
    assert!(!sim.is_port_error_passive(x.port(0)));
    sim.run_until(us(100));
    sim.power_on(x);
    sim.run_until(us(200));
    assert!(sim.is_port_error_passive(x.port(0)));
    assert_eq!(
        sim.device(x).status_on(0).last(),
        Some(&(us(100), PortStatus::Error(ErrorCause::ErrorPassive)))
    );
}
