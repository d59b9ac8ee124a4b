//! A bus that lags: the master's port on bus 2 hands it every frame a fixed time late (the
//! simulator's per-port latency), a slave sends a cyclic TPDO with a counter and an unchanged
//! one every 20 ms for 10 s, and a heartbeat every 50 ms.
//!
//! With receive timestamps (the simulator stamps each frame with its wire time, as SocketCAN's
//! kernel does), a port whose receive path runs behind shows no lag at all: every twin is found
//! by its stamp, however far behind it runs while it hands copies over (the merger keeps the
//! other port's copies until it has shown their twins); a reader that freezes beyond the
//! merger's horizon (80 ms by default) has its late copies dropped as late, the other bus
//! having delivered them. Without timestamps (a driver
//! that stamps a frame when it hands it over), the lag shows between twins: it is measured from
//! the frames whose content changes (the counter), corrected, reported, and the copies before
//! the second such frame may come twice; repeats never measure it.

use super::sim::{App, Dev, Net, WideTpdo1, HB_MS, MASTER};
use duocan::machine::{BusLink, Composite};
use duocan::od::comm;
use duocan::sim::{BusConfig, SimNetwork, TxOutcome};
use duocan::{Duration, Frame, Id, Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEventKind, LinkMode, PortReason, PortState};

const SLAVE: u8 = 2;
const PERIOD: Duration = Duration::from_millis(20);
const START: Instant = Instant::from_millis(100);
const STOP: Instant = Instant::from_millis(10_100);
const END: Instant = Instant::from_millis(10_300);

fn ms(x: u64) -> Duration {
    Duration::from_millis(x)
}

/// The default active-active timing for a 50 ms heartbeat: skew window 5 ms, maximum 40 ms,
/// silence limit (and lag period) 150 ms.
fn config() -> DualBusConfig {
    DualBusConfig::with_guard_period(LinkMode::ActiveActive, ms(HB_MS as u64))
}

/// The master (node 1) and the slave (node 2) on two 1 Mbit/s buses; the master's port on bus
/// 2 lags by `lag`.
fn rig(lag: Duration) -> Net {
    let mut sim = SimNetwork::new(1);
    let buses = [
        sim.add_bus(BusConfig::new("can1", 1_000_000)),
        sim.add_bus(BusConfig::new("can2", 1_000_000)),
    ];
    let mut devs = vec![];
    for id in [MASTER, SLAVE] {
        let nid = NodeId::must(id);
        let od = comm::standard_dictionary(id, comm::Identity::default());
        let nc = if id == MASTER {
            NodeConfig::master(nid)
        } else {
            NodeConfig::slave(nid)
        };
        let mut node = Node::new(nc, od);
        node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, HB_MS)
            .unwrap();
        node.boot(Instant::ZERO);
        let app = App::new(id, START, PERIOD, STOP);
        let station = Station::new(DualBus::new(config()), Composite::new(node, app));
        let station = Dev::new(station, WideTpdo1 { fd: false });
        devs.push(sim.add_device(format!("n{id}"), station, &buses).unwrap());
    }
    sim.set_port_latency(devs[0].port(1), lag);
    Net { sim, buses, devs }
}

impl Net {
    /// The end of the slave's transmissions of `frame` on `bus` that reached the master.
    fn slave_frames(&self, bus: usize) -> Vec<(Instant, Frame)> {
        self.wire(bus)
            .into_iter()
            .filter(|(_, s, _, o)| *s == SLAVE && matches!(o, TxOutcome::Delivered { .. }))
            .map(|(t, _, f, _)| (t, f))
            .collect()
    }
    /// The master's lag reports: (instant, port, lag, window), and its port events.
    fn lag_events(&self) -> Vec<(Instant, LinkEventKind)> {
        self.link_events(MASTER)
            .into_iter()
            .filter(|e| {
                matches!(
                    e.kind,
                    LinkEventKind::Lag { .. }
                        | LinkEventKind::LagCleared { .. }
                        | LinkEventKind::Port { .. }
                )
            })
            .map(|e| (e.at, e.kind))
            .collect()
    }
    fn master_link(&self) -> &DualBus {
        &self.station(MASTER).link
    }
}

