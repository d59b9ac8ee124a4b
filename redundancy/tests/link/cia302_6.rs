//! CiA 302-6 active-standby mode on the simulated dual bus, rule by rule, with the frames on
//! the wire: heartbeats on both channels, application traffic on the active one, the power-on
//! and reset-communication evaluations, the transmit-error counter, the 0x7F indication.

use crate::sim::*;
use duocan::node::NodeEventKind;
use duocan::od::ObjectDictionary;
use duocan::sim::TxOutcome;
use duocan::{Duration, Frame, Instant, NmtCommand, NmtTarget, NodeId};
use duocan_redundancy::link::channel::cia302_6::indicate_active;
use duocan_redundancy::{Cia3026Config, DualBusConfig, LinkEventKind, LinkMode, SwitchReason};
use std::cell::RefCell;
use std::rc::Rc;

const SLAVES: u8 = 8;
const POWER_ON_WINDOW: Duration = Duration::from_millis(300);
const RESET_WINDOW: Duration = Duration::from_millis(200);

fn cfg(threshold: u8) -> DualBusConfig {
    DualBusConfig::with_guard_period(
        LinkMode::Cia302_6(
            Cia3026Config::default()
                .with_eval_power_on(POWER_ON_WINDOW)
                .with_eval_reset(RESET_WINDOW)
                .with_error_threshold(threshold),
        ),
        Duration::from_millis(HB_MS as u64),
    )
}

/// (time, from, to, reason) of every channel switch at `node`.
fn switches(net: &Net, node: u8) -> Vec<(Instant, u8, u8, SwitchReason)> {
    net.link_events(node)
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::Channel { from, to, reason } => Some((e.at, from, to, reason)),
            _ => None,
        })
        .collect()
}

fn is_app(f: &Frame) -> bool {
    let raw = f.id().raw();
    (0x181..=0x2FF).contains(&raw) || raw == 0x80
}
fn is_heartbeat(f: &Frame) -> bool {
    (0x701..=0x77F).contains(&f.id().raw())
}

/// Indications (0x7F) on `bus`: (end, sender).
fn indications(net: &Net, bus: usize) -> Vec<(Instant, u8)> {
    net.wire(bus)
        .into_iter()
        .filter(|(_, _, f, _)| *f == indicate_active())
        .map(|(t, s, _, _)| (t, s))
        .collect()
}

/// Each sender's counters arrive at most once and increasing (302-6 loses the frames that
/// failed on the old channel during a switch; it must never double one).
fn assert_no_duplicates(net: &Net) {
    for r in 1..=SLAVES + 1 {
        for s in (1..=SLAVES + 1).filter(|s| *s != r) {
            let got = net.station(r).machine.b.counters_from(s);
            assert!(
                got.windows(2).all(|w| w[0] < w[1]),
                "node {r} from node {s}: {got:?}"
            );
        }
    }
}

#[test]
fn heartbeats_on_both_channels_application_on_the_default_only() {
    let stop = Instant::from_millis(1_000);
    let mut net = network(11, SLAVES, cfg(16), stop);
    stop_sync(&mut net, stop);
    net.sim.run_until(stop + Duration::from_millis(100));
    net.assert_application_exact();
    net.assert_no_heartbeat_lost();
    let (default, redundant) = (net.wire(0), net.wire(1));
    assert!(default.iter().filter(|x| is_app(&x.2)).count() > 1_500);
    assert_eq!(
        redundant.iter().filter(|x| is_app(&x.2)).count(),
        0,
        "no application traffic on the redundant channel"
    );
    for node in 1..=SLAVES + 1 {
        let hb = |w: &[(Instant, u8, Frame, TxOutcome)]| {
            w.iter()
                .filter(|x| x.1 == node && is_heartbeat(&x.2))
                .count()
        };
        // Boot-up and a heartbeat every 50 ms, on each channel.
        assert!(hb(&default) >= 21, "node {node} on default");
        assert_eq!(
            hb(&default),
            hb(&redundant),
            "node {node}: the same on both"
        );
        // The power-on evaluation found three heartbeats of everybody: no switch.
        assert!(switches(&net, node).is_empty());
    }
    assert!(indications(&net, 0).is_empty() && indications(&net, 1).is_empty());
}

