//! The layer's own unit tests: fan-out, pairs, modes.

use super::*;
use crate::link::channel::EcssConfig;
use crate::link::events::{LinkEventKind, PortReason};
use duocan_core::machine::ErrorCause;
use duocan_core::{Id, NodeId};

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}
fn drain(l: &mut DualBus) -> Vec<(usize, Frame)> {
    core::iter::from_fn(|| l.poll_transmit()).collect()
}

#[test]
fn fan_out_skips_failed_ports_and_the_merge_delivers_once() {
    let mut l = DualBus::new(DualBusConfig::default());
    let f = Frame::from_array(Id::Standard(0x181), [1]);
    l.send(ms(0), &f);
    assert_eq!(drain(&mut l), [(0, f), (1, f)]);
    l.handle_port_status(ms(1), 1, PortStatus::Down(ErrorCause::InterfaceDown));
    l.send(ms(2), &f);
    assert_eq!(drain(&mut l), [(0, f)]);
    assert_eq!(l.port(0).counters().tx, 2);
    assert_eq!(l.port(1).counters().tx, 1);
    let g = Frame::from_array(Id::Standard(0x182), [2]);
    assert_eq!(l.handle_rx(ms(3), 0, &g), Some(g));
    assert_eq!(l.handle_rx(ms(3), 1, &g), None);
    assert_eq!(l.handle_rx(ms(3), 7, &g), None);
    assert_eq!(l.stats().bad_port, 1);
    assert_eq!(l.stats().delivered, 1);
    let e = l.poll_event().unwrap();
    assert_eq!(
        e.kind,
        LinkEventKind::Port {
            port: 1,
            from: PortState::Ok,
            to: PortState::Failed,
            reason: PortReason::Down(ErrorCause::InterfaceDown)
        }
    );
}

#[test]
fn pairs_deliver_the_active_member_only_and_follow_set_active() {
    let mut l = DualBus::new(DualBusConfig::default());
    let (a, b) = (NodeId::must(0x10), NodeId::must(0x11));
    let p = l.add_pair(a, b, Some(Member::A)).unwrap();
    let ta = Frame::from_array(Id::Standard(0x190), [1]);
    let tb = Frame::from_array(Id::Standard(0x191), [1]);
    let hb_b = Frame::from_array(Id::Standard(0x711), [5]);
    assert_eq!(l.handle_rx(ms(0), 0, &ta), Some(ta));
    assert_eq!(l.handle_rx(ms(0), 0, &tb), None);
    // Not process data: both members' heartbeats go up.
    assert_eq!(l.handle_rx(ms(0), 0, &hb_b), Some(hb_b));
    assert_eq!(l.pairs().latest(p, Member::B, 1), Some((ms(0), tb)));
    assert!(l.set_active(p, Some(Member::B)));
    assert_eq!(l.handle_rx(ms(20), 0, &ta), None);
    assert_eq!(l.handle_rx(ms(20), 0, &tb), Some(tb));
    assert_eq!(l.stats().standby, 2);
}

#[test]
fn modes_and_commands() {
    let mut l = DualBus::new(DualBusConfig::default());
    assert_eq!(l.mode(), ModeKind::ActiveActive);
    assert_eq!(l.active_channel(), None);
    assert!(!l.select_channel(ms(0), 1));
    let cfg = DualBusConfig {
        mode: LinkMode::EcssToggle(EcssConfig::master()),
        ..DualBusConfig::default()
    };
    let mut l = DualBus::new(cfg);
    assert_eq!(l.mode(), ModeKind::EcssToggle);
    assert!(!l.health().config().silence_detection);
    let f = Frame::from_array(Id::Standard(0x181), [1]);
    l.send(ms(0), &f);
    assert_eq!(drain(&mut l), [(0, f)]);
    // Only the active bus is listened to.
    assert_eq!(l.handle_rx(ms(1), 1, &f), None);
    assert_eq!(l.handle_rx(ms(1), 0, &f), Some(f));
    assert!(l.select_channel(ms(2), 1));
    l.send(ms(3), &f);
    assert_eq!(drain(&mut l), [(1, f)]);
    assert_eq!(l.ecss().map(|e| e.active_bus()), Some(1));
}

