//! Port health: every rule of the state machine, with exact instants.

use super::*;
use duocan_core::machine::PortRequest;

const W: Duration = Duration::from_millis(10);
fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}
fn port_events(out: &mut Outbox) -> Vec<(Instant, u8, PortState, PortReason)> {
    let mut v = vec![];
    while let Some(e) = out.events.pop() {
        if let LinkEventKind::Port {
            port, to, reason, ..
        } = e.kind
        {
            v.push((e.at, port, to, reason));
        }
    }
    v
}
/// Frames on both ports every 10 ms until `cut`, then only on port 0, until `end`.
fn traffic(h: &mut Health, out: &mut Outbox, from: u64, cut: u64, end: u64) {
    let mut t = from;
    while t < end {
        if let Some(d) = h.poll_timeout().filter(|d| *d < ms(t)) {
            h.handle_timeout(d, out);
        }
        // Port 0's copy comes first: delivered whether or not port 0 is proven (port 1 has
        // not reached its time yet); port 1's is its twin.
        h.on_rx(ms(t), ms(t), 0, RxOutcome::Delivered, out);
        if t < cut {
            let o = RxOutcome::Duplicate;
            h.on_rx(
                ms(t) + Duration::from_micros(200),
                ms(t) + Duration::from_micros(200),
                1,
                o,
                out,
            );
        }
        t += 10;
    }
}

#[test]
fn a_repaired_port_in_a_quiet_network_is_not_failed_again_for_an_old_miss() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    // Port 1 goes silent while port 0 hears traffic, and fails; then the network falls
    // quiet (traffic ends at 1000 ms).
    traffic(&mut h, &mut out, 0, 200, 1000);
    assert_eq!(h.port(1).state(), PortState::Failed);
    // Re-initialised after its back-off: recovering, and nothing is missed from then on.
    let mut t = 1000;
    while t < 5_000 {
        if let Some(d) = h.poll_timeout().filter(|d| *d <= ms(t)) {
            h.handle_timeout(d, &mut out);
        }
        t += 5;
    }
    assert_eq!(
        h.port(1).state(),
        PortState::Recovering,
        "{:?}",
        port_events(&mut out)
    );
    // A frame port 0 delivers and port 1 misses counts again: port 1 has been silent for
    // longer than the limit, so it fails when the twin is overdue (one window later).
    h.on_rx(ms(5_000), ms(5_000), 0, RxOutcome::Delivered, &mut out);
    let d = h.poll_timeout().unwrap();
    assert_eq!(d, ms(5_000) + W);
    h.handle_timeout(d, &mut out);
    assert_eq!(h.port(1).state(), PortState::Failed);
}

#[test]
fn a_quiet_port_is_not_judged_next_to_a_failed_one() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    // Traffic on both, then port 1's interface goes down and the network falls quiet (a
    // silent master): port 0 hears nothing more, and must stay usable.
    traffic(&mut h, &mut out, 0, 1000, 1000);
    // Port 0 missed the last frame port 1 heard before it went down.
    h.on_rx(ms(995), ms(995), 1, RxOutcome::Delivered, &mut out);
    h.on_status(
        ms(1000),
        1,
        PortStatus::Down(ErrorCause::InterfaceDown),
        &mut out,
    );
    let mut t = 1000;
    while t < 10_000 {
        if let Some(d) = h.poll_timeout().filter(|d| *d <= ms(t)) {
            h.handle_timeout(d, &mut out);
        }
        t += 10;
    }
    assert!(
        port_events(&mut out).iter().all(|(_, p, _, _)| *p == 1),
        "port 0 keeps its state while port 1 is failed"
    );
    assert!(h.usable(0));
}

