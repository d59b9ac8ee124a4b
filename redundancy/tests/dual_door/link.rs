//! The front door on a dual link: requests fan out, answers merge exactly, port health and
//! reach show through `ports()`, `heard_on()` and the events.

use duocan::net::{sim_description, sim_dictionary, NetEvent, NetOptions, Network, SIM_VENDOR};
use duocan::od::DynamicDictionary;
use duocan::port::mem::{Connector, MemBus};
use duocan::runtime::{Handle, Runtime};
use duocan::{Instant, NmtState, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::net::open_dual;
use duocan_redundancy::{DualBus, DualBusConfig, DualBusNode, PortState};
use std::time::Duration;

fn booted(id: u8) -> Node<DynamicDictionary> {
    let id = NodeId::must(id);
    let mut n = Node::new(NodeConfig::slave(id), sim_dictionary(id));
    n.boot(Instant::ZERO);
    n
}

/// Simulated node `id` on both buses, through its own dual-bus layer.
fn on_both(id: u8, buses: &[MemBus; 2]) -> Handle<DualBusNode<DynamicDictionary>> {
    Runtime::new(Station::new(
        DualBus::new(DualBusConfig::default()),
        booted(id),
    ))
    .port(buses[0].port())
    .port(buses[1].port())
    .spawn()
    .unwrap()
}

/// Two buses, the network on both (bus 1 through a connector that can be pulled), node 5 on
/// both.
struct Rig {
    buses: [MemBus; 2],
    cut: Connector,
    net: Network,
    node: Handle<DualBusNode<DynamicDictionary>>,
}

fn rig() -> Rig {
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let (port1, cut) = buses[0].plugged_port();
    let opts = NetOptions::default().with_sdo_timeout(Duration::from_millis(200));
    let net = open_dual(port1, buses[1].port(), opts).unwrap();
    let node = on_both(5, &buses);
    Rig {
        buses,
        cut,
        net,
        node,
    }
}

async fn sleep_ms(ms: u64) {
    tokio::time::sleep(Duration::from_millis(ms)).await;
}

async fn drain(events: &mut duocan::net::Events, for_ms: u64) -> Vec<NetEvent> {
    let mut out = vec![];
    let end = tokio::time::Instant::now() + Duration::from_millis(for_ms);
    while let Ok(Some(e)) = tokio::time::timeout_at(end, events.next()).await {
        out.push(e);
    }
    out
}

#[tokio::test(start_paused = true)]
async fn sdo_works_with_bus_1_down_and_the_port_shows_failed_after_its_timeout() {
    let r = rig();
    let sdo = r.net.node(5).sdo();
    assert_eq!(sdo.read::<u32>(0x1018, 1).await.unwrap(), SIM_VENDOR);
    sleep_ms(500).await;
    let before = r.net.ports().await.unwrap();
    assert_eq!(before.len(), 2);
    assert_eq!(
        [before[0].name.as_str(), before[1].name.as_str()],
        ["bus1", "bus2"]
    );
    for p in &before {
        assert_eq!(p.state, "ok", "{p:?}");
        assert!(p.counters.rx_frames > 0, "{p:?}: received");
        assert!(
            p.counters.tx_frames > 0,
            "{p:?}: the request went out on it"
        );
    }

    let mut events = r.net.events();
    r.cut.pull();
    sleep_ms(400).await;
    let ports = r.net.ports().await.unwrap();
    assert_eq!((ports[0].state, ports[1].state), ("failed", "ok"));
    assert_eq!(
        ports[0].last_error,
        Some(duocan::machine::ErrorCause::InterfaceDown)
    );
    // Only bus 2 carries the transfer now.
    let rx2 = ports[1].counters.rx_frames;
    let tx1 = ports[0].counters.tx_frames;
    assert_eq!(
        sdo.read::<u32>(0x1018, 2).await.unwrap(),
        5,
        "product = node-ID"
    );
    assert_eq!(
        sdo.read_string(0x1008, 0).await.unwrap(),
        "duocan simulated node"
    );
    let after = r.net.ports().await.unwrap();
    assert!(after[1].counters.rx_frames > rx2);
    assert_eq!(
        after[0].counters.tx_frames, tx1,
        "nothing sent on the failed port"
    );

    let seen = drain(&mut events, 10).await;
    let fail = seen
        .iter()
        .find(|e| matches!(e, NetEvent::PortState { port: 0, .. }))
        .expect("a port-state event");
    let NetEvent::PortState {
        from, to, reason, ..
    } = fail
    else {
        unreachable!()
    };
    assert_eq!((*from, *to), (PortState::Ok, PortState::Failed), "{fail}");
    assert!(reason.to_string().contains("interface down"), "{fail}");
    assert_eq!(fail.to_string(), format!("bus 1: failed ({reason})"));

    // Plugged back: re-initialised, recovering, then ok.
    r.cut.plug_in();
    let seen = drain(&mut events, 2000).await;
    let states: Vec<&str> = seen
        .iter()
        .filter_map(|e| match e {
            NetEvent::PortState { port: 0, to, .. } => Some(to.as_str()),
            _ => None,
        })
        .collect();
    // (A heartbeat twin that arrives on the re-subscribed port just after its silence deadline
    // may make it suspect for an instant afterwards: the simulated clock is that exact.)
    assert_eq!(states[..2], ["recovering", "ok"], "{seen:#?}");
    assert_eq!(states.last(), Some(&"ok"), "{seen:#?}");
    assert_eq!(r.net.ports().await.unwrap()[0].state, "ok");
    r.net.close().await;
    r.node.shutdown().await;
}

#[tokio::test(start_paused = true)]
async fn what_arrives_on_both_buses_is_delivered_once() {
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let net = open_dual(buses[0].port(), buses[1].port(), NetOptions::default()).unwrap();
    let mut events = net.events();
    let node = on_both(6, &buses);
    // One boot-up (at 0) and ten heartbeats (100 ms apart, the tenth at 1,000 ms) of node 6,
    // each sent on both buses: waited for until 50 ms after the tenth, not until its very
    // instant (where the paused clock's timers fire in any order).
    let seen = drain(&mut events, 1050).await;
    let node6: Vec<&NetEvent> = seen
        .iter()
        .filter(|e| e.node() == Some(NodeId::must(6)))
        .collect();
    let boot_ups = node6
        .iter()
        .filter(|e| matches!(e, NetEvent::BootUp { .. }))
        .count();
    let states: Vec<_> = node6
        .iter()
        .filter(|e| matches!(e, NetEvent::State { .. }))
        .collect();
    assert_eq!(boot_ups, 1, "{node6:#?}");
    assert_eq!(
        states.len(),
        1,
        "one state change, not one per bus: {node6:#?}"
    );
    assert_eq!(states[0].state(), Some(NmtState::PreOperational));
    // Both ports received every frame twice over: the merge, not a lost bus, made it one.
    let ports = net.ports().await.unwrap();
    assert!(ports[0].counters.rx_frames >= 11 && ports[1].counters.rx_frames >= 11);
    // An SDO answer comes on both buses too: the transfer ends once, with the value.
    let name = net.node(6).sdo().read_string(0x1008, 0).await.unwrap();
    assert_eq!(name, "duocan simulated node");
    net.close().await;
    node.shutdown().await;
}

#[tokio::test(start_paused = true)]
async fn a_tpdo_sent_on_both_buses_is_decoded_once() {
    // The door decoded each port's copy before the merge: every TPDO came twice on the
    // event stream, 0 ms apart.
    let r = rig();
    let node = r.net.add_node(5, sim_description().unwrap());
    let mut t1 = node.tpdo(1).read().await.unwrap();
    t1.event_timer_ms = Some(40);
    node.tpdo(1).save(&t1).await.unwrap();
    node.start().await.unwrap();
    node.wait_for_pdo(1, Duration::from_secs(2)).await.unwrap();
    let mut events = r.net.events();
    let seen = drain(&mut events, 1000).await;
    let at: Vec<_> = seen
        .iter()
        .filter(|e| e.pdo().is_some_and(|(n, k, _)| (n.raw(), k) == (5, 1)))
        .filter_map(NetEvent::at)
        .collect();
    assert!(at.len() >= 24, "a TPDO every 40 ms for a second: {at:?}");
    for w in at.windows(2) {
        let gap = w[1].saturating_since(w[0]);
        assert_eq!(gap, duocan::Duration::from_millis(40), "{at:?}");
    }
    assert_eq!(r.net.dropped_pdos().await.unwrap(), 0);
    r.net.close().await;
    r.node.shutdown().await;
}

#[tokio::test(start_paused = true)]
async fn heard_on_tells_the_buses_of_each_node_and_reach_changes_are_events() {
    let r = rig();
    let mut events = r.net.events();
    // Node 9 is on bus 2 only.
    let lone = Runtime::new(Station::single(booted(9)))
        .port(r.buses[1].port())
        .spawn()
        .unwrap();
    sleep_ms(500).await;
    assert_eq!(r.net.heard_on(5).await.unwrap(), Some([true, true].into()));
    assert_eq!(r.net.heard_on(9).await.unwrap(), Some([false, true].into()));
    assert_eq!(
        r.net.heard_on(33).await.unwrap(),
        Some([false, false].into())
    );
    assert!(matches!(
        r.net.heard_on(0).await,
        Err(duocan::net::NetError::NoSuchNode(0))
    ));
    let seen = drain(&mut events, 1).await;
    let reach = |n: u8| {
        seen.iter()
            .filter_map(|e| match e {
                NetEvent::Reach { node, heard, .. } if node.raw() == n => Some(*heard),
                _ => None,
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(reach(5), [[true, true]]);
    assert_eq!(reach(9), [[false, true]]);
    let line = seen
        .iter()
        .find(|e| matches!(e, NetEvent::Reach { node, .. } if node.raw() == 9))
        .unwrap()
        .to_string();
    assert_eq!(line, "node 0x09: heard on bus 2 only");

    // Node 5 stops: heard on no bus after the reach timeout.
    r.node.shutdown().await;
    let seen = drain(&mut events, 1000).await;
    assert!(
        seen.iter().any(
            |e| matches!(e, NetEvent::Reach { node, heard, .. } if *heard == [false, false] && node.raw() == 5)
        ),
        "{seen:#?}"
    );
    assert_eq!(
        r.net.heard_on(5).await.unwrap(),
        Some([false, false].into())
    );

    // On one port the question has no answer, and the state comes from the driver.
    let single = Network::open(r.buses[1].port()).unwrap();
    sleep_ms(300).await;
    assert_eq!(single.heard_on(9).await.unwrap(), None);
    let ports = single.ports().await.unwrap();
    assert_eq!(ports.len(), 1);
    assert_eq!((ports[0].name.as_str(), ports[0].state), ("bus2", "ok"));
    assert!(ports[0].counters.rx_frames > 0);
    single.close().await;
    r.net.close().await;
    lone.shutdown().await;
}

/// Copies of `n` distinct frames that reach port 1 only after all `n` reached port 0 (one bus's
/// receiver far behind the other's, as under a loaded machine): how many the link delivers.
fn delivered_with_one_bus_behind<const SLOTS: usize>(
    link: &mut duocan_redundancy::net::DualLink<SLOTS>,
    n: u32,
) -> u32 {
    use duocan::machine::BusLink;
    let frame = |i: u32| duocan::Frame::new(duocan::Id::Standard(0x585), &i.to_le_bytes()).unwrap();
    let mut delivered = 0;
    for port in 0..2 {
        for i in 0..n {
            let at = Instant::from_micros(u64::from(i) * 50 + u64::from(port as u32) * 100_000);
            delivered += u32::from(link.handle_rx(at, port, &frame(i)).is_some());
        }
    }
    delivered
}

/// A link built with more merger slots ([`DualLink::with_slots`]) has room for a long
/// transfer's frames waiting for their twins on a bus far behind: 2,000 frames 100 ms apart on
/// the two buses are each delivered once, where the default merger (room for 768) passes
/// evicted ones' twins on a second time.
#[test]
fn a_link_with_more_slots_has_room_for_a_bus_far_behind() {
    use duocan_redundancy::net::DualLink;
    let cfg = DualBusConfig::default()
        .with_skew_window(duocan::Duration::from_millis(250))
        .with_max_skew_window(duocan::Duration::from_millis(1000));
    let mut wide = DualLink::<4096>::with_slots(cfg);
    assert_eq!(delivered_with_one_bus_behind(&mut wide, 2000), 2000);
    let mut default = DualLink::new(cfg);
    assert!(delivered_with_one_bus_behind(&mut default, 2000) > 2000);
}