/// The slave's application frames reached the master's application exactly once, in order.
fn assert_exact(net: &Net) {
    let app = &net.station(MASTER).machine.b;
    let sent = net.station(SLAVE).machine.b.sent_counter;
    assert_eq!(sent, 500);
    assert_eq!(app.counters_from(SLAVE), (0..sent).collect::<Vec<_>>());
    assert_eq!(app.constants_from(SLAVE), 500);
}

/// Bus 2's receive path runs `lag_ms` behind, its frames stamped on the wire: nothing comes
/// twice, nothing is lost, no lag is reported, bus 2 stays ok. Beyond the horizon, until bus
/// 2's reader hands its first copy over, nothing shows that it runs behind (it is as silent
/// as a dead bus): bus 1's copies from before then may be given up at the horizon, and their
/// twins dropped as late; none after.
fn stamped_lag(lag_ms: u64) {
    let mut net = rig(ms(lag_ms));
    net.sim.run_until(END);
    assert_exact(&net);
    let link = net.master_link();
    let merged = link.merger().stats();
    assert_eq!((merged.slipped, merged.evicted), (0, 0));
    let first_handed = net.slave_frames(1)[0].0 + ms(lag_ms);
    let before = net
        .slave_frames(0)
        .iter()
        .filter(|(t, _)| *t < first_handed)
        .count() as u64;
    assert!(
        merged.late == 0 || (lag_ms > 80 && merged.late <= before),
        "{merged:?}, {before} copies before bus 2's first"
    );
    let sent = net.slave_frames(0).len() as u64;
    assert_eq!(sent, net.slave_frames(1).len() as u64);
    assert_eq!(link.stats().delivered, sent);
    assert_no_lag_nor_failure(&net);
    assert_eq!(link.lag().lag(1), Duration::ZERO);
    assert_eq!(
        (link.port_state(0), link.port_state(1)),
        (PortState::Ok, PortState::Ok)
    );
}

/// No lag reported and no port failed. (A reader that hands nothing over for longer than the
/// suspect time is reported suspect meanwhile: at the start, before its first frame, or when
/// its delay jumps; that is no failure.)
fn assert_no_lag_nor_failure(net: &Net) {
    for (t, e) in net.lag_events() {
        match e {
            LinkEventKind::Port { to, reason, .. } => assert!(
                to != PortState::Failed
                    && matches!(reason, PortReason::Silence { .. } | PortReason::Traffic),
                "{t} {e:?}"
            ),
            e => panic!("{t} {e:?}"),
        }
    }
}

#[test]
fn a_receive_path_12_ms_behind_costs_nothing() {
    stamped_lag(12);
}

#[test]
fn a_receive_path_25_ms_behind_costs_nothing() {
    stamped_lag(25);
}

#[test]
fn a_receive_path_45_ms_behind_costs_nothing() {
    stamped_lag(45);
}

#[test]
fn a_receive_path_75_ms_behind_within_the_horizon_costs_nothing() {
    stamped_lag(75);
}

/// 100 ms behind, beyond the 80 ms horizon: bus 1's copies are kept while bus 2's reader,
/// running that far behind, has not shown their twins, so every twin is still found.
#[test]
fn a_receive_path_100_ms_behind_beyond_the_horizon_costs_nothing() {
    stamped_lag(100);
}

/// And 400 ms behind, five horizons.
#[test]
fn a_receive_path_400_ms_behind_costs_nothing() {
    stamped_lag(400);
}

/// A reader that freezes: bus 2's receive path hands nothing over for 120 ms (its delay jumps
/// from none to 120 ms), which the merger cannot tell from a bus that stopped carrying frames
/// until it hands over again. Bus 1's copies from the first 40 ms of it are given up at the
/// horizon; their twins, when they come, are dropped as late (bus 1 delivered their time's
/// frames). Nothing comes twice, nothing is lost, and the drops are counted.
#[test]
fn a_receive_path_frozen_beyond_the_horizon_has_its_late_copies_dropped() {
    let mut net = rig(Duration::ZERO);
    net.sim.run_until(Instant::from_millis(5_000));
    let port = net.dev(MASTER).port(1);
    net.sim.set_port_latency(port, ms(120));
    net.sim.run_until(END);
    assert_exact(&net);
    let link = net.master_link();
    let merged = link.merger().stats();
    let sent = net.slave_frames(0).len() as u64;
    assert_eq!(link.stats().delivered, sent);
    assert!(merged.late > 0 && merged.forgotten > 0, "{merged:?}");
    assert_eq!(link.port(1).counters().stale, merged.late);
}