#[test]
fn silence_makes_suspect_then_failed_at_exact_instants_then_reinit_with_backoff() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    traffic(&mut h, &mut out, 0, 1000, 2000);
    // Last frame on port 1 at 990.2 ms: suspect 100 ms later, failed 300 ms later,
    // re-initialised 100 ms after that, failed again after 300 ms of silence, then 200 ms
    // back-off …
    let last = ms(990) + Duration::from_micros(200);
    let ev = port_events(&mut out);
    let silence = |d| PortReason::Silence {
        silent: Duration::from_millis(d),
    };
    assert_eq!(
        ev[..5],
        [
            (
                last + Duration::from_millis(100),
                1,
                PortState::Suspect,
                silence(100)
            ),
            (
                last + Duration::from_millis(300),
                1,
                PortState::Failed,
                silence(300)
            ),
            (
                last + Duration::from_millis(400),
                1,
                PortState::Recovering,
                PortReason::Reinit { attempt: 1 }
            ),
            (
                last + Duration::from_millis(700),
                1,
                PortState::Failed,
                silence(300)
            ),
            (
                last + Duration::from_millis(900),
                1,
                PortState::Recovering,
                PortReason::Reinit { attempt: 2 }
            ),
        ]
    );
    assert_eq!(out.requests.pop(), Some((1, PortRequest::Reinit)));
    assert_eq!(h.port(0).state(), PortState::Ok);
}

#[test]
fn a_quiet_network_fails_nobody() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    traffic(&mut h, &mut out, 0, 1000, 1000);
    assert_eq!(h.poll_timeout(), None);
    h.handle_timeout(ms(10_000), &mut out);
    assert!(port_events(&mut out).is_empty());
    // Traffic resumes, port 1 a little late: still nothing.
    traffic(&mut h, &mut out, 20_000, 30_000, 30_000);
    h.handle_timeout(ms(30_500), &mut out);
    assert!(port_events(&mut out).is_empty());
}

#[test]
fn repaired_port_recovers_after_probation_and_is_untrusted_meanwhile() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    traffic(&mut h, &mut out, 0, 100, 450);
    assert_eq!(h.port(1).state(), PortState::Failed);
    assert!(!h.trusted(1));
    traffic(&mut h, &mut out, 450, 1000, 1000);
    let ev = port_events(&mut out);
    let n = ev.len();
    let first = ms(450) + Duration::from_micros(200);
    assert_eq!(
        ev[n - 2..],
        [
            (first, 1, PortState::Recovering, PortReason::Traffic),
            (
                first + Duration::from_millis(100),
                1,
                PortState::Ok,
                PortReason::Traffic
            )
        ]
    );
    assert_eq!(h.port(1).attempts(), 0);
}

#[test]
fn controller_reports() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    h.on_status(ms(1), 0, PortStatus::Error(ErrorCause::Crc), &mut out);
    assert_eq!(h.port(0).state(), PortState::Suspect);
    // A frame within the hold time keeps it suspect; after it, ok.
    h.on_rx(ms(50), ms(50), 0, RxOutcome::Delivered, &mut out);
    assert_eq!(h.port(0).state(), PortState::Suspect);
    h.on_rx(ms(101), ms(101), 0, RxOutcome::Delivered, &mut out);
    assert_eq!(h.port(0).state(), PortState::Ok);
    h.on_status(
        ms(200),
        0,
        PortStatus::TxFailed(ErrorCause::BusOff),
        &mut out,
    );
    assert_eq!(h.port(0).state(), PortState::Failed);
    assert!(!h.usable(0));
    h.on_status(
        ms(250),
        0,
        PortStatus::Error(ErrorCause::Restarted),
        &mut out,
    );
    assert_eq!(h.port(0).state(), PortState::Recovering);
    h.on_status(
        ms(260),
        1,
        PortStatus::Down(ErrorCause::InterfaceDown),
        &mut out,
    );
    h.on_status(ms(270), 1, PortStatus::Up, &mut out);
    assert_eq!(h.port(1).state(), PortState::Recovering);
    // Both untrusted: both deliver.
    assert!(h.trusted(0) && h.trusted(1));
    let c = h.port(0).counters();
    assert_eq!(c.errors_of(ErrorCause::Crc), 1);
    assert_eq!(c.errors_of(ErrorCause::BusOff), 1);
    assert_eq!(c.tx_failed, 1);
}

