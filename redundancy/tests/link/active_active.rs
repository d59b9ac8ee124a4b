//! Active-active mode on the simulated dual bus: a master and 20 nodes exchange frames every
//! 10 ms while a bus is cut, a single port is unplugged, a port babbles, or a controller is
//! stuck error passive. Nothing is lost or doubled at the application; port states follow, at
//! exact instants in simulated time.

use crate::sim::*;
use duocan::{Duration, Frame, Id, Instant};
use duocan_redundancy::{DualBusConfig, LinkEventKind, Member, PortReason, PortState};

const SILENCE_LIMIT: Duration = Duration::from_millis(150);
const SUSPECT_AFTER: Duration = Duration::from_millis(50);
const CUT: Instant = Instant::from_millis(1_005);
const REPAIR: Instant = Instant::from_millis(2_000);
const STOP: Instant = Instant::from_millis(3_500);
const END: Instant = Instant::from_millis(3_600);
const SLAVES: u8 = 20;

fn run_to_end(net: &mut Net) {
    stop_sync(net, STOP);
    net.sim.run_until(END);
}

/// The port of every station on `bus` goes suspect (at its first failed transmission, or after
/// 50 ms of silence) and failed exactly the silence limit after the last frame it received or
/// had acknowledged; it returns to ok after the repair; the other port sees no event at all.
fn assert_bus_failed_and_recovered(net: &Net, bus: usize) {
    for node in 1..=SLAVES + 1 {
        let last = net.last_rx(node, bus, CUT);
        let ev = net.port_events(node, bus as u8);
        let (t, from, to, reason) = ev[0];
        assert_eq!(
            (from, to),
            (PortState::Ok, PortState::Suspect),
            "node {node}"
        );
        match reason {
            PortReason::Silence { silent } => {
                assert_eq!(
                    (t, silent),
                    (last + SUSPECT_AFTER, SUSPECT_AFTER),
                    "node {node}"
                )
            }
            PortReason::TxFailed(duocan::machine::ErrorCause::NoAck) => {
                assert!(t > CUT && t < last + SUSPECT_AFTER, "node {node}")
            }
            r => panic!("node {node}: suspect because {r:?}"),
        }
        let failed = net.last_heard(node, bus, CUT) + SILENCE_LIMIT;
        assert_eq!(
            ev[1],
            (
                failed,
                PortState::Suspect,
                PortState::Failed,
                PortReason::Silence {
                    silent: failed.saturating_since(last)
                }
            ),
            "node {node}"
        );
        // Re-initialised after a back-off of 100 ms, failed again after the silence limit,
        // re-initialised after 200 ms, … (the next attempt, 400 ms later, is after the repair).
        let ms = Duration::from_millis;
        let cycle: Vec<_> = ev[2..6].iter().map(|e| (e.0, e.2, e.3)).collect();
        let silence = PortReason::Silence {
            silent: SILENCE_LIMIT,
        };
        assert_eq!(
            cycle,
            [
                (
                    failed + ms(100),
                    PortState::Recovering,
                    PortReason::Reinit { attempt: 1 }
                ),
                (failed + ms(250), PortState::Failed, silence),
                (
                    failed + ms(450),
                    PortState::Recovering,
                    PortReason::Reinit { attempt: 2 }
                ),
                (failed + ms(600), PortState::Failed, silence),
            ],
            "node {node}"
        );
        let (t, _, to, reason) = *ev.last().unwrap();
        assert_eq!(
            (to, reason),
            (PortState::Ok, PortReason::Traffic),
            "node {node}"
        );
        assert!(
            t > REPAIR && t < REPAIR + Duration::from_millis(400),
            "node {node}: {t}"
        );
        assert_eq!(net.station(node).link.port_state(bus), PortState::Ok);
        assert!(
            net.port_events(node, 1 - bus as u8).is_empty(),
            "node {node}: the other bus stays ok"
        );
        let m = net.station(node).link.merger().stats();
        assert_eq!(m.evicted, 0);
    }
}

fn cut_bus(bus: usize) {
    cut_bus_on(network(1, SLAVES, active_active(), STOP), bus);
}