/// Without receive timestamps bus 2's copies are stamped when handed over, 25 ms after their
/// twins. Repeats cannot measure it, nor the first frames after the start (bus 2 had nothing
/// before them to show it was receiving); the counter TPDO (fresh every time) does, at the
/// second late twin that agrees. Before that, counters 0 and 1 come a second time, each at its
/// bus-2 copy; so do the first two copies of the constant TPDO (20 ms apart, 25 ms late: no
/// twin within the 5 ms window), the boot-up and the first heartbeats (50 ms apart); after
/// that, nothing.
#[test]
fn a_lag_without_timestamps_is_measured_from_fresh_frames_and_corrected() {
    let lag = ms(25);
    let mut net = rig(lag);
    let port = net.dev(MASTER).port(1);
    net.sim.set_port_stamps(port, false);
    net.sim.run_until(END);
    let link = net.master_link();
    assert_eq!(link.lag().lag(1), lag);
    let lags: Vec<_> = net
        .lag_events()
        .into_iter()
        .filter(|(_, k)| {
            matches!(
                k,
                LinkEventKind::Lag { .. } | LinkEventKind::LagCleared { .. }
            )
        })
        .collect();
    let counters: Vec<Instant> = net
        .slave_frames(1)
        .into_iter()
        .filter(|(_, f)| f.id() == Id::Standard(0x182))
        .map(|(e, _)| e)
        .collect();
    assert_eq!(
        lags,
        [(
            counters[1] + lag,
            LinkEventKind::Lag {
                port: 1,
                lag,
                window: ms(30)
            }
        )]
    );
    let app = &net.station(MASTER).machine.b;
    let want: Vec<u32> = [0, 1, 0, 2, 1].into_iter().chain(3..500).collect();
    assert_eq!(app.counters_from(SLAVE), want);
    assert_eq!(app.constants_from(SLAVE), 502);
    let sent = net.slave_frames(0).len() as u64;
    let merged = link.merger().stats();
    // And three error-control frames, the boot-up and the first heartbeats (50 ms apart, 25
    // ms late: no twin in the window before the correction).
    assert_eq!(link.stats().delivered - sent, 2 + 2 + 3);
    assert!(merged.slipped >= 1, "{merged:?}");
    assert_eq!(link.port_state(1), PortState::Ok);
}

/// Bus 2's receive path runs 40 ms behind; at 5 s the master's bus-1 port is unplugged: bus 2
/// is all it has. Every frame the slave sends after its last one on bus 1 is delivered from bus
/// 2, exactly 40 ms after it ended on the wire; none twice, none lost.
#[test]
fn when_the_good_bus_dies_the_late_one_delivers_everything_after_its_last_frame() {
    const CUT: Instant = Instant::from_millis(5_003);
    let mut net = rig(ms(40));
    let port = net.dev(MASTER).port(0);
    net.sim.at(CUT, move |sim| sim.disconnect(port));
    net.sim.run_until(END);

    assert_exact(&net);
    let last_on_bus_1 = net.last_rx(MASTER, 0, END);
    assert!(last_on_bus_1 < CUT && last_on_bus_1 > CUT - PERIOD);
    let ends: Vec<(Instant, Frame)> = net.slave_frames(1);
    let app = &net.station(MASTER).machine.b;
    let after: Vec<_> = app.received.iter().filter(|(t, _)| *t > CUT).collect();
    assert!(after.len() > 480, "{}", after.len());
    for (t, f) in after {
        let end = ends
            .iter()
            .find(|(e, g)| g == f && *e + ms(40) == *t)
            .map(|(e, _)| *e);
        assert!(end.is_some_and(|e| e > last_on_bus_1), "{t} {f}");
    }
    let link = net.master_link();
    assert_eq!(link.port_state(0), PortState::Failed);
    assert_eq!(link.merger().stats().slipped, 0);
}