/// A transmission left unacknowledged (a cut next to this node) says nobody is reached through
/// the port; frames its reader hands over afterwards that were on the bus before (a reader
/// running behind) do not say otherwise, a frame from after does (found by the fault
/// campaign, seed 974: a master sent its boot process's request only on the port whose bus
/// had just been cut, its reader 56 ms behind, and waited for the SDO timeout).
#[test]
fn frames_from_before_an_unacknowledged_transmission_do_not_prove_the_port() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    h.on_rx(ms(10), ms(10), 0, RxOutcome::Delivered, &mut out);
    assert!(h.port(0).proven());
    h.on_status(
        ms(100),
        0,
        PortStatus::TxFailed(ErrorCause::NoAck),
        &mut out,
    );
    assert!(!h.port(0).proven());
    // Read at 105 ms, on the bus at 45 ms.
    h.on_rx(ms(105), ms(45), 0, RxOutcome::Delivered, &mut out);
    assert!(!h.port(0).proven(), "a frame from before the cut");
    h.on_rx(ms(110), ms(101), 0, RxOutcome::Delivered, &mut out);
    assert!(h.port(0).proven(), "a frame from after it");
}

#[test]
fn transmit_stall_flushes_and_fails_and_only_reinit_revives() {
    let cfg = HealthConfig {
        tx_stall: W,
        ..HealthConfig::default()
    };
    let mut h = Health::new(cfg, W);
    let mut out = Outbox::new();
    let ok = |h: &mut Health, t: u64, p: usize| {
        h.on_status(ms(t), p, PortStatus::TxOk, &mut Outbox::new())
    };
    // Drivers that never confirmed a success are not judged, however long their frames wait
    // (embedded-can drivers report failures but cannot confirm successes).
    h.count_tx(ms(0), 0, 0);
    h.count_tx(ms(0), 1, 0);
    assert_eq!(h.poll_timeout(), None);
    ok(&mut h, 1, 1);
    let mut only_failures = Health::new(cfg, W);
    only_failures.count_tx(ms(0), 0, 0);
    only_failures.on_status(
        ms(0),
        0,
        PortStatus::TxFailed(ErrorCause::Bit),
        &mut Outbox::new(),
    );
    only_failures.count_tx(ms(1), 0, 1);
    assert_eq!(only_failures.stall_deadline(0), None);
    ok(&mut h, 1, 0);
    // Two frames handed to both ports, waiting on both alike (lost arbitration on two busy
    // buses): no stall however long, their twins still match.
    for t in [2, 3] {
        h.count_tx(ms(t), 0, t as u32);
        h.count_tx(ms(t), 1, t as u32);
    }
    assert_eq!(h.poll_timeout(), None);
    // Bus 2 sends the first at 30 ms: its twin on bus 1 has the window to follow.
    ok(&mut h, 30, 1);
    assert_eq!(h.stall_deadline(0), Some(ms(40)));
    assert_eq!(h.stall_deadline(1), None);
    ok(&mut h, 31, 1);
    assert_eq!(h.stall_deadline(0), Some(ms(40)));
    // It follows at 32 ms; the second's twin went out at 31 ms: the window from then (not
    // from 32 ms: waiting behind the first does not buy it more time). Frames are told apart
    // by the layer's numbers, not by their hand-over times (a SYNC and a heartbeat are handed
    // over in one instant).
    ok(&mut h, 32, 0);
    assert_eq!(h.stall_deadline(0), Some(ms(41)));
    h.count_tx(ms(33), 0, 33);
    h.count_tx(ms(33), 1, 33);
    ok(&mut h, 34, 1);
    assert_eq!(h.poll_timeout(), Some(ms(41)));
    h.handle_timeout(ms(41), &mut out);
    assert_eq!(out.requests.pop(), Some((0, PortRequest::Reinit)));
    assert_eq!(
        port_events(&mut out),
        [(
            ms(41),
            0,
            PortState::Failed,
            PortReason::TxStalled { waited: W }
        )]
    );
    // Receiving (a babbler's frames) does not revive it; the back-off re-initialisation does.
    h.on_rx(ms(50), ms(50), 0, RxOutcome::Stale, &mut out);
    assert_eq!(h.port(0).state(), PortState::Failed);
    h.handle_timeout(ms(144), &mut out);
    assert_eq!(h.port(0).state(), PortState::Recovering);
    assert_eq!(h.port(0).counters().reinits, 2);
    // A refused hand-over (queue full) concerns the newest frame: the oldest, handed at
    // 150 ms, still waits when bus 2 sends its twin at 152 ms.
    h.count_tx(ms(150), 0, 150);
    h.count_tx(ms(151), 0, 151);
    h.on_status(
        ms(151),
        0,
        PortStatus::TxFailed(ErrorCause::TxTimeout),
        &mut out,
    );
    h.count_tx(ms(150), 1, 150);
    h.count_tx(ms(151), 1, 151);
    ok(&mut h, 152, 1);
    ok(&mut h, 153, 1);
    assert_eq!(h.stall_deadline(0), Some(ms(162)));
    // Bus 2 gone: a frame bus 1 cannot send has no twin to be late for; it is not judged.
    h.on_status(
        ms(153),
        1,
        PortStatus::Down(ErrorCause::InterfaceDown),
        &mut out,
    );
    h.on_status(ms(154), 0, PortStatus::TxOk, &mut out);
    h.count_tx(ms(155), 0, 155);
    assert_eq!(h.stall_deadline(0), None);
}