#[test]
fn power_on_evaluation_switches_to_redundant_when_default_gave_fewer_than_three() {
    let stop = Instant::from_millis(1_000);
    // Counter disabled, so that only the evaluation decides.
    let mut net = network(12, SLAVES, cfg(0), stop);
    let default = net.buses[0];
    net.sim.at(Instant::ZERO, move |sim| sim.bus_down(default));
    net.sim.run_until(stop + Duration::from_millis(100));
    for node in 1..=SLAVES + 1 {
        // Everybody booted at 0: the window closes at 300 ms exactly. The producers are the
        // nodes heard (on the redundant channel); the weakest is reported: the lowest other ID.
        let weakest = NodeId::must(if node == 1 { 2 } else { 1 });
        assert_eq!(
            switches(&net, node),
            [(
                Instant::ZERO + POWER_ON_WINDOW,
                0,
                1,
                SwitchReason::PowerOnEvaluation {
                    node: weakest,
                    count: 0
                }
            )],
            "node {node}"
        );
    }
    // Every node indicated the redundant channel, on it.
    let ind = indications(&net, 1);
    assert_eq!(ind.len(), SLAVES as usize + 1);
    assert!(ind
        .iter()
        .all(|(t, _)| *t > Instant::ZERO + POWER_ON_WINDOW && *t < Instant::from_millis(305)));
    // From then on the application runs on the redundant channel, nothing doubled, and every
    // frame sent after the switch arrives.
    let app_after = net
        .wire(1)
        .iter()
        .filter(|x| is_app(&x.2) && x.0 > Instant::from_millis(305))
        .count();
    assert!(app_after > 1_000);
    assert_no_duplicates(&net);
    for r in 1..=SLAVES + 1 {
        for s in (1..=SLAVES + 1).filter(|s| *s != r) {
            let got = net.station(r).machine.b.counters_from(s);
            let sent = net.station(s).machine.b.sent_counter;
            assert_eq!(*got.last().unwrap(), sent - 1);
            assert_eq!(
                got.len() as u32,
                sent - got[0],
                "contiguous after the switch"
            );
        }
    }
}

/// (when, node, 0x1F60 sub 5 in its dictionary, its layer's error counter).
type Shown = (Instant, u8, u8, u8);

