//! Power cycles and reboots.

use super::probe::{std_frame, Probe, ProbeEvent};
use super::{network, tx_records};
use crate::frame::instant::{Duration, Instant};
use crate::sim::timing::frame_duration;
use crate::sim::TxOutcome;

const RATE: u32 = 500_000;
const MS: Duration = Duration::from_millis(1);

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

#[test]
fn a_powered_off_device_hears_nothing_sends_nothing_and_its_timers_stop() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, Instant::ZERO, MS), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.run_until(ms(2) + Duration::from_micros(500));
    assert_eq!(sim.device(l).rx.len(), 3);
    sim.power_off(x);
    assert!(!sim.is_powered(x));
    sim.device_mut(l).send(0, std_frame(0x200, &[]));
    sim.run_until(ms(5) + Duration::from_micros(500));
    assert_eq!(sim.device(l).rx.len(), 3);
    assert!(sim.device(x).rx.is_empty());
    assert!(sim.device(x).timeouts.iter().all(|t| *t <= ms(2)));

    sim.power_on(x);
    sim.run_until(ms(7));
    // Missed deadlines are due at power-on; then the period resumes.
    let after: Vec<_> = sim
        .device(x)
        .timeouts
        .iter()
        .copied()
        .filter(|t| *t > ms(2))
        .collect();
    assert_eq!(after, [ms(5) + Duration::from_micros(500), ms(6), ms(7)]);
    assert!(sim.device(l).rx.len() > 3);
}

#[test]
fn power_off_drops_queued_frames_and_the_one_on_the_wire() {
    let (mut sim, b) = network(1, 1, RATE);
    let x = sim.add_device("x", Probe::new(1), &[b[0]]).unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    for i in 0..3 {
        sim.device_mut(x).send(0, std_frame(0x100, &[i]));
    }
    sim.run_until(Instant::from_micros(10));
    sim.power_off(x);
    assert_eq!(sim.tx_queue_len(x.port(0)), 0);
    sim.run_until(ms(1));
    assert!(sim.device(l).rx.is_empty());
    assert!(sim.device(x).status.is_empty());
    let tx = tx_records(&sim);
    assert_eq!(tx.len(), 1);
    assert_eq!(tx[0].outcome, TxOutcome::SenderOff);
}

#[test]
fn replace_reboots_with_a_fresh_device_that_starts_at_once() {
    let (mut sim, b) = network(1, 1, RATE);
    let f = std_frame(0x181, &[1]);
    let x = sim
        .add_device("x", Probe::new(1).every(0, f, Instant::ZERO, MS), &[b[0]])
        .unwrap();
    let l = sim.add_device("l", Probe::new(1), &[b[0]]).unwrap();
    sim.device_mut(l).send(0, std_frame(0x200, &[]));
    sim.run_until(ms(3) + Duration::from_micros(500));
    let boot = std_frame(0x701, &[0]);
    let mut fresh = Probe::new(1);
    fresh.send(0, boot);
    let old = sim.replace(x, fresh).unwrap();
    assert_eq!(old.rx.len(), 1);
    assert!(sim.device(x).rx.is_empty());
    sim.run_until(ms(5));
    let t = ms(3) + Duration::from_micros(500);
    assert_eq!(
        sim.device(l).rx.last(),
        Some(&(t + frame_duration(&boot, RATE), 0, boot))
    );
    // The fresh probe has no periodic frame: nothing after the boot frame.
    assert_eq!(sim.device(l).rx.len(), 5);
    // The event log spans both lives.
    assert!(matches!(sim.events(x)[0].1, ProbeEvent::Status(..)));
    assert!(sim.replace(x, Probe::new(2)).is_err());
}