#[test]
fn a_stalled_port_comes_back_when_a_probe_is_confirmed_in_time() {
    let cfg = HealthConfig {
        tx_stall: W,
        ..HealthConfig::default()
    };
    let mut h = Health::new(cfg, W);
    let mut out = Outbox::new();
    // Port 0's frame waits (behind a babble, in a slow controller) while port 1 sends its
    // twin: stalled at 12 ms.
    h.on_status(ms(0), 1, PortStatus::TxOk, &mut out);
    h.count_tx(ms(1), 0, 1);
    h.count_tx(ms(1), 1, 1);
    h.on_status(ms(2), 1, PortStatus::TxOk, &mut out);
    h.handle_timeout(ms(12), &mut out);
    assert!(h.port(0).stalled());
    assert_eq!(out.requests.pop(), Some((0, PortRequest::Reinit)));
    // Receiving tells nothing of its transmitter: a babbler's flood, nor the network's own
    // traffic (a controller that sends late hears the bus fine), in either order.
    h.on_rx(ms(20), ms(20), 0, RxOutcome::Delivered, &mut out);
    h.on_rx(ms(21), ms(21), 0, RxOutcome::Stale, &mut out);
    h.on_rx(ms(30), ms(30), 1, RxOutcome::Delivered, &mut out);
    h.on_rx(ms(30), ms(30), 0, RxOutcome::Duplicate, &mut out);
    h.on_rx(ms(31), ms(31), 0, RxOutcome::Delivered, &mut out);
    h.on_rx(ms(31), ms(31), 1, RxOutcome::Duplicate, &mut out);
    assert!(h.port(0).stalled());
    // A probe (its heartbeat) on both at 40 ms; port 1 sends it at 41 ms, port 0 still
    // waits at 51 ms: flushed, and the port stays failed without a new event.
    h.count_tx(ms(40), 0, 40);
    h.count_tx(ms(40), 1, 40);
    h.on_status(ms(41), 1, PortStatus::TxOk, &mut out);
    assert_eq!(h.stall_deadline(0), Some(ms(51)));
    h.handle_timeout(ms(51), &mut out);
    assert_eq!(out.requests.pop(), Some((0, PortRequest::Reinit)));
    assert!(h.port(0).stalled());
    // The flushed probe's confirmation, had it gone out meanwhile, proves nothing.
    h.on_status(ms(60), 0, PortStatus::TxOk, &mut out);
    assert!(h.port(0).stalled());
    // The next probe is confirmed within the stall time of its twin: the transmitter keeps
    // time again, long before the back-off (112 ms). Probation as for any return.
    h.count_tx(ms(80), 0, 80);
    h.count_tx(ms(80), 1, 80);
    h.on_status(ms(81), 1, PortStatus::TxOk, &mut out);
    h.on_status(ms(83), 0, PortStatus::TxOk, &mut out);
    assert_eq!(h.port(0).state(), PortState::Recovering);
    h.on_rx(ms(90), ms(90), 0, RxOutcome::Duplicate, &mut out);
    h.on_rx(ms(190), ms(190), 0, RxOutcome::Duplicate, &mut out);
    assert_eq!(
        port_events(&mut out),
        [
            (
                ms(12),
                0,
                PortState::Failed,
                PortReason::TxStalled { waited: W }
            ),
            (ms(83), 0, PortState::Recovering, PortReason::Traffic),
            (ms(190), 0, PortState::Ok, PortReason::Traffic),
        ]
    );
}