fn cut_bus_on(mut net: Net, bus: usize) {
    let b = net.buses[bus];
    net.sim.at(CUT, move |sim| sim.bus_down(b));
    net.sim.at(REPAIR, move |sim| sim.bus_up(b));
    run_to_end(&mut net);

    net.assert_application_exact();
    net.assert_no_heartbeat_lost();
    assert!(net.assert_sync_exact() > 340);
    assert_bus_failed_and_recovered(&net, bus);
    // On FD buses the counters travelled as FD frames: 21 stations, 340 cycles, two buses.
    let fd_frames = net
        .sim
        .trace()
        .iter()
        .filter(|r| matches!(r, duocan::sim::TraceRecord::Tx(x) if x.fd.is_some()))
        .count();
    assert_eq!(
        fd_frames > 10_000,
        net.station(MASTER).app.fd,
        "{fd_frames}"
    );

    // Reachability: the master reports every node heard on the surviving bus only, at the
    // node's last frame on the cut bus + the timeout, then on both again.
    for node in 2..=SLAVES + 1 {
        let last = net.last_tx(node, bus, CUT);
        let mut only = [false, false];
        only[1 - bus] = true;
        let ev = net.reach_events(MASTER, node);
        assert_eq!(ev[0].1, [true, true], "first report of node {node}");
        assert_eq!(ev[1], (last + SILENCE_LIMIT, only), "node {node}");
        assert_eq!(ev.last().unwrap().1, [true, true]);
    }
}

#[test]
fn cut_bus_1_mid_exchange_loses_and_doubles_nothing() {
    cut_bus(0);
}

#[test]
fn cut_bus_2_mid_exchange_loses_and_doubles_nothing() {
    cut_bus(1);
}

/// The same on CAN FD buses (1 Mbit/s nominal, 5 Mbit/s data), every application's counter
/// frame a 64-byte FD frame: each delivered once, in order, through the cut and the repair,
/// port states at the same instants (heartbeats and SYNC stay classic).
#[test]
fn on_fd_buses_cut_bus_1_mid_exchange_loses_and_doubles_nothing() {
    cut_bus_on(network_fd(1, SLAVES, active_active(), 5_000_000, STOP), 0);
}

#[test]
fn single_port_unplugged_is_failed_at_its_node_and_reported_by_the_others() {
    const NODE: u8 = 7;
    let mut net = network(2, SLAVES, active_active(), STOP);
    let port = net.dev(NODE).port(0);
    net.sim.at(CUT, move |sim| sim.disconnect(port));
    net.sim.at(REPAIR, move |sim| sim.reconnect(port));
    run_to_end(&mut net);

    net.assert_application_exact();
    net.assert_no_heartbeat_lost();
    // The node's own port fails exactly at the silence limit (after the last frame it
    // received or had acknowledged), and recovers after the repair.
    let last = net.last_heard(NODE, 0, CUT);
    let ev = net.port_events(NODE, 0);
    assert_eq!(ev[1].0, last + SILENCE_LIMIT);
    assert_eq!(ev[1].2, PortState::Failed);
    assert_eq!(net.station(NODE).link.port_state(0), PortState::Ok);
    // Everybody else: no port event, but "node 7 heard on bus 2 only", then both again.
    let last = net.last_tx(NODE, 0, CUT);
    for node in (1..=SLAVES + 1).filter(|n| *n != NODE) {
        assert!(net.port_events(node, 0).is_empty(), "node {node}");
        assert!(net.port_events(node, 1).is_empty(), "node {node}");
        let ev = net.reach_events(node, NODE);
        assert_eq!(ev[1], (last + SILENCE_LIMIT, [false, true]), "node {node}");
        assert_eq!(ev[2].1, [true, true], "node {node}");
        assert!(ev[2].0 >= REPAIR);
        // Nobody else lost sight of anybody.
        for other in (1..=SLAVES + 1).filter(|o| *o != NODE && *o != node) {
            assert_eq!(
                net.reach_events(node, other).len(),
                1,
                "{node} about {other}"
            );
        }
    }
}

