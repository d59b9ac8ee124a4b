//! A port whose transmitter reaches nobody: bit errors, error passive, bus-off, restart.

use super::network;
use super::probe::{std_frame, Probe};
use crate::frame::instant::{Duration, Instant};
use crate::machine::{ErrorCause, PortRequest, PortStatus};
use crate::sim::timing::{bits_duration, frame_duration};

const RATE: u32 = 500_000;

fn us(n: u64) -> Instant {
    Instant::from_micros(n)
}

#[test]
fn a_dead_transmitter_fails_every_attempt_goes_bus_off_and_restarts_while_it_still_receives() {
    let (mut sim, b) = network(1, 1, RATE);
    let fx = std_frame(0x181, &[1]);
    let fz = std_frame(0x100, &[2]);
    let period = Duration::from_millis(10);
    let x = sim
        .add_device(
            "x",
            Probe::new(1).every(0, fx, Instant::ZERO, period),
            &[b[0]],
        )
        .unwrap();
    let y = sim.add_device("y", Probe::new(1), &[b[0]]).unwrap();
    let z = sim
        .add_device(
            "z",
            Probe::new(1).every(0, fz, us(500), Duration::from_millis(1)),
            &[b[0]],
        )
        .unwrap();
    sim.set_port_tx_dead(x.port(0), true);
    assert!(sim.is_port_tx_dead(x.port(0)));
    sim.run_until(us(1_000));
    // 16 attempts of 18 bit times (36 µs), then 8 of 26 (52 µs, error passive): 24 × 8.
    assert_eq!(sim.port_tx_errors(x.port(0)), 192);
    // 16 attempts error active (36 µs each), 16 error passive (52 µs): bus-off at 1,408 µs.
    let off = us(16 * 36 + 16 * 52);
    sim.run_until(off);
    assert!(sim.is_port_bus_off(x.port(0)));
    let mut want = vec![];
    let mut t = 0;
    for k in 1..=32u64 {
        t += if k <= 16 { 36 } else { 52 };
        want.push((us(t), PortStatus::Error(ErrorCause::Bit)));
        match k {
            12 => want.push((us(t), PortStatus::Error(ErrorCause::ErrorWarning))),
            16 => want.push((us(t), PortStatus::Error(ErrorCause::ErrorPassive))),
            32 => want.push((us(t), PortStatus::Down(ErrorCause::BusOff))),
            _ => {}
        }
    }
    assert_eq!(sim.device(x).status_on(0), want);
    // It heard z's frame while it failed; nobody heard it.
    let d = frame_duration(&fz, RATE);
    assert_eq!(sim.device(x).rx_on(0), vec![(us(500) + d, fz)]);
    assert!(sim.device(y).rx.iter().all(|(_, _, f)| *f == fz));
    assert_eq!(sim.port_stats(x.port(0)).tx_attempts, 32);
    assert_eq!(sim.tx_queue_len(x.port(0)), 0, "bus-off drops what it held");

    // Bus-off: nothing received, until the restart after 128 × 11 recessive bit times.
    let restart = off + bits_duration(128 * 11, RATE);
    sim.run_until(restart - Duration::from_micros(1));
    assert_eq!(
        sim.device(x).rx_on(0).len(),
        1,
        "z's frame at 1.5 ms missed"
    );
    assert!(sim.device(y).rx_on(0).len() >= 2);
    sim.run_until(restart);
    assert!(!sim.is_port_bus_off(x.port(0)));
    assert_eq!(sim.port_tx_errors(x.port(0)), 0);
    assert_eq!(
        sim.device(x).status_on(0).last(),
        Some(&(restart, PortStatus::Up))
    );
    sim.run_until(us(9_000));
    // Nothing to send until 10 ms: error active and receiving again.
    assert_eq!(sim.port_tx_errors(x.port(0)), 0);
    assert!(sim.device(x).rx_on(0).len() >= 4);

    // Its next frame fails again; repaired, the one after that goes out.
    sim.run_until(us(10_100));
    assert_eq!(sim.port_tx_errors(x.port(0)), 16);
    sim.set_port_tx_dead(x.port(0), false);
    sim.run_until(us(10_400));
    assert!(sim.device(y).rx_on(0).iter().any(|(_, f)| *f == fx));
    assert_eq!(
        sim.port_tx_errors(x.port(0)),
        15,
        "one frame sent: one less"
    );
    assert!(sim
        .device(z)
        .status_on(0)
        .iter()
        .all(|(_, s)| *s == PortStatus::TxOk));
}

#[test]
fn a_dead_transmitter_acknowledges_nothing_and_a_reinit_restarts_it_from_bus_off() {
    let (mut sim, b) = network(1, 1, RATE);
    let fx = std_frame(0x181, &[1]);
    let fz = std_frame(0x100, &[2]);
    let x = sim
        .add_device(
            "x",
            Probe::new(1).every(0, fx, Instant::ZERO, Duration::from_secs(1)),
            &[b[0]],
        )
        .unwrap();
    let z = sim
        .add_device(
            "z",
            Probe::new(1).every(0, fz, us(100), Duration::from_secs(1)),
            &[b[0]],
        )
        .unwrap();
    sim.set_port_tx_dead(x.port(0), true);
    sim.run_until(us(500));
    // Alone with a dead transmitter, z's frame is not acknowledged: nobody gets it.
    let d = frame_duration(&fz, RATE);
    assert_eq!(
        sim.device(z).status_on(0)[0],
        (us(100) + d, PortStatus::TxFailed(ErrorCause::NoAck))
    );
    assert!(sim.device(x).rx.is_empty());
    sim.run_until(us(1_500));
    assert!(sim.is_port_bus_off(x.port(0)));
    sim.device_mut(x).request(0, PortRequest::Reinit);
    sim.run_until(us(1_501));
    assert!(!sim.is_port_bus_off(x.port(0)));
    assert_eq!(
        sim.device(x).status_on(0).last(),
        Some(&(us(1_500), PortStatus::Up))
    );
    // A power cycle starts the controller afresh too.
    sim.device_mut(x).send(0, fx);
    sim.run_until(us(3_000));
    assert!(sim.is_port_bus_off(x.port(0)));
    sim.power_off(x);
    sim.power_on(x);
    assert!(!sim.is_port_bus_off(x.port(0)));
    assert_eq!(sim.port_tx_errors(x.port(0)), 0);
}