/// Bus 2's receive path runs 40 ms behind until 5 s, then catches up at once, then falls 70 ms
/// behind at 7 s: nothing twice, nothing lost, nothing reported.
#[test]
fn a_receive_path_that_catches_up_and_falls_behind_again_costs_nothing() {
    let mut net = rig(ms(40));
    let port = net.dev(MASTER).port(1);
    net.sim.at(Instant::from_millis(5_000), move |sim| {
        sim.set_port_latency(port, Duration::ZERO)
    });
    net.sim.at(Instant::from_millis(7_000), move |sim| {
        sim.set_port_latency(port, ms(70))
    });
    net.sim.run_until(END);
    assert_exact(&net);
    let link = net.master_link();
    assert_eq!(link.merger().stats().slipped, 0);
    assert_eq!(link.stats().delivered, net.slave_frames(0).len() as u64);
    assert_no_lag_nor_failure(&net);
}

/// The frame pattern of an LSS fastscan (and of any unchanged frame two nodes send at once)
/// with one of the nodes on bus 2 only: every 33 ms bus 2 carries two identical frames 0.1 ms
/// apart, bus 1 the first node's copy only; bus 2's reader hands frames over 1 ms late, so bus
/// 1's copy comes first. It is the twin of bus 2's first copy, still to come; bus 2's second
/// copy of the step before (the node on bus 2 only, no twin) is a repeat, not a twin 33 ms
/// late. (Taken for fresh because it was stamped before bus 1's copy of its own step, it made
/// the layer measure a 33 ms lag and deliver answers twice, and an LSS master misread a bit.)
#[test]
fn a_node_on_one_bus_answering_beside_one_on_both_is_no_lag() {
    let mut l: DualBus = DualBus::new(DualBusConfig::default());
    let f = Frame::from_array(Id::Standard(0x7E4), [0x4F, 0, 0, 0, 0, 0, 0, 0]);
    let us = Duration::from_micros;
    let mut delivered = 0;
    for k in 0..100u64 {
        let t = Instant::from_millis(1000 + 33 * k);
        // (handed over, stamp, port), in the order handed over.
        for (now, at, port) in [
            (t + us(350), t + us(300), 0),
            (t + us(1000), t, 1),
            (t + us(1100), t + us(100), 1),
        ] {
            while let Some(d) = duocan::machine::BusLink::poll_timeout(&l).filter(|d| *d <= now) {
                duocan::machine::BusLink::handle_timeout(&mut l, d);
            }
            delivered +=
                duocan::machine::BusLink::handle_rx_at(&mut l, now, port, &f, at).is_some() as u32;
        }
    }
    assert_eq!(delivered, 200);
    assert_eq!(
        (l.lag().lag(0), l.lag().lag(1)),
        (Duration::ZERO, Duration::ZERO)
    );
    while let Some(e) = duocan::machine::BusLink::poll_event(&mut l) {
        assert!(!matches!(e.kind, LinkEventKind::Lag { .. }), "{e:?}");
    }
}

