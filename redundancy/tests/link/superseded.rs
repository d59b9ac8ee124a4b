//! A watched node's heartbeat that the merge delivers after a newer one of the same node (it
//! came over a bus whose reader runs behind, with its receive time) is not handed up: it
//! reports a state the node has left. A master took such a late "pre-operational" for a board
//! that stopped by itself right after its start, reset it, and did so again at every heartbeat
//! while the lag lasted (found by the fault campaign, seed 357).

use duocan::machine::BusLink;
use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::{DualBus, DualBusConfig, LinkCommand, LinkMode};

const A: u8 = 0x10;
const PERIOD_MS: u64 = 20;
const PRE_OP: u8 = 0x7F;
const OPERATIONAL: u8 = 0x05;

fn hb(state: u8) -> Frame {
    Frame::from_array(Id::Standard(0x700 + A as u16), [state])
}

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// The layer watching node A, as a master's does.
fn layer() -> DualBus {
    let mut l = DualBus::new(DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        Duration::from_millis(PERIOD_MS),
    ));
    l.handle_command(
        Instant::ZERO,
        LinkCommand::Watch {
            node: NodeId::must(A),
            producer_ms: PERIOD_MS as u16,
        },
    );
    l
}

/// The layer after A's heartbeats at 0, 20 and 40 ms on both buses (each handed up once).
fn beating_on_both() -> DualBus {
    let mut l = layer();
    for t in [0, 20, 40] {
        assert_eq!(arrive(&mut l, ms(t), 0, &hb(PRE_OP), ms(t)), Some(PRE_OP));
        assert_eq!(arrive(&mut l, ms(t), 1, &hb(PRE_OP), ms(t)), None);
    }
    l
}

/// Hands `frame` (on the bus at `at`) over on `port` at `now`, after the layer's deadlines;
/// the state byte of what it handed up.
fn arrive(l: &mut DualBus, now: Instant, port: usize, frame: &Frame, at: Instant) -> Option<u8> {
    while let Some(d) = l.poll_timeout().filter(|d| *d <= now) {
        l.handle_timeout(d);
    }
    let up = l.handle_rx_at(now, port, frame, at).map(|f| f.data()[0]);
    while l.poll_transmit().is_some() {}
    while l.poll_event().is_some() {}
    while l.poll_machine_request().is_some() {}
    up
}

/// Both buses carry A's heartbeats; bus 1 is cut from 100 ms to 300 ms while bus 2's reader
/// runs 60 ms behind from 200 ms on (receive times are the kernel's). A is started at 310 ms,
/// when bus 1 is back: its operational heartbeats come over bus 1 at once, its last
/// pre-operational ones (sent while bus 1 was cut) over bus 2 60 ms late.
#[test]
fn a_heartbeat_older_than_one_handed_up_is_not_handed_up() {
    let mut l = layer();
    // Every arrival: (handed over, port, state, on the bus at).
    let mut arrivals = vec![];
    for k in 0..30u64 {
        let t = k * PERIOD_MS;
        let state = if t >= 310 { OPERATIONAL } else { PRE_OP };
        if !(100..300).contains(&t) {
            arrivals.push((t, 0, state, t));
        }
        let late = if t >= 200 { 60 } else { 0 };
        arrivals.push((t + late, 1, state, t));
    }
    // The start's own heartbeat, at once.
    arrivals.push((310, 0, OPERATIONAL, 310));
    arrivals.push((370, 1, OPERATIONAL, 310));
    arrivals.sort_by_key(|a| (a.0, a.3));
    let mut up = vec![];
    for (now, port, state, at) in arrivals {
        if let Some(s) = arrive(&mut l, ms(now), port, &hb(state), ms(at)) {
            up.push((now, at, s));
        }
    }
    let after_start: Vec<_> = up.iter().filter(|(now, ..)| *now >= 310).collect();
    assert!(
        after_start.iter().all(|(.., s)| *s == OPERATIONAL),
        "after the operational heartbeat, nothing older: {after_start:?}"
    );
    // Bus 2's copies of 260 and 280 (the only copies of those heartbeats) came after 310's:
    // superseded, counted. (300 went over bus 1 too, at once.)
    assert_eq!(l.stats().superseded, 2);
    // Each heartbeat handed up once, in the order they were sent.
    let sent: Vec<_> = up.iter().map(|(_, at, _)| *at).collect();
    assert!(sent.windows(2).all(|w| w[0] < w[1]), "{sent:?}");
}

/// A boot-up is never superseded: the node lost its state then, whatever was heard after.
#[test]
fn a_late_boot_up_is_handed_up() {
    let mut l = beating_on_both();
    // A boot-up on bus 2 only, at 50 ms, handed over 40 ms late; the heartbeat it was
    // followed by came over bus 1 first.
    assert_eq!(arrive(&mut l, ms(60), 0, &hb(PRE_OP), ms(60)), Some(PRE_OP));
    assert_eq!(arrive(&mut l, ms(90), 1, &hb(0), ms(50)), Some(0));
    assert_eq!(l.stats().superseded, 0);
}

/// Two heartbeats of a node sent close together (the one a node sends at a state change right
/// after its periodic one) may reach the buses in either order (arbitration): the newer one
/// is handed up even when its copy on the other bus was there before the older one's.
#[test]
fn a_newer_heartbeat_on_the_wire_first_is_handed_up() {
    let mut l = beating_on_both();
    let us = Instant::from_micros;
    // Pre-operational sent at 60.0 ms waits on bus 1 until 61.0; operational, sent at 60.3,
    // is on bus 2 at 60.4, whose reader hands it over at 62.0.
    assert_eq!(
        arrive(&mut l, us(61_000), 0, &hb(PRE_OP), us(61_000)),
        Some(PRE_OP)
    );
    assert_eq!(
        arrive(&mut l, us(62_000), 1, &hb(OPERATIONAL), us(60_400)),
        Some(OPERATIONAL)
    );
    assert_eq!(l.stats().superseded, 0);
}

/// The clock stepping back moves what the layer remembers with it: the heartbeats after the
/// step are not older than those before it.
#[test]
fn heartbeats_after_a_clock_step_back_are_handed_up() {
    let mut l = layer();
    for t in [1_000, 1_020, 1_040] {
        assert_eq!(arrive(&mut l, ms(t), 0, &hb(PRE_OP), ms(t)), Some(PRE_OP));
    }
    // The clock steps back 1 s: the next heartbeat is read at 60 ms.
    for t in [60, 80, 100] {
        assert_eq!(
            arrive(&mut l, ms(t), 0, &hb(PRE_OP), ms(t)),
            Some(PRE_OP),
            "at {t} ms"
        );
    }
    assert_eq!(l.stats().superseded, 0);
}