#[test]
fn babbling_port_floods_bus_1_the_other_bus_carries_the_traffic_in_bounded_memory() {
    const NODE: u8 = 5;
    let mut net = network(3, SLAVES, active_active(), STOP);
    let port = net.dev(NODE).port(0);
    let flood = Frame::from_array(Id::Standard(0x001), [0xFF; 8]);
    net.sim.at(CUT, move |sim| sim.babble(port, Some(flood)));
    net.sim.at(REPAIR, move |sim| sim.babble(port, None));
    run_to_end(&mut net);

    net.assert_application_exact();
    net.assert_no_heartbeat_lost();
    let flooded = net
        .sim
        .trace()
        .iter()
        .filter(|r| matches!(r, duocan::sim::TraceRecord::Tx(t) if t.babble))
        .count();
    assert!(flooded > 5_000, "the flood ran: {flooded} frames");
    for node in 1..=SLAVES + 1 {
        let link = &net.station(node).link;
        // Bus 1 could not carry this station's frames. It was flushed and failed exactly the
        // stall time (3 ms, the window less the frame time) after bus 2 sent the twin of bus 1's oldest
        // waiting frame (or a later frame: the twin would be late), within a cycle and the
        // window of the flood's start; re-initialised after 100, 200, 400 ms, each time
        // failing again the same way. Meanwhile each heartbeat went there as a probe, was
        // flushed the same way, and the port stayed failed without a word.
        let ev = net.port_events(node, 0);
        let ms = Duration::from_millis;
        let stall = DualBusConfig::default().health.tx_stall;
        assert_eq!(stall, Duration::from_micros(3_000));
        let stalled = PortReason::TxStalled { waited: stall };
        let overtaken = |from: Instant, failed: Instant| {
            let twin = failed - stall;
            assert!(
                net.sent_from(node, 1, from).contains(&twin) && twin < from + ms(16),
                "node {node}: no frame sent on bus 2 the stall time before the stall at {failed:?}"
            );
        };
        let mut want = vec![];
        let mut t = CUT;
        for (attempt, backoff) in [(1, 100), (2, 200), (3, 400)] {
            let failed = ev[want.len()].0;
            overtaken(t, failed);
            want.push((failed, PortState::Failed, stalled));
            t = failed + ms(backoff);
            want.push((t, PortState::Recovering, PortReason::Reinit { attempt }));
        }
        let failed = ev[want.len()].0;
        overtaken(t, failed);
        want.push((failed, PortState::Failed, stalled));
        // The flood over, the first probe is confirmed (in time): back at once, not at the
        // fourth re-initialisation 800 ms later; ok after the 50 ms probation.
        let back = net.sent_from(node, 0, REPAIR)[0];
        assert!(
            back < REPAIR + ms(HB_MS as u64),
            "node {node}: back at {back:?}"
        );
        want.push((back, PortState::Recovering, PortReason::Traffic));
        let got: Vec<_> = ev.iter().map(|e| (e.0, e.2, e.3)).collect();
        assert_eq!(got[..8], want[..], "node {node}");
        assert_eq!(got.len(), 9, "node {node}: {got:?}");
        assert_eq!((got[8].1, got[8].2), (PortState::Ok, PortReason::Traffic));
        // Probation runs from the first frame bus 1 brings after that.
        let heard = (1..=SLAVES + 1)
            .filter(|n| *n != node)
            .flat_map(|n| net.sent_from(n, 0, back - ms(1)))
            .filter(|end| *end >= back)
            .min()
            .expect("bus 1 carries traffic again");
        assert!(
            got[8].0 >= heard + ms(50) && got[8].0 < heard + ms(60),
            "node {node}: heard at {heard:?}, {got:?}"
        );
        assert_eq!(link.port_state(0), PortState::Ok, "node {node} recovered");
        assert!(net.port_events(node, 1).is_empty(), "node {node}");
        // The flood passed through this station's merger without growing it.
        // (Unmatched copies wait for the other bus up to the horizon, 80 ms: the babbler's own
        // station, which does not hear its flood, keeps its bus-2 copies that long.)
        let m = link.merger().stats();
        assert_eq!(m.evicted, 0, "node {node}");
        assert!(
            m.high_water < 500,
            "node {node}: high water {}",
            m.high_water
        );
        let stats = link.stats();
        assert_eq!((stats.events_dropped, stats.tx_dropped), (0, 0));
    }
}