/// Campaign seed 2056 (quiet network): bus 1 flapping every millisecond lost the first copy of
/// an SDO request and of its answer; the sender of each repeated it 5 ms later on both buses.
/// Paired with the first copies, the repeats' bus-1 copies were two fresh twins 5 ms late that
/// agreed: a lag of 5 ms was measured, and every twin after it came twice for 200 ms. Each
/// repeat's own twin, on bus 2 within the window, now withdraws the sample.
#[test]
fn a_frame_one_bus_missed_and_its_sender_repeated_is_no_lag() {
    let mut l = DualBus::new(config());
    let t = Instant::from_micros;
    let hb = Frame::from_array(Id::Standard(0x705), [0x05]);
    let req = Frame::from_array(Id::Standard(0x650), [0x40, 0, 0x20, 1, 0, 0, 0, 0]);
    let ans = Frame::from_array(Id::Standard(0x5D0), [0x4B, 0, 0x20, 1, 0xA5, 0x5A, 0, 0]);
    let rx = |l: &mut DualBus, at: u64, port: usize, f: &Frame| {
        let d = l.handle_rx_at(t(at), port, f, t(at)).is_some() as u32;
        while l.poll_event().is_some() {}
        d
    };
    // Both buses carry a heartbeat every 50 ms for a second: both ports work.
    for k in 0..20 {
        rx(&mut l, k * 50_000, 0, &hb);
        rx(&mut l, k * 50_000 + 20, 1, &hb);
    }
    // The request and its answer on bus 2 only; a heartbeat on both; both repeated 5 ms later.
    rx(&mut l, 1_000_000, 1, &req);
    rx(&mut l, 1_000_120, 1, &ans);
    rx(&mut l, 1_002_000, 0, &hb);
    rx(&mut l, 1_002_020, 1, &hb);
    rx(&mut l, 1_005_061, 0, &req);
    rx(&mut l, 1_005_061, 1, &req);
    rx(&mut l, 1_005_181, 0, &ans);
    rx(&mut l, 1_005_181, 1, &ans);
    assert_no_lag_and_twins_once(&mut l, 1_010_000);
}

/// No lag measured on either port, and ten fresh twins 30 µs apart from `from` (µs), stamped
/// as handed over, are delivered once each.
fn assert_no_lag_and_twins_once(l: &mut DualBus, from: u64) {
    assert_eq!(
        (l.lag().lag(0), l.lag().lag(1)),
        (Duration::ZERO, Duration::ZERO)
    );
    let t = Instant::from_micros;
    let mut delivered = 0;
    for k in 0..10 {
        let (at, f) = (
            from + k * 10_000,
            Frame::from_array(Id::Standard(0x181), [k as u8]),
        );
        for (port, at) in [(0, at), (1, at + 30)] {
            delivered += l.handle_rx_at(t(at), port, &f, t(at)).is_some() as u32;
            while l.poll_event().is_some() {}
        }
    }
    assert_eq!(delivered, 10);
}

/// Two fresh frames on bus 1 late on its wire by 8.3 and 8.9 ms (retransmissions behind a
/// node destroying frames), while bus 2's receive path runs 13 ms behind: bus 2's copies,
/// stamped that much earlier, are handed over 4.7 and 4.2 ms after their twins. That is no
/// receive clock that is off (its copies would come within half a window of their twins):
/// no lag is measured. (Taken for one, a correction of 8.9 ms, then 17.6 ms, put the next
/// SYNCs and heartbeats past their twins' window: dropped as twins of the ones before.)
#[test]
fn a_twin_late_on_its_wire_beside_a_reader_as_far_behind_is_no_lag() {
    let mut l = DualBus::new(config());
    let t = Instant::from_micros;
    let hb = Frame::from_array(Id::Standard(0x705), [0x05]);
    let f1 = Frame::from_array(Id::Standard(0x290), [0x00, 0x10]);
    let f2 = Frame::from_array(Id::Standard(0x292), [0x02, 0x10]);
    let rx = |l: &mut DualBus, now: u64, port: usize, f: &Frame, at: u64| {
        let d = l.handle_rx_at(t(now), port, f, t(at)).is_some() as u32;
        while l.poll_event().is_some() {}
        d
    };
    for k in 0..20 {
        rx(&mut l, k * 50_000, 0, &hb, k * 50_000);
        rx(&mut l, k * 50_000 + 20, 1, &hb, k * 50_000 + 20);
    }
    let s = 1_000_000;
    rx(&mut l, s + 8_300, 0, &f1, s + 8_300);
    rx(&mut l, s + 9_000, 0, &f2, s + 9_000);
    rx(&mut l, s + 13_000, 1, &f1, s);
    rx(&mut l, s + 13_100, 1, &f2, s + 100);
    assert_no_lag_and_twins_once(&mut l, s + 20_000);
}

