//! A port whose controller goes bus-off again and again (a transceiver that receives but
//! cannot send: the fault campaign's seed 27, every kind).

use super::*;

/// The controller's cycle as the simulator plays it for a dead transmitter: a bit error,
/// bus-off 0.7 ms later, the automatic restart 1.4 ms after that; frames received meanwhile.
fn cycle(h: &mut Health, out: &mut Outbox, at: Instant) {
    let us = Duration::from_micros;
    h.on_status(at, 0, PortStatus::Error(ErrorCause::Bit), out);
    h.on_rx(at + us(300), at + us(300), 0, RxOutcome::Duplicate, out);
    h.on_status(at + us(700), 0, PortStatus::Down(ErrorCause::BusOff), out);
    h.on_status(at + us(2_100), 0, PortStatus::Up, out);
    h.on_rx(at + us(2_500), at + us(2_500), 0, RxOutcome::Duplicate, out);
}

#[test]
fn a_port_bus_off_again_after_its_restart_stays_failed_until_a_probe_is_confirmed() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    // Its driver confirms transmissions (SocketCAN, the simulator).
    h.count_tx(ms(1), 0, 0);
    h.on_status(ms(2), 0, PortStatus::TxOk, &mut out);
    // The first bus-off: the restart revives it, as for a bus fault that is gone.
    cycle(&mut h, &mut out, ms(10));
    assert_eq!(h.port(0).state(), PortState::Recovering);
    // Again before it was back: its transmitter is the fault. Neither restarts nor frames
    // revive it any more, however many cycles.
    for k in 1..50 {
        cycle(&mut h, &mut out, ms(10 + 3 * k));
        assert_eq!(h.port(0).state(), PortState::Failed, "cycle {k}");
        assert!(h.port(0).stalled());
    }
    let events = port_events(&mut out);
    let reasons: Vec<_> = events.iter().map(|e| (e.2, e.3)).collect();
    assert_eq!(
        reasons,
        vec![
            (PortState::Suspect, PortReason::Controller(ErrorCause::Bit)),
            (PortState::Failed, PortReason::Down(ErrorCause::BusOff)),
            (PortState::Recovering, PortReason::Up),
            (PortState::Failed, PortReason::Down(ErrorCause::BusOff)),
        ],
        "four changes in 50 cycles, not a hundred"
    );
    // Its re-initialisation tries it again; a bus-off then fails it again, no more.
    let due = h.port(0).next_reinit().unwrap();
    h.handle_timeout(due, &mut out);
    assert_eq!(h.port(0).state(), PortState::Recovering);
    // A quiet node (pre-operational: a heartbeat every period) hands it nothing for longer
    // than the probation: frames received alone do not make it ok (seed 27: the port was ok
    // between two heartbeats, its back-off reset each time).
    let probation = HealthConfig::default().probation;
    for k in 0..=probation.as_millis() / 5 + 1 {
        let t = due + Duration::from_millis(5 * k);
        h.on_rx(t, t, 0, RxOutcome::Duplicate, &mut out);
    }
    assert_eq!(h.port(0).state(), PortState::Recovering);
    let due = due + probation + Duration::from_millis(10);
    cycle(&mut h, &mut out, due + Duration::from_millis(1));
    assert_eq!(h.port(0).state(), PortState::Failed);
    assert!(h.port(0).stalled());
    // Repaired: the next probe (a heartbeat) handed to it is confirmed, and it recovers.
    let t = due + Duration::from_millis(20);
    h.count_tx(t, 0, 2);
    h.on_status(
        t + Duration::from_micros(100),
        0,
        PortStatus::TxOk,
        &mut out,
    );
    assert_eq!(h.port(0).state(), PortState::Recovering);
    let back = t + probation + Duration::from_millis(1);
    h.on_rx(t, t, 0, RxOutcome::Duplicate, &mut out);
    h.on_rx(back, back, 0, RxOutcome::Duplicate, &mut out);
    assert_eq!(h.port(0).state(), PortState::Ok);
}

#[test]
fn after_its_first_bus_off_a_port_is_ok_only_once_a_transmission_is_confirmed() {
    // A node with a producer time longer than the probation (25 ms, the probation 20 ms): after
    // its first bus-off and the restart, frames received alone made the port ok before its
    // next heartbeat tested the transmitter, which could not send: ok and failed at every
    // cycle (the campaign's seeds 1225 and 1337, a transceiver that cannot send).
    let probation = HealthConfig::default().probation;
    for confirms in [true, false] {
        let mut h = Health::new(HealthConfig::default(), W);
        let mut out = Outbox::new();
        if confirms {
            h.count_tx(ms(1), 0, 0);
            h.on_status(ms(2), 0, PortStatus::TxOk, &mut out);
        }
        cycle(&mut h, &mut out, ms(10));
        assert_eq!(h.port(0).state(), PortState::Recovering);
        let mut t = ms(13);
        while t < ms(13) + probation + Duration::from_millis(5) {
            h.on_rx(t, t, 0, RxOutcome::Duplicate, &mut out);
            t += Duration::from_millis(1);
        }
        // Without confirmations frames are all a port can go by (unchanged).
        let expected = if confirms {
            PortState::Recovering
        } else {
            PortState::Ok
        };
        assert_eq!(h.port(0).state(), expected, "driver confirms: {confirms}");
        if confirms {
            h.count_tx(t, 0, 1);
            h.on_status(
                t + Duration::from_micros(100),
                0,
                PortStatus::TxOk,
                &mut out,
            );
            h.on_rx(
                t + Duration::from_millis(1),
                t,
                0,
                RxOutcome::Duplicate,
                &mut out,
            );
            assert_eq!(h.port(0).state(), PortState::Ok);
        }
    }
}