/// A station that sends nothing while its own port babbles fails that port for silence, not
/// for a stall; its heartbeat then goes there as a probe and waits behind the flood. Held past
/// the stall time after its twin went out on the other bus, the probe is flushed (and the
/// port counted stalled): every frame of the station on bus 1 has its twin on bus 2 within
/// the window, none comes out stale when the flood ends (which every other station would take
/// for a frame of its own).
#[test]
fn a_probe_held_behind_a_babble_is_flushed_not_sent_stale() {
    const NODE: u8 = 5;
    let mut net = network(5, SLAVES, active_active(), STOP);
    let d = net.dev(NODE);
    let port = d.port(0);
    let flood = Frame::from_array(Id::Standard(0x001), [0xFF; 8]);
    let beat = move |sim: &mut duocan::sim::SimNetwork, t: Instant, ms: u16| {
        sim.device_mut(d)
            .machine
            .a
            .set(t, duocan::od::comm::HEARTBEAT_PRODUCER, 0, ms)
            .unwrap();
    };
    // Quiet (no application frames, no heartbeat) as its flood starts; beating again once its
    // bus-1 port has failed for silence (150 ms), the flood over before that port's first
    // re-initialisation (100 ms after it failed) would have flushed it.
    net.sim.device_mut(d).machine.b.stop_at = Instant::ZERO;
    net.sim.at(CUT, move |sim| {
        beat(sim, CUT, 0);
        sim.babble(port, Some(flood));
    });
    let again = CUT + Duration::from_millis(160);
    net.sim.at(again, move |sim| beat(sim, again, HB_MS));
    let over = CUT + Duration::from_millis(200);
    net.sim.at(over, move |sim| sim.babble(port, None));
    run_to_end(&mut net);

    let ev = net.port_events(NODE, 0);
    assert!(
        matches!(
            ev[..2],
            [
                (_, _, PortState::Suspect, PortReason::Silence { .. }),
                (_, _, PortState::Failed, PortReason::Silence { .. })
            ]
        ),
        "{ev:?}"
    );
    let mine = |bus| -> Vec<(Instant, Frame)> {
        net.wire(bus)
            .into_iter()
            .filter(|w| w.1 == NODE && w.0 > again)
            .filter(|w| matches!(w.3, duocan::sim::TxOutcome::Delivered { .. }))
            .map(|w| (w.0, w.2))
            .collect()
    };
    let (bus1, bus2) = (mine(0), mine(1));
    assert!(bus2.len() > 20, "it beats on bus 2: {bus2:?}");
    let window = DualBusConfig::default().skew_window;
    for (t, f) in &bus1 {
        assert!(
            bus2.iter().any(|(u, g)| g == f
                && t.saturating_since(*u) <= window
                && u.saturating_since(*t) <= window),
            "{f:?} on bus 1 at {t:?} without its twin on bus 2 within the window: {bus2:?}"
        );
    }
    net.assert_application_exact();
}

#[test]
fn a_pair_is_one_stream_from_its_active_member_and_discrepancies_are_reported() {
    let switch = Instant::from_millis(1_500);
    let mut net = network(4, SLAVES, active_active(), STOP);
    let m = net.dev(MASTER);
    let (a, b) = (duocan::NodeId::must(2), duocan::NodeId::must(3));
    let pair = net
        .sim
        .device_mut(m)
        .link
        .add_pair(a, b, Some(Member::A))
        .unwrap();
    net.sim.at(switch, move |sim| {
        assert!(sim.device_mut(m).link.set_active(pair, Some(Member::B)));
    });
    run_to_end(&mut net);

    // The master's application gets the pair's process data from A until the switch, from B
    // after it; everything else as usual.
    let app = &net.station(MASTER).machine.b;
    let from = |node: u16| -> Vec<Instant> {
        app.received
            .iter()
            .filter(|(_, f)| f.id().raw() & 0x7F == node as u32)
            .map(|(t, _)| *t)
            .collect()
    };
    let (got_a, got_b) = (from(2), from(3));
    assert!(got_a.len() > 250 && got_a.iter().all(|t| *t < switch));
    assert!(got_b.len() > 350 && got_b.iter().all(|t| *t > switch));
    for r in 2..=SLAVES + 1 {
        net.assert_application_exact_at(r);
    }
    // The standby's values are kept: B's last counter before the switch is known.
    let link = &net.station(MASTER).link;
    let (t, last_a) = link.pairs().latest(pair, Member::A, 1).unwrap();
    assert!(t < STOP + Duration::from_millis(10) && last_a.id() == Id::Standard(0x182));
    // TPDO2 carries the node-ID: A and B always differ, reported 100 ms after B's first TPDO2
    // reached the master (A's came first). TPDO1 counters differ only for the 300 µs between
    // the two boards' cycles: never reported.
    let b_first = net
        .wire(0)
        .iter()
        .filter(|x| x.1 == 3 && x.2.id() == Id::Standard(0x283))
        .map(|x| x.0)
        .min()
        .unwrap();
    let disc: Vec<_> = net
        .link_events(MASTER)
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::Discrepancy {
                pair: p,
                function,
                a,
                b,
            } => Some((e.at, p, function, a.data()[0], b.data()[0])),
            _ => None,
        })
        .collect();
    assert_eq!(
        disc,
        [(b_first + Duration::from_millis(100), pair, 2, 2, 3)]
    );
}

