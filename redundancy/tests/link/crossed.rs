//! Crossed cabling: a node whose connector for bus 1 is wired to bus 2 and the other way round
//! (an installation error, as likely as any in a cabinet of forty boards), in each mode.
//!
//! A port number is always the node's own connector: the crossed node reports its port 1
//! failed when bus 1 is cut. What must not depend on the wiring is the traffic: in
//! active-active mode the merge is symmetric, in CiA 302-6 mode every node accepts frames from
//! both channels, and in ECSS mode a slave that does not hear the redundancy master on the
//! bus it listens to toggles to the other, as after a bus failure.

use crate::sim::*;
use duocan::{Duration, Id, Instant, NodeId};
use duocan_redundancy::{
    Cia3026Config, DualBusConfig, EcssConfig, LinkEventKind, LinkMode, PortState,
};

const SLAVES: u8 = 6;
/// The crossed slave.
const CROSSED: u8 = 4;
const STOP: Instant = Instant::from_millis(3_000);
const END: Instant = Instant::from_millis(3_100);

fn run_to_end(net: &mut Net) {
    stop_sync(net, STOP);
    net.sim.run_until(END);
}

/// When `port` of `node` first left `Ok`.
fn first_failure(net: &Net, node: u8, port: u8) -> Option<Instant> {
    net.port_events(node, port)
        .into_iter()
        .find(|e| e.1 == PortState::Ok)
        .map(|e| e.0)
}

#[test]
fn active_active_with_a_crossed_slave_and_a_crossed_master_survives_buses_in_sequence() {
    let mut net = network_wired(31, SLAVES, |_| active_active(), &[MASTER, CROSSED], STOP);
    // Bus 1 cut, repaired, and bus 2 cut the same instant (a maintainer's hand-over).
    let [b1, b2] = net.buses;
    let (cut, swap, repair) = (
        Instant::from_millis(800),
        Instant::from_millis(1_500),
        Instant::from_millis(2_200),
    );
    net.sim.at(cut, move |sim| sim.bus_down(b1));
    net.sim.at(swap, move |sim| {
        sim.bus_up(b1);
        sim.bus_down(b2);
    });
    net.sim.at(repair, move |sim| sim.bus_up(b2));
    run_to_end(&mut net);

    net.assert_application_exact();
    net.assert_no_heartbeat_lost();
    assert!(net.assert_sync_exact() > 290);
    // Each node names its own connector: bus 1's cut fails port 0 of the straight nodes and
    // port 1 of the crossed ones; nobody's other port failed before the swap.
    for node in 1..=SLAVES + 1 {
        let (on_bus_1, on_bus_2) = if [MASTER, CROSSED].contains(&node) {
            (1, 0)
        } else {
            (0, 1)
        };
        let failed = first_failure(&net, node, on_bus_1).expect("bus 1's port failed");
        assert!(failed > cut && failed < swap, "node {node}: {failed}");
        let other = first_failure(&net, node, on_bus_2).expect("bus 2's port failed");
        assert!(other > swap && other < repair, "node {node}: {other}");
    }
}

#[test]
fn cia302_6_with_a_crossed_slave_loses_and_doubles_nothing() {
    let cfg = DualBusConfig::with_guard_period(
        LinkMode::Cia302_6(Cia3026Config::default().with_error_threshold(16)),
        Duration::from_millis(HB_MS as u64),
    );
    let mut net = network_wired(32, SLAVES, |_| cfg, &[CROSSED], STOP);
    run_to_end(&mut net);

    net.assert_application_exact();
    net.assert_no_heartbeat_lost();
    // Its default channel is its port 0, on bus 2: its application frames go there, the
    // others' on bus 1, and everybody takes frames from both channels.
    let tpdo = |node: u8| move |f: &duocan::Frame| f.id() == Id::Standard(0x180 + node as u16);
    let on = |bus: usize, node: u8| {
        net.wire(bus)
            .into_iter()
            .filter(|x| x.1 == node && tpdo(node)(&x.2))
            .count()
    };
    assert!(on(1, CROSSED) > 280 && on(0, CROSSED) == 0);
    assert!(on(0, 2) > 280 && on(1, 2) == 0);
}

#[test]
fn ecss_with_a_crossed_slave_toggles_to_the_masters_bus_and_then_loses_nothing() {
    // Ttoggle 2, Ntoggle 4: the slave waits one consumer time, then toggles.
    const P: Duration = Duration::from_millis(150);
    let cfg = |node: u8| {
        let ecss = if node == MASTER {
            EcssConfig::master()
        } else {
            EcssConfig::slave(NodeId::must(MASTER), P)
                .with_ttoggle(2)
                .with_ntoggle(4)
        };
        DualBusConfig::with_guard_period(
            LinkMode::EcssToggle(ecss),
            Duration::from_millis(HB_MS as u64),
        )
    };
    let mut net = network_wired(33, SLAVES, cfg, &[CROSSED], STOP);
    run_to_end(&mut net);

    let found: Vec<_> = net
        .link_events(CROSSED)
        .into_iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::MasterFound { bus, .. } => Some((e.at, bus)),
            _ => None,
        })
        .collect();
    // It listened on its port 0 (bus 2), where the master is silent; it toggled to its port 1
    // (bus 1), found the master there, and stayed.
    assert_eq!(found.len(), 1, "{found:?}");
    assert_eq!(found[0].1, 1);
    assert!(found[0].0 < Instant::from_millis(1_000), "{found:?}");
    // From then on, everybody's frames reach it, exactly once and in order.
    for s in (1..=SLAVES + 1).filter(|s| *s != CROSSED) {
        let got: Vec<u32> = net.station(CROSSED).machine.b.counters_from(s);
        let sent = net.station(s).machine.b.sent_counter;
        assert!(got.windows(2).all(|w| w[1] == w[0] + 1), "from node {s}");
        assert_eq!(got.last().copied(), Some(sent - 1), "from node {s}");
        assert!(got.len() >= 265, "from node {s}: {}", got.len());
    }
}