/// Bus 2's receive path, without timestamps, drifts from on time to 20 ms late by half a
/// millisecond every 200 ms (a hand-over delay that creeps, or two adapters' clocks apart):
/// matched twins near the window's edge start the correction before the skew leaves the
/// window, and then follow it. Nothing twice, nothing lost. (Started only from twins beyond
/// the window, the correction let 11 frames through twice.)
#[test]
fn a_lag_that_drifts_without_timestamps_is_followed_before_it_leaves_the_window() {
    let mut net = rig(Duration::ZERO);
    let port = net.dev(MASTER).port(1);
    net.sim.set_port_stamps(port, false);
    for k in 0..=40u64 {
        net.sim.at(START + ms(200 * k), move |sim| {
            sim.set_port_latency(port, Duration::from_micros(500 * k))
        });
    }
    net.sim.run_until(END);
    assert_exact(&net);
    let link = net.master_link();
    assert_eq!(link.merger().stats().slipped, 0);
    let lag = link.lag().lag(1);
    assert!(lag >= ms(16) && lag <= ms(20), "{lag:?}");
}

/// The master's receive clock on bus 2 runs 5,000 ppm slow (two adapters' crystals, minutes of
/// drift in seconds) while bus 1 is cut from 0.5 s to 3 s: at the repair, bus 2's stamps are
/// 14.5 ms behind bus 1's, though both copies of each frame reach the master together. Their
/// two fresh frames after the repair measure it (copies that came together stamped apart
/// are a clock off, not a reader running behind), the correction follows the drift, and when
/// the clock is resynchronised at 6 s it is taken back: each change costs the copies up to its
/// second measuring frame (after the repair, from the port's return on: it measures nothing
/// on probation). (Taken for a reader running behind, the skew was never measured: every
/// frame came twice until the resynchronisation.)
#[test]
fn a_receive_clock_that_drifted_while_the_other_bus_was_cut_is_measured_after_the_repair() {
    let mut net = rig(Duration::ZERO);
    let (port, bus) = (net.dev(MASTER).port(1), net.buses[0]);
    net.sim
        .at(START, move |sim| sim.set_port_stamp_drift(port, -5_000));
    net.sim
        .at(Instant::from_millis(500), move |sim| sim.bus_down(bus));
    net.sim
        .at(Instant::from_millis(3_000), move |sim| sim.bus_up(bus));
    net.sim.at(Instant::from_millis(6_000), move |sim| {
        sim.set_port_stamp_drift(port, 0)
    });
    net.sim.run_until(END);
    let app = &net.station(MASTER).machine.b;
    let sent = net.station(SLAVE).machine.b.sent_counter;
    assert_eq!(sent, 500);
    let got = app.counters_from(SLAVE);
    let mut seen = vec![0u32; sent as usize];
    for c in &got {
        seen[*c as usize] += 1;
    }
    assert!(seen.iter().all(|n| *n >= 1), "every frame delivered");
    // Twice: at the repair, the copies from bus 1's return until it is ok again (50 ms:
    // no sample is taken from a port on probation) and its two measuring frames (3.06 to
    // 3.10 s); at the resynchronisation, its two measuring frames.
    let twice: Vec<_> = (0..sent as usize).filter(|c| seen[*c] > 1).collect();
    assert_eq!(twice, [146, 147, 148, 149, 150, 295, 296]);
    assert_eq!(got.len(), sent as usize + twice.len());
    // Measured on port 1 (its copies taken 14.5 ms and more earlier) soon after the repair,
    // followed, and cleared after the resynchronisation.
    let lags: Vec<_> = net
        .lag_events()
        .into_iter()
        .filter(|(_, e)| {
            matches!(
                e,
                LinkEventKind::Lag { .. } | LinkEventKind::LagCleared { .. }
            )
        })
        .collect();
    let (t, first) = lags[0];
    assert!(
        t > Instant::from_millis(3_000) && t < Instant::from_millis(3_200),
        "{t}"
    );
    assert!(
        matches!(first, LinkEventKind::Lag { port: 0, lag, .. } if lag >= ms(14) && lag <= ms(16)),
        "{first:?}"
    );
    assert!(
        matches!(lags.last(), Some((t, LinkEventKind::LagCleared { port: 0 })) if *t > Instant::from_millis(6_000)),
        "{lags:?}"
    );
}