#[test]
fn transmit_errors_switch_to_redundant_and_heartbeats_bring_the_network_back() {
    let cut = Instant::from_millis(1_005);
    let repair = Instant::from_millis(2_000);
    let stop = Instant::from_millis(3_000);
    let mut net = network(13, SLAVES, cfg(16), stop);
    let default = net.buses[0];
    net.sim.at(cut, move |sim| sim.bus_down(default));
    net.sim.at(repair, move |sim| sim.bus_up(default));
    // Every 5 ms, each node's dictionary (0x1F60 sub 5) against its layer's error counter.
    let shown: Rc<RefCell<Vec<Shown>>> = Rc::default();
    for k in 0..600u64 {
        let t = Instant::from_millis(5 * k);
        let out = shown.clone();
        let devs: Vec<_> = (1..=SLAVES + 1).map(|n| net.dev(n)).collect();
        net.sim.at(t, move |sim| {
            for (i, d) in devs.iter().enumerate() {
                let st = sim.device(*d);
                let od = st.machine.a.od().get_u32(0x1F60, 5).unwrap() as u8;
                let layer = st.link.cia302_6().unwrap().error_counter();
                out.borrow_mut().push((t, i as u8 + 1, od, layer));
            }
        });
    }
    net.sim.run_until(stop + Duration::from_millis(100));
    let shown = shown.borrow();
    assert!(
        shown.iter().all(|(_, _, od, layer)| od == layer),
        "0x1F60 sub 5 shows the counter"
    );
    assert!(
        shown.iter().any(|x| x.2 == 16),
        "and the counter reached the threshold"
    );

    let wire = net.wire(0);
    for node in 1..=SLAVES + 1 {
        let sw = switches(&net, node);
        assert_eq!(sw.len(), 2, "node {node}: {sw:?}");
        // Away: by its own counter (+4 per failed frame, threshold 16: the fourth failure after
        // the cut), or by a peer's indication if that came first.
        let failures: Vec<Instant> = wire
            .iter()
            .filter(|x| x.1 == node && x.0 > cut && x.3 == TxOutcome::BusDown)
            .map(|x| x.0)
            .collect();
        match sw[0] {
            (t, 0, 1, SwitchReason::TxErrors { counter: 16 }) => {
                assert_eq!(t, failures[3], "node {node}: at the fourth failure");
                let disabled = net
                    .link_events(node)
                    .into_iter()
                    .find(|e| matches!(e.kind, LinkEventKind::DefaultDisabled { counter: 16 }));
                assert_eq!(disabled.map(|e| e.at), Some(t));
            }
            (t, 0, 1, SwitchReason::Indicated) => {
                assert!(failures.len() < 4 || t <= failures[3], "node {node}");
                assert!(indications(&net, 1).iter().any(|(i, _)| *i == t));
            }
            s => panic!("node {node}: {s:?}"),
        }
        // Back: by three heartbeats of every producer on the default channel, or by a peer's
        // indication there.
        match sw[1] {
            (t, 1, 0, SwitchReason::HeartbeatsBack | SwitchReason::Indicated) => {
                assert!(
                    t > repair + Duration::from_millis(100)
                        && t < repair + Duration::from_millis(400)
                )
            }
            s => panic!("node {node}: {s:?}"),
        }
        assert_eq!(net.station(node).link.active_channel(), Some(0));
        assert_eq!(
            net.station(node).link.cia302_6().unwrap().error_counter(),
            0
        );
    }
    // Indications: on the redundant channel right after the cut, on the default one after the
    // repair.
    let away = indications(&net, 1);
    assert!(
        !away.is_empty()
            && away
                .iter()
                .all(|(t, _)| *t > cut && *t < cut + Duration::from_millis(50))
    );
    let back: Vec<_> = indications(&net, 0)
        .into_iter()
        .filter(|(t, _)| *t > repair)
        .collect();
    assert!(!back.is_empty());
    // The application moved with the channel: nothing on the redundant bus before the cut or
    // after the way back, nothing ever doubled.
    for x in net.wire(1).iter().filter(|x| is_app(&x.2)) {
        assert!(
            x.0 > cut && x.0 < repair + Duration::from_millis(400),
            "{x:?}"
        );
    }
    assert_no_duplicates(&net);
}