#[test]
fn a_port_lagging_beyond_the_maximum_is_suspect_until_its_lag_is_within_again() {
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    let lag = Duration::from_millis(45);
    h.set_lagging(ms(10), 1, lag, true, &mut out);
    assert_eq!(h.port(1).lagging(), Some(lag));
    // Frames received do not make it ok while it lags, nor does the lag report repeat.
    h.on_rx(ms(500), ms(500), 1, RxOutcome::Duplicate, &mut out);
    h.set_lagging(ms(600), 1, lag, true, &mut out);
    assert_eq!(h.port(1).state(), PortState::Suspect);
    let within = Duration::from_millis(20);
    h.set_lagging(ms(700), 1, within, false, &mut out);
    assert_eq!(
        port_events(&mut out),
        [
            (ms(10), 1, PortState::Suspect, PortReason::Lag { lag }),
            (
                ms(700),
                1,
                PortState::Ok,
                PortReason::LagWithin { lag: within }
            ),
        ]
    );
    // Suspect for an error as well: it stays suspect when the lag ends, until the error hold
    // is over and a frame comes.
    h.on_status(
        ms(800),
        0,
        PortStatus::Error(ErrorCause::ErrorPassive),
        &mut out,
    );
    h.set_lagging(ms(810), 0, lag, true, &mut out);
    h.set_lagging(ms(850), 0, Duration::ZERO, false, &mut out);
    assert_eq!(h.port(0).state(), PortState::Suspect);
    h.on_rx(ms(900), ms(900), 0, RxOutcome::Delivered, &mut out);
    assert_eq!(h.port(0).state(), PortState::Ok);
    // A port that fails and recovers while it lags comes back suspect for the lag.
    h.set_lagging(ms(1_000), 1, lag, true, &mut out);
    h.on_status(
        ms(1_000),
        1,
        PortStatus::Down(ErrorCause::InterfaceDown),
        &mut out,
    );
    h.on_status(ms(1_050), 1, PortStatus::Up, &mut out);
    h.on_rx(ms(1_060), ms(1_060), 1, RxOutcome::Duplicate, &mut out);
    h.on_rx(ms(1_200), ms(1_200), 1, RxOutcome::Duplicate, &mut out);
    assert_eq!(h.port(1).state(), PortState::Suspect);
    let last = port_events(&mut out).pop().unwrap();
    assert_eq!(
        last,
        (ms(1_200), 1, PortState::Suspect, PortReason::Lag { lag })
    );
}

#[test]
fn a_port_whose_frames_are_acknowledged_is_not_failed_for_silence() {
    // Port 1 hears nothing after 1000 ms (its receive path stalls), while its own frames, one
    // every 10 ms until 1500 ms, are acknowledged: its bus works. Suspect for the silence, but
    // failed (out of the fan-out) only when its frames have not been confirmed for the
    // silence limit either.
    let mut h = Health::new(HealthConfig::default(), W);
    let mut out = Outbox::new();
    let mut seq = 0;
    let mut t = 0;
    while t < 2000 {
        while let Some(d) = h.poll_timeout().filter(|d| *d < ms(t)) {
            h.handle_timeout(d, &mut out);
        }
        h.on_rx(ms(t), ms(t), 0, RxOutcome::Delivered, &mut out);
        if t < 1000 {
            let o = RxOutcome::Duplicate;
            h.on_rx(
                ms(t) + Duration::from_micros(200),
                ms(t) + Duration::from_micros(200),
                1,
                o,
                &mut out,
            );
        }
        if t < 1500 {
            seq += 1;
            h.count_tx(ms(t) + Duration::from_micros(300), 1, seq);
            h.on_status(
                ms(t) + Duration::from_micros(500),
                1,
                PortStatus::TxOk,
                &mut out,
            );
        }
        t += 10;
    }
    let last_rx = ms(990) + Duration::from_micros(200);
    let last_ok = ms(1490) + Duration::from_micros(500);
    let silence = |d: Instant| PortReason::Silence {
        silent: d.saturating_since(last_rx),
    };
    let at = [
        last_rx + Duration::from_millis(100),
        last_ok + Duration::from_millis(300),
    ];
    assert_eq!(
        port_events(&mut out)[..2],
        [
            (at[0], 1, PortState::Suspect, silence(at[0])),
            (at[1], 1, PortState::Failed, silence(at[1])),
        ]
    );
}

mod bus_off;