#[test]
fn frames_one_bus_missed_after_its_fault_measure_no_lag_behind_a_late_reader() {
    // A 20 ms guarding period: window 5 ms, horizon 80 ms. After a fault of bus 1, two boards'
    // ports on it come back late: their heartbeats in a new state (0x11, 0x12 from 349 ms;
    // 0x51, 0x52 from 355 ms) go on bus 0 only, then from 409 and 395 ms on both. This
    // node's port 0 reader hands everything over 52 ms late; a SYNC every 10 ms on both buses.
    // Port 1's copies of the state come before port 0's: neither their first copies (port 0
    // still holds repeats) nor port 0's older ones (its reader is behind, not bus 1) are twins
    // beyond the window, and each heartbeat is delivered once.
    let mut l = DualBus::new(DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        Duration::from_millis(20),
    ));
    let us = Duration::from_micros;
    let mut sent = vec![];
    for k in 0..40u64 {
        sent.push((
            ms(300 + 10 * k),
            [true, true],
            Frame::from_array(Id::Standard(0x80), []),
        ));
    }
    for (id, state, first, both) in [
        (0x711, 0x7F, us(349_000), 409),
        (0x712, 0x7F, us(349_300), 409),
        (0x751, 0x05, us(355_100), 395),
        (0x752, 0x05, us(355_400), 395),
    ] {
        for k in 0..8u64 {
            let at = Instant::ZERO + first + Duration::from_millis(20 * k);
            let f = Frame::from_array(Id::Standard(id), [state]);
            sent.push((at, [true, at >= ms(both)], f));
        }
    }
    // (handed over, stamp, port, frame)
    let mut arrivals = vec![];
    for (at, on, f) in &sent {
        arrivals.push((*at + Duration::from_millis(52), *at, 0, *f));
        if on[1] {
            arrivals.push((*at, *at, 1, *f));
        }
    }
    arrivals.sort_by_key(|a| a.0);
    let mut delivered = 0;
    for (now, at, p, f) in arrivals {
        l.handle_timeout(now);
        delivered += usize::from(l.handle_rx_at(now, p, &f, at).is_some());
        assert_eq!(
            [l.lag().lag(0), l.lag().lag(1)],
            [Duration::ZERO; 2],
            "at {now}"
        );
    }
    assert_eq!(delivered, sent.len());
}

/// Bus 2 is cut from `cut.0` to `cut.1` ms (`down`: its interface reports it down; otherwise
/// its port only falls silent) while port 1's reader runs 30 ms behind (its stamps are right:
/// the frames were on the wire on time). Two boards start a cyclic frame (every 20 ms) just
/// before bus 2 is repaired; bus 2 carries the next ones, while port 1 hands over, later, the
/// first ones, from before the repair. Those were never on bus 2: their copies on port 1 are
/// not the twins of bus 2's next copies, 20 ms later, and measure no lag (a correction of bus
/// 2 by 20 ms paired its later copies one period off: delivered twice).
fn a_repaired_bus(cut: (u64, u64), down: bool) {
    let cfg = DualBusConfig::with_guard_period(LinkMode::ActiveActive, Duration::from_millis(20));
    let mut l = DualBus::new(cfg);
    let hb = Frame::from_array(Id::Standard(0x701), [5]);
    let pdos = [0x181, 0x182].map(|id| Frame::from_array(Id::Standard(id), [1]));
    let first = cut.1 - 10;
    // (hand-over, port, frame, stamp).
    let mut arrivals = vec![];
    let mut sent = 0;
    for t in (0..cut.1 + 100).step_by(10) {
        let mut frames = vec![hb];
        if t >= first && (t - first).is_multiple_of(20) {
            frames.extend(pdos);
            sent += 1;
        }
        for (k, f) in frames.into_iter().enumerate() {
            let at = ms(t) + Duration::from_micros(100 * k as u64);
            arrivals.push((at + Duration::from_millis(30), 0, f, at));
            if !(cut.0..cut.1).contains(&t) {
                arrivals.push((at + Duration::from_micros(50), 1, f, at));
            }
        }
    }
    arrivals.sort_by_key(|a| (a.0, a.1));
    let mut delivered = [0; 2];
    let mut down = down;
    for (now, port, f, at) in arrivals {
        if down && now >= ms(cut.0) {
            l.handle_port_status(ms(cut.0), 1, PortStatus::Down(ErrorCause::InterfaceDown));
            down = false;
        }
        while let Some(d) = l.poll_timeout().filter(|d| *d <= now) {
            l.handle_timeout(d);
        }
        if let Some(g) = l.handle_rx_at(now, port, &f, at) {
            if let Some(i) = pdos.iter().position(|p| *p == g) {
                delivered[i] += 1;
            }
        }
    }
    // Every occurrence once (the last few are still on their way through port 0's reader,
    // and came on bus 2 already).
    assert_eq!(delivered, [sent; 2]);
    assert_eq!(l.lag().lag(1), Duration::ZERO);
    assert_eq!(l.lag().lag(0), Duration::ZERO);
}

#[test]
fn frames_a_repaired_bus_never_carried_measure_no_lag_against_it() {
    // Failed, recovering, then ok.
    a_repaired_bus((100, 300), true);
}

#[test]
fn frames_a_bus_silent_for_a_while_never_carried_measure_no_lag_against_it() {
    // Suspect for its silence, then ok again.
    a_repaired_bus((250, 290), false);
}