#[test]
fn reset_communication_returns_to_default_and_switches_if_a_producer_gave_nothing() {
    const NODE: u8 = 5;
    let stop = Instant::from_millis(2_500);
    let mut net = network(14, SLAVES, cfg(0), stop);
    let default = net.buses[0];
    let m = net.dev(MASTER);
    // Everybody onto the redundant channel by the master's command; then default dies and the
    // master resets node 5's communication.
    net.sim.at(Instant::from_millis(1_000), move |sim| {
        assert!(sim
            .device_mut(m)
            .link
            .select_channel(Instant::from_millis(1_000), 1));
    });
    // Before anybody has counted three heartbeats there to switch back.
    net.sim.at(Instant::from_millis(1_060), move |sim| {
        sim.bus_down(default)
    });
    net.sim.at(Instant::from_millis(1_500), move |sim| {
        sim.device_mut(m)
            .machine
            .a
            .nmt_command(
                Instant::from_millis(1_500),
                NmtCommand::ResetCommunication,
                NmtTarget::Node(NodeId::must(NODE)),
            )
            .unwrap();
    });
    net.sim.run_until(stop);

    let reset_at = net
        .node_events(NODE)
        .iter()
        .find(|e| {
            matches!(
                e.kind,
                NodeEventKind::NmtObserved {
                    cmd: NmtCommand::ResetCommunication,
                    target: NODE
                }
            )
        })
        .map(|e| e.at)
        .expect("node 5 reset its communication");
    let sw = switches(&net, NODE);
    let t = Instant::from_millis(1_000);
    assert_eq!((sw[0].1, sw[0].2, sw[0].3), (0, 1, SwitchReason::Indicated));
    assert!(sw[0].0 > t && sw[0].0 < t + Duration::from_millis(1));
    // Back to default with the reset (indicated there, where nobody hears it), then, after the
    // 200 ms window without a single heartbeat on default, to redundant again.
    assert_eq!(
        sw[1..],
        [
            (reset_at, 1, 0, SwitchReason::ResetCommunication),
            (
                reset_at + RESET_WINDOW,
                0,
                1,
                SwitchReason::ResetEvaluation {
                    node: NodeId::must(1)
                }
            ),
        ]
    );
    let on_default: Vec<_> = net
        .wire(0)
        .into_iter()
        .filter(|x| x.1 == NODE && x.2 == indicate_active())
        .collect();
    assert_eq!(on_default.len(), 1);
    assert!(on_default[0].0 >= reset_at && on_default[0].3 == TxOutcome::BusDown);
    let on_redundant: Vec<_> = indications(&net, 1)
        .into_iter()
        .filter(|(_, s)| *s == NODE)
        .collect();
    assert_eq!(on_redundant.len(), 1);
    assert!(on_redundant[0].0 > reset_at + RESET_WINDOW);
    assert_eq!(net.station(NODE).link.active_channel(), Some(1));
    // The others stayed where they were.
    for node in (1..=SLAVES + 1).filter(|n| *n != NODE) {
        assert_eq!(
            net.station(node).link.active_channel(),
            Some(1),
            "node {node}"
        );
    }
    assert_no_duplicates(&net);
}

#[test]
fn an_indication_moves_every_node_and_heartbeats_on_default_bring_them_back() {
    let stop = Instant::from_millis(2_000);
    let mut net = network(15, SLAVES, cfg(16), stop);
    stop_sync(&mut net, stop);
    let node3 = net.dev(3);
    let t = Instant::from_millis(1_000);
    net.sim.at(t, move |sim| {
        assert!(sim.device_mut(node3).link.select_channel(t, 1));
    });
    net.sim.run_until(stop + Duration::from_millis(100));

    // Node 3's 0x7F on the redundant channel moves everybody at the instant it ends.
    let ind = indications(&net, 1);
    assert_eq!(ind.len(), 1);
    let (t7f, sender) = ind[0];
    assert_eq!(sender, 3);
    assert_eq!(switches(&net, 3)[0], (t, 0, 1, SwitchReason::Command));
    for node in (1..=SLAVES + 1).filter(|n| *n != 3) {
        assert_eq!(
            switches(&net, node)[0],
            (t7f, 0, 1, SwitchReason::Indicated),
            "node {node}"
        );
    }
    // The default channel is healthy: as soon as a node has counted three heartbeats of every
    // producer there, it switches back and indicates it; the others follow that indication or
    // count their own three at the same instant.
    let back = indications(&net, 0);
    assert!(!back.is_empty());
    let (first_back, _) = back[0];
    for node in 1..=SLAVES + 1 {
        let sw = switches(&net, node);
        assert_eq!(sw.len(), 2, "node {node}: {sw:?}");
        let (tb, from, to, reason) = sw[1];
        assert_eq!((from, to), (1, 0), "node {node}");
        match reason {
            SwitchReason::HeartbeatsBack => {
                assert!(tb > t7f + Duration::from_millis(100) && tb < first_back)
            }
            SwitchReason::Indicated => assert!(back.iter().any(|(i, _)| *i == tb)),
            r => panic!("node {node}: {r:?}"),
        }
        assert_eq!(net.station(node).link.active_channel(), Some(0));
    }
    // Both channels worked throughout and the receivers merge both: nothing lost or doubled.
    net.assert_application_exact();
    net.assert_no_heartbeat_lost();
}
