//! The failover as the bus sees it: a started standby announces its new state at once (its
//! heartbeat follows the NMT start), instead of on its heartbeat grid up to a period later.
//! Slaves beat every 20 ms, consumer time 50 ms, 1 Mbit/s (the `on_bus` network).

use crate::net::*;
use duocan::node::{NodeEvent, NodeEventKind};
use duocan::{Duration, Id, Instant, NmtCommand, NmtState};
use duocan_redundancy::SupervisorEvent;

fn ms(x: u64) -> Instant {
    Instant::from_millis(x)
}

/// First copies (either bus) of `node`'s heartbeats: (end, state byte).
fn heartbeats(n: &SupNet, node: u8) -> Vec<(Instant, u8)> {
    let mut all: Vec<(Instant, u8)> = n
        .delivered()
        .into_iter()
        .filter(|(_, _, s, f)| *s == node && f.id() == Id::Standard(0x700 + node as u16))
        .map(|(t, _, _, f)| (t, f.data()[0]))
        .collect();
    all.sort();
    let mut first: Vec<(Instant, u8)> = vec![];
    for (t, s) in all {
        match first.last() {
            Some(&(p, ps)) if ps == s && t.saturating_since(p) < Duration::from_millis(2) => {}
            _ => first.push((t, s)),
        }
    }
    first
}

#[test]
fn the_started_standby_is_seen_operational_at_once_not_on_its_heartbeat_grid() {
    let p = Params::default();
    let mut n = SupNet::new(p);
    n.kill_slave_at(a(0), ms(1003));
    n.sim.run_until(ms(1200));
    let last_a = n.last_heartbeat(a(0), ms(1003));
    let start = n
        .nmt_first_copies()
        .into_iter()
        .find(|x| x.0 > ms(1000) && x.2 == NmtCommand::Start)
        .expect("the standby is started");
    assert_eq!(start.3, b(0));
    let hb = heartbeats(&n, b(0));
    let last_standby = *hb
        .iter()
        .rfind(|(t, _)| *t < start.0)
        .expect("the standby beat before");
    assert_eq!(last_standby.1, 0x7F, "pre-operational");
    let first_running = *hb
        .iter()
        .find(|(_, s)| *s == 0x05)
        .expect("B beats operational");
    // The instants, exact in simulated time (ends of the first copies on the wire).
    assert_eq!(last_a, Instant::from_micros(993_305));
    // Consumer time (50 ms) after A's last heartbeat, plus the NMT frame itself.
    assert_eq!(start.0, Instant::from_micros(1_043_374));
    // B handles the start when the frame ends and queues its heartbeat at once; it goes out
    // after the master's reset of A (already queued), 126 µs after the start.
    assert_eq!(first_running.0, Instant::from_micros(1_043_500));
    // Before, the first operational heartbeat came on B's grid: a period after its last
    // pre-operational one (the bus is idle then, so the frame takes the same time).
    let on_grid = last_standby.0 + p.slave_hb;
    assert_eq!(last_standby.0, Instant::from_micros(1_032_332));
    assert_eq!(on_grid, Instant::from_micros(1_052_332));
    assert!(on_grid > start.0);
    // So a master sees the standby running 8.832 ms earlier: 50.195 ms after A's last
    // heartbeat instead of 59.027 ms. The saving is wherever the start falls in B's period: up
    // to one period (20 ms here).
    assert_eq!(on_grid - first_running.0, Duration::from_micros(8_832));
    assert_eq!(first_running.0 - last_a, Duration::from_micros(50_195));
    assert_eq!(on_grid - last_a, Duration::from_micros(59_027));
    // B's grid starts over where it handled the start (1 043.374 ms): the next beat ends a
    // period later, plus the 58 µs the frame takes.
    let next = hb.iter().find(|(t, _)| *t > first_running.0).unwrap();
    assert_eq!(next.0, Instant::from_micros(1_063_432));
    // Both masters learn it from that frame, at that instant.
    for m in [STRONG, WEAK] {
        let seen = n.sup_events(m).into_iter().find_map(|e| match e {
            SupervisorEvent::Node(NodeEvent {
                at,
                kind:
                    NodeEventKind::RemoteState {
                        node,
                        to: NmtState::Operational,
                        ..
                    },
            }) if node.raw() == b(0) => Some(at),
            _ => None,
        });
        assert_eq!(seen, Some(first_running.0), "master {m}");
    }
}