/// A burst of higher-priority traffic on both buses, three times the skew window long: every
/// station's frames wait on both buses alike (lost arbitration, not a stall), go out after it on
/// both, and their twins match. No port fails, nothing is flushed, nothing delivered twice.
#[test]
fn frames_waiting_on_both_busy_buses_longer_than_the_window_are_not_a_stall() {
    const NODE: u8 = 5;
    const BURST: Duration = Duration::from_millis(30);
    let mut net = network(3, SLAVES, active_active(), STOP);
    let flood = Frame::from_array(Id::Standard(0x001), [0xFF; 8]);
    let ports = [net.dev(NODE).port(0), net.dev(NODE).port(1)];
    net.sim.at(CUT, move |sim| {
        for p in ports {
            sim.babble(p, Some(flood));
        }
    });
    net.sim.at(CUT + BURST, move |sim| {
        for p in ports {
            sim.babble(p, None);
        }
    });
    run_to_end(&mut net);

    net.assert_application_exact();
    net.assert_no_heartbeat_lost();
    for node in 1..=SLAVES + 1 {
        // Every station had frames waiting for the whole burst.
        let waited = net.sent_from(node, 0, CUT);
        assert!(waited[0] > CUT + BURST, "node {node}: {:?}", waited[0]);
        for port in 0..2 {
            assert!(
                net.port_events(node, port).is_empty(),
                "node {node} port {port}"
            );
        }
        let link = &net.station(node).link;
        for port in 0..2 {
            assert_eq!(link.port(port).counters().reinits, 0, "node {node}");
        }
    }
}

/// A node whose controller on one bus sends late (its mailboxes behind traffic only it sees,
/// a driver that batches): its copies there would leave after their twins. Later than the
/// stall time, each is flushed before it could come out as a duplicate and the port fails
/// (`TxStalled`) once; while the slowness lasts the node's heartbeats go there as probes, each
/// flushed the same way without a word (re-initialisation retries aside), and the first probe
/// confirmed in time after it ends brings the port back, within a heartbeat period. Either
/// bus: at the slow node, a failed port's copies of the others' frames arrive first on bus 1
/// and second on bus 2 (receiving says nothing of a transmitter). Slower by less than the
/// stall time, its twins stay within the window: no event at all. Exactly once throughout.
#[test]
fn a_slow_transmitter_on_one_bus_is_flushed_not_duplicated_and_used_again_at_its_next_probe() {
    const NODE: u8 = 5;
    let ms = Duration::from_millis;
    for (port, delay) in [(0, ms(10)), (1, ms(10)), (1, Duration::from_micros(1_500))] {
        let mut net = network(7, SLAVES, active_active(), STOP);
        let p = net.dev(NODE).port(port);
        net.sim
            .at(CUT, move |sim| sim.set_port_tx_latency(p, delay));
        net.sim.at(REPAIR, move |sim| {
            sim.set_port_tx_latency(p, Duration::ZERO)
        });
        run_to_end(&mut net);
        net.assert_application_exact();
        net.assert_no_heartbeat_lost();
        let waited = net.sim.port_stats(p).tx_waited;
        assert!(
            waited > 10,
            "port {port}: the fault ran ({waited} frames waited)"
        );
        let ev = net.port_events(NODE, port as u8);
        let other = net.port_events(NODE, 1 - port as u8);
        assert!(other.is_empty(), "port {port}: the other port {other:?}");
        for node in (1..=SLAVES + 1).filter(|n| *n != NODE) {
            assert!(net.port_events(node, 0).is_empty(), "node {node}");
            assert!(net.port_events(node, 1).is_empty(), "node {node}");
        }
        if delay < DualBusConfig::default().health.tx_stall {
            assert!(ev.is_empty(), "{delay:?} late: {ev:?}");
            continue;
        }
        // Failed at its first frame after the onset; then only the re-initialisations'
        // retries (100, 200, 400 ms: each fails again), no event for the flushed probes.
        let stalled = PortReason::TxStalled {
            waited: Duration::from_micros(3_000),
        };
        assert_eq!((ev[0].2, ev[0].3), (PortState::Failed, stalled), "{ev:?}");
        assert!(ev[0].0 < CUT + ms(16), "{ev:?}");
        let during: Vec<_> = ev.iter().filter(|e| e.0 < REPAIR).collect();
        assert_eq!(during.len(), 7, "port {port}: {during:?}");
        // Back at the first frame it sent after the end: a probe, within a heartbeat period.
        let back = net.sent_from(NODE, port, REPAIR)[0];
        assert!(
            back < REPAIR + ms(HB_MS as u64),
            "port {port}: back at {back:?}"
        );
        let after: Vec<_> = ev.iter().filter(|e| e.0 >= REPAIR).collect();
        assert_eq!(
            (after[0].0, after[0].2, after[0].3),
            (back, PortState::Recovering, PortReason::Traffic),
            "port {port}: {after:?}"
        );
        assert_eq!(after.len(), 2, "port {port}: {after:?}");
        assert_eq!(after[1].2, PortState::Ok);
    }
}

