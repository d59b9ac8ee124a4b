//! Lag with the cyclic traffic CANopen really carries: SYNC every 10 ms, a TPDO whose data never
//! changes every 10 ms from every station (the same frame again and again), a counting TPDO,
//! heartbeats. Bus 2 is late: every station's port on it hands frames over a fixed time late,
//! or a lag that grows and shrinks, or switches on and off, or only one slave's port lags.
//!
//! Every frame is stamped where it arrived (the simulator's wire time, as SocketCAN's kernel
//! stamps), so the merger pairs each copy with its twin by when it was on the wire, not with
//! the repeat one period off: every application frame and every SYNC arrives exactly once, at
//! any lag up to the merger's horizon (80 ms by default), and no port is called lagging.
//!
//! (A merger that paired copies by arrival took a repeat one period off for the twin: 43 to 55
//! frames twice in 20 s at 25 to 45 ms, 60 ms measured as 10 ms, over 10,000 twice with a lag
//! growing to 60 ms and back, and the healthy bus distrusted when the lag began while only
//! heartbeats flowed.)

use super::sim::*;
use duocan::{Duration, Instant};
use duocan_redundancy::{LinkEventKind, PortState};

const SLAVES: u8 = 3;

fn ms(x: u64) -> Duration {
    Duration::from_millis(x)
}

/// Sets the lag of the port on bus 2 of each station in `nodes` to `lag` at `t`.
fn lag_at(net: &mut Net, nodes: &[u8], t: Instant, lag: Duration) {
    let ports: Vec<_> = nodes.iter().map(|n| net.dev(*n).port(1)).collect();
    net.sim.at(t, move |sim| {
        for p in &ports {
            sim.set_port_latency(*p, lag);
        }
    });
}

/// Runs the network with its traffic until `stop` (SYNC too), then lets it settle.
fn run(net: &mut Net, stop: Instant) {
    stop_sync(net, stop);
    net.sim.run_until(stop + ms(300));
}

/// Every application frame and every SYNC exactly once at every station; no port failed or
/// called lagging anywhere; no heartbeat consumer timed out.
fn assert_exact(net: &Net) {
    net.assert_application_exact();
    net.assert_sync_exact();
    net.assert_no_heartbeat_lost();
    for n in 1..=SLAVES + 1 {
        for e in net.link_events(n) {
            match e.kind {
                LinkEventKind::Lag { .. } => panic!("node {n}: {e:?}"),
                LinkEventKind::Port { to, .. } => {
                    assert_ne!(to, PortState::Failed, "node {n}: {e:?}")
                }
                _ => {}
            }
        }
        let link = &net.station(n).link;
        let m = link.merger().stats();
        assert_eq!((m.slipped, m.late, m.evicted), (0, 0, 0), "node {n}: {m:?}");
    }
}

fn fixed(lag_ms: u64) {
    let stop = Instant::from_millis(10_000);
    let mut net = network(3, SLAVES, active_active(), stop);
    let all: Vec<u8> = (1..=SLAVES + 1).collect();
    lag_at(&mut net, &all, Instant::ZERO, ms(lag_ms));
    run(&mut net, stop);
    assert_exact(&net);
}

#[test]
fn bus_2_25_ms_late_with_cyclic_data_exactly_once() {
    fixed(25);
}

#[test]
fn bus_2_35_ms_late_with_cyclic_data_exactly_once() {
    fixed(35);
}

#[test]
fn bus_2_45_ms_late_with_cyclic_data_exactly_once() {
    fixed(45);
}

#[test]
fn bus_2_60_ms_late_with_cyclic_data_exactly_once() {
    fixed(60);
}

#[test]
fn a_lag_growing_to_60_ms_and_back_exactly_once() {
    // One millisecond more every 500 ms up to 60, then back: a minute.
    let stop = Instant::from_millis(61_000);
    let mut net = network(4, SLAVES, active_active(), stop);
    let all: Vec<u8> = (1..=SLAVES + 1).collect();
    for k in 0..=120u64 {
        let lag = if k <= 60 { k } else { 120 - k };
        lag_at(&mut net, &all, Instant::from_millis(500 + 500 * k), ms(lag));
    }
    run(&mut net, stop);
    assert_exact(&net);
}

#[test]
fn a_lag_switching_between_0_and_30_ms_every_200_ms_exactly_once() {
    let stop = Instant::from_millis(10_000);
    let mut net = network(5, SLAVES, active_active(), stop);
    let all: Vec<u8> = (1..=SLAVES + 1).collect();
    for k in 0..48u64 {
        let lag = if k % 2 == 0 { 30 } else { 0 };
        lag_at(&mut net, &all, Instant::from_millis(300 + 200 * k), ms(lag));
    }
    run(&mut net, stop);
    assert_exact(&net);
}

#[test]
fn one_slaves_port_45_ms_late_exactly_once() {
    let stop = Instant::from_millis(10_000);
    let mut net = network(6, SLAVES, active_active(), stop);
    lag_at(&mut net, &[3], Instant::ZERO, ms(45));
    run(&mut net, stop);
    assert_exact(&net);
}

#[test]
fn a_lag_that_begins_while_only_heartbeats_flow_distrusts_no_bus() {
    // No application traffic, no SYNC: heartbeats only (every 50 ms). Bus 2 turns 30 ms late
    // at 1 s at the master. The healthy bus 1 is never suspected, bus 2 never failed.
    let stop = Instant::from_millis(100);
    let mut net = network(7, SLAVES, active_active(), stop);
    stop_sync(&mut net, Instant::from_millis(1));
    lag_at(&mut net, &[MASTER], Instant::from_millis(1000), ms(30));
    net.sim.run_until(Instant::from_millis(5000));
    net.assert_no_heartbeat_lost();
    for e in net.link_events(MASTER) {
        match e.kind {
            LinkEventKind::Port { port: 0, .. } | LinkEventKind::Lag { .. } => {
                panic!("{e:?}")
            }
            LinkEventKind::Port { to, .. } => assert_ne!(to, PortState::Failed, "{e:?}"),
            _ => {}
        }
    }
    let link = &net.station(MASTER).link;
    assert_eq!(link.port_state(0), PortState::Ok);
    assert_eq!(link.port_state(1), PortState::Ok);
}