#[test]
fn a_controller_stuck_error_passive_on_one_bus_loses_nothing_and_fails_no_port() {
    // Node 5's controller on one bus held error passive from the cut to the repair: after each
    // of its frames it sits out the suspend-transmission time, so on every 10 ms burst the 20
    // other stations' frames go first there, while its twins on the other bus win by their
    // identifier. The skew stays within the window: nothing lost or doubled, the port suspect
    // for the report only, no other port touched.
    const NODE: u8 = 5;
    for (port, tec) in [(0, 128), (1, 250)] {
        let mut net = network(7, SLAVES, active_active(), STOP);
        let p = net.dev(NODE).port(port);
        net.sim
            .at(CUT, move |sim| sim.set_port_error_passive(p, Some(tec)));
        net.sim.at(REPAIR, move |sim| {
            assert!(sim.is_port_error_passive(p), "held until now");
            sim.set_port_error_passive(p, None)
        });
        run_to_end(&mut net);
        net.assert_application_exact();
        net.assert_no_heartbeat_lost();
        // The fault ran: some of its frames there came out after their twins on the other
        // bus (each behind a frame queued while it sat out its suspend time).
        let during = |bus: usize| -> Vec<Instant> {
            let sent = net.sent_from(NODE, bus, CUT);
            sent.into_iter().filter(|t| *t < REPAIR).collect()
        };
        let (held, other) = (during(port), during(1 - port));
        assert_eq!(held.len(), other.len(), "port {port}");
        let later = held.iter().zip(&other).filter(|(h, o)| h > o).count();
        assert!(
            later > held.len() / 4,
            "port {port}: {later} of {} later",
            held.len()
        );
        // Back to error active once it sent enough frames to count down under 128.
        assert!(!net.sim.is_port_error_passive(p), "port {port}");
        let ev = net.port_events(NODE, port as u8);
        let warned = PortReason::Controller(duocan::machine::ErrorCause::ErrorWarning);
        assert_eq!(
            ev.iter().map(|e| (e.1, e.2, e.3)).collect::<Vec<_>>(),
            [
                (PortState::Ok, PortState::Suspect, warned),
                (PortState::Suspect, PortState::Ok, PortReason::Traffic),
            ],
            "port {port}: {ev:?}"
        );
        assert_eq!(ev[0].0, CUT);
        assert!(net.port_events(NODE, 1 - port as u8).is_empty());
        for node in (1..=SLAVES + 1).filter(|n| *n != NODE) {
            assert!(net.port_events(node, 0).is_empty(), "node {node}");
            assert!(net.port_events(node, 1).is_empty(), "node {node}");
        }
    }
}
