//! The front door of the redundant master (`RedundantNetwork`, a `duocan::net::Network` over the
//! supervised station) on two in-memory buses with a simulated node on both: process data,
//! once after the merge and sent on both buses, and a standby master that sends none.

use duocan::net::{sim_description, NetError, NetEvent, SIM_VENDOR};
use duocan::od::DynamicDictionary;
use duocan::port::mem::{Connector, MemBus, MemPort};
use duocan::port::{Port, PortInput};
use duocan::runtime::{Handle, Runtime};
use duocan::{CobId, Id, Instant, NmtState, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::net::RedundantNetwork;
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::{DualBus, DualBusConfig, DualBusNode};
use std::time::Duration;

const T: Duration = Duration::from_secs(2);

fn ms(n: u64) -> duocan::Duration {
    duocan::Duration::from_millis(n)
}

async fn sleep_ms(n: u64) {
    tokio::time::sleep(Duration::from_millis(n)).await;
}

/// Simulated node `id` (duocan's simulated dictionary: inputs 0x6000 on TPDO 1, outputs
/// 0x6200 on RPDO 1) on both buses, through its own dual-bus layer.
fn on_both(id: u8, buses: &[MemBus; 2]) -> Handle<DualBusNode<DynamicDictionary>> {
    let id = NodeId::must(id);
    let mut n = Node::new(NodeConfig::slave(id), duocan::net::sim_dictionary(id));
    n.boot(Instant::ZERO);
    Runtime::new(Station::new(DualBus::new(DualBusConfig::default()), n))
        .port(buses[0].port())
        .port(buses[1].port())
        .spawn()
        .unwrap()
}

/// Two buses; master 7 on both (bus 1 through a connector that can be pulled), alone and so
/// active after the power-on negotiation; node 5 on both.
struct Rig {
    buses: [MemBus; 2],
    cut: Connector,
    net: RedundantNetwork,
    node: Handle<DualBusNode<DynamicDictionary>>,
}

async fn rig() -> Rig {
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let (port1, cut) = buses[0].plugged_port();
    let net = RedundantNetwork::builder()
        .node_id(7)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .open(port1, buses[1].port())
        .unwrap();
    let node = on_both(5, &buses);
    sleep_ms(2000).await;
    assert_eq!(net.role().await.unwrap(), MasterRole::Active);
    Rig {
        buses,
        cut,
        net,
        node,
    }
}

async fn drain(events: &mut duocan::net::Events, for_ms: u64) -> Vec<NetEvent> {
    let mut out = vec![];
    let end = tokio::time::Instant::now() + Duration::from_millis(for_ms);
    while let Ok(Some(e)) = tokio::time::timeout_at(end, events.next()).await {
        out.push(e);
    }
    out
}

/// When node 5's TPDO 1 arrived on the event stream, over `for_ms`.
async fn tpdo1_times(net: &RedundantNetwork, for_ms: u64) -> Vec<Instant> {
    let mut events = net.events();
    drain(&mut events, for_ms)
        .await
        .iter()
        .filter(|e| e.pdo().is_some_and(|(n, k, _)| (n.raw(), k) == (5, 1)))
        .filter_map(NetEvent::at)
        .collect()
}

/// A TPDO every 40 ms for a second: one event each, 40 ms apart (a copy per bus would come
/// 0 ms after its twin).
fn assert_once_every_40_ms(at: &[Instant]) {
    assert!(at.len() >= 24, "a TPDO every 40 ms for a second: {at:?}");
    for w in at.windows(2) {
        assert_eq!(w[1].saturating_since(w[0]), ms(40), "{at:?}");
    }
}

/// Frames on `id` a spy on the bus saw within 100 ms.
pub(crate) async fn seen_on(spy: &mut MemPort, id: u16) -> Vec<Vec<u8>> {
    let mut out = vec![];
    let end = tokio::time::Instant::now() + Duration::from_millis(100);
    while let Ok(input) = tokio::time::timeout_at(end, spy.recv()).await {
        match input {
            Ok(PortInput::Frame(f, _)) if f.id() == Id::Standard(id) => out.push(f.data().to_vec()),
            Ok(_) => {}
            Err(e) => panic!("the spy's port: {e}"),
        }
    }
    out
}

#[tokio::test(start_paused = true)]
async fn a_tpdo_arrives_once_with_both_buses_and_with_bus_1_cut() {
    let r = rig().await;
    let node = r.net.add_node(5, sim_description().unwrap());
    assert_eq!(node.sdo().read::<u32>(0x1018, 1).await.unwrap(), SIM_VENDOR);
    let mut t1 = node.tpdo(1).read().await.unwrap();
    t1.event_timer_ms = Some(40);
    node.tpdo(1).save(&t1).await.unwrap();
    node.start().await.unwrap();
    node.wait_for_pdo(1, T).await.unwrap();
    assert_once_every_40_ms(&tpdo1_times(&r.net, 1000).await);

    r.cut.pull();
    sleep_ms(400).await;
    let ports = r.net.ports().await.unwrap();
    assert_eq!((ports[0].state, ports[1].state), ("failed", "ok"));
    assert_once_every_40_ms(&tpdo1_times(&r.net, 1000).await);
    assert_eq!(r.net.dropped_pdos().await.unwrap(), 0);
    r.net.close().await;
    r.node.shutdown().await;
}

#[tokio::test(start_paused = true)]
async fn an_rpdo_goes_out_on_both_buses_and_changes_the_nodes_dictionary() {
    let r = rig().await;
    let node = r.net.add_node(5, sim_description().unwrap());
    let r1 = node.rpdo(1);
    r1.read().await.unwrap();
    node.start().await.unwrap();
    node.wait_for_state(NmtState::Operational, T).await.unwrap();
    let mut spies = [r.buses[0].port(), r.buses[1].port()];
    r1.send(&[1234u16.into(), (-3i8).into()]).await.unwrap();
    // One frame of the door's, fanned out: one copy on each bus, and the node applied it once.
    for spy in &mut spies {
        assert_eq!(seen_on(spy, 0x205).await, [vec![0xD2, 0x04, 0xFD]]);
    }
    assert_eq!(node.sdo().read::<u16>(0x6200, 1).await.unwrap(), 1234);
    assert_eq!(node.sdo().read::<i8>(0x6200, 2).await.unwrap(), -3);

    // With bus 1 cut, bus 2 carries it.
    r.cut.pull();
    sleep_ms(400).await;
    r1.send(&[4321u16.into(), 5i8.into()]).await.unwrap();
    sleep_ms(10).await;
    assert_eq!(node.sdo().read::<u16>(0x6200, 1).await.unwrap(), 4321);
    assert_eq!(node.sdo().read::<i8>(0x6200, 2).await.unwrap(), 5);
    r.net.close().await;
    r.node.shutdown().await;
}

/// Masters 1 and 2 on both buses, each the other's peer, 2.5 s after they opened: the active
/// one and the standby.
pub(crate) async fn two_masters(buses: &[MemBus; 2]) -> (RedundantNetwork, RedundantNetwork) {
    let open = |id: u8, peer: u8| {
        RedundantNetwork::builder()
            .node_id(id)
            .heartbeat(ms(20))
            .master_timeout(ms(50))
            .peer_master(peer)
            .open(buses[0].port(), buses[1].port())
            .unwrap()
    };
    let (one, two) = (open(1, 2), open(2, 1));
    sleep_ms(2500).await;
    match (one.role().await.unwrap(), two.role().await.unwrap()) {
        (MasterRole::Active, MasterRole::Standby(_)) => (one, two),
        (MasterRole::Standby(_), MasterRole::Active) => (two, one),
        r => panic!("one active master and one standby: {r:?}"),
    }
}

#[tokio::test(start_paused = true)]
async fn a_standby_master_sends_no_rpdo_and_says_why() {
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let (active, standby) = two_masters(&buses).await;
    // RPDO 1 of node 5, learned (no SDO: the standby master has no client to use).
    let r1 = standby.node(5).rpdo(1);
    let mut m = r1.blank().unwrap();
    m.cob_id = CobId(0x205);
    m.enabled = true;
    m.add(0x6200, 1, 16).unwrap();
    r1.learn(&m).await.unwrap();
    let mut spy = buses[1].port();
    let e = r1.send(&[1u16.into()]).await.unwrap_err();
    assert_eq!(
        e,
        NetError::Standby {
            node: NodeId::new(5)
        }
    );
    assert!(
        e.to_string().contains("RPDOs go through the active master"),
        "{e}"
    );
    assert!(seen_on(&mut spy, 0x205).await.is_empty(), "nothing sent");
    // The active master's door sends it.
    let a1 = active.node(5).rpdo(1);
    a1.learn(&m).await.unwrap();
    a1.send(&[2u16.into()]).await.unwrap();
    assert_eq!(seen_on(&mut spy, 0x205).await, [vec![2, 0]]);
    // Once the active master is gone, the other one takes over and its door sends.
    active.close().await;
    sleep_ms(500).await;
    assert_eq!(standby.role().await.unwrap(), MasterRole::Active);
    r1.send(&[3u16.into()]).await.unwrap();
    assert_eq!(seen_on(&mut spy, 0x205).await, [vec![3, 0]]);
    standby.close().await;
}

#[tokio::test(start_paused = true)]
async fn states_boot_ups_and_a_watched_heartbeat_through_the_redundant_door() {
    let r = rig().await;
    let node = r.net.node(5);
    // Node 5 booted before this object was made: a wait for its boot-up waits for the next.
    let e = node.wait_for_boot_up(Duration::from_millis(100)).await;
    assert!(matches!(e, Err(NetError::Timeout { .. })), "{e:?}");
    let booted = node.wait_for_boot_up_since(Instant::ZERO, T).await.unwrap();
    assert!(booted < r.net.now(), "{booted}");
    node.reset_communication().await.unwrap();
    let again = node.wait_for_boot_up(T).await.unwrap();
    assert!(again > booted, "{again} after {booted}");
    node.wait_for_state(NmtState::PreOperational, T)
        .await
        .unwrap();
    node.start().await.unwrap();
    node.wait_for_state(NmtState::Operational, T).await.unwrap();
    assert_eq!(node.state().await.unwrap(), Some(NmtState::Operational));

    // Watched: an entry of the door's in the master's 0x1016, and a loss is the door's event.
    let mut events = r.net.events();
    node.watch_heartbeat(Duration::from_millis(300))
        .await
        .unwrap();
    let entries = r
        .net
        .with(|n, _| {
            use duocan::od::ObjectDictionary;
            (1..=127u8)
                .filter_map(|s| n.od().get_u32(0x1016, s))
                .filter(|v| v >> 16 == 5)
                .collect::<Vec<_>>()
        })
        .await
        .unwrap();
    assert_eq!(entries, [0x0005_012C]);
    // A node never heard is reported after the watch's timeout.
    r.net
        .node(0x33)
        .watch_heartbeat(Duration::from_millis(300))
        .await
        .unwrap();
    sleep_ms(500).await;
    r.node.shutdown().await;
    let seen = drain(&mut events, 1000).await;
    let lost: Vec<&NetEvent> = seen
        .iter()
        .filter(|e| matches!(e, NetEvent::HeartbeatLost { .. }))
        .collect();
    assert_eq!(lost.len(), 1, "{seen:#?}");
    let NetEvent::HeartbeatLost { node: n, last, at } = *lost[0] else {
        unreachable!()
    };
    assert_eq!((n.raw(), at - last), (5, ms(300)), "{seen:#?}");
    let not_heard = seen
        .iter()
        .find(|e| matches!(e, NetEvent::NotHeard { .. }))
        .unwrap_or_else(|| panic!("{seen:#?}"));
    assert_eq!(not_heard.node(), NodeId::new(0x33));
    // Zero stops watching: the entry is cleared.
    node.watch_heartbeat(Duration::ZERO).await.unwrap();
    let left = r
        .net
        .with(|n, _| {
            use duocan::od::ObjectDictionary;
            (1..=127u8).any(|s| {
                n.od()
                    .get_u32(0x1016, s)
                    .is_some_and(|v| v >> 16 == 5 && v & 0xFFFF != 0)
            })
        })
        .await
        .unwrap();
    assert!(!left, "the door's entry is cleared");
    r.net.close().await;
}

/// When SYNC frames passed on the spy's bus within `for_ms` from now (what it holds from
/// before is dropped first).
async fn syncs(spy: &mut MemPort, for_ms: u64) -> Vec<tokio::time::Instant> {
    while let Ok(Ok(_)) = tokio::time::timeout(Duration::ZERO, spy.recv()).await {}
    let mut out = vec![];
    let end = tokio::time::Instant::now() + Duration::from_millis(for_ms);
    while let Ok(input) = tokio::time::timeout_at(end, spy.recv()).await {
        match input {
            Ok(PortInput::Frame(f, _)) if f.id() == Id::Standard(0x080) => {
                out.push(tokio::time::Instant::now());
            }
            Ok(_) => {}
            Err(e) => panic!("the spy's port: {e}"),
        }
    }
    out
}

fn gaps(at: &[tokio::time::Instant]) -> Vec<Duration> {
    at.windows(2).map(|w| w[1] - w[0]).collect()
}

#[tokio::test(start_paused = true)]
async fn start_and_stop_sync_change_the_period_on_the_wire_and_a_standby_produces_none() {
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let (active, standby) = two_masters(&buses).await;
    let mut spy = buses[1].port();
    assert!(syncs(&mut spy, 200).await.is_empty(), "no SYNC configured");
    // The standby master takes a period, and produces nothing.
    standby.start_sync(Duration::from_millis(20)).await.unwrap();
    assert!(syncs(&mut spy, 200).await.is_empty(), "a standby's SYNC");
    // The active one produces at the period it is given, and at the next one.
    active.start_sync(Duration::from_millis(10)).await.unwrap();
    let at = syncs(&mut spy, 200).await;
    assert!(at.len() >= 19, "{at:?}");
    assert!(
        gaps(&at).iter().all(|g| *g == Duration::from_millis(10)),
        "{:?}",
        gaps(&at)
    );
    active.start_sync(Duration::from_millis(50)).await.unwrap();
    sleep_ms(60).await;
    let at = syncs(&mut spy, 500).await;
    assert!(at.len() >= 9, "{at:?}");
    assert!(
        gaps(&at).iter().all(|g| *g == Duration::from_millis(50)),
        "{:?}",
        gaps(&at)
    );
    active.stop_sync().await.unwrap();
    sleep_ms(60).await;
    assert!(syncs(&mut spy, 300).await.is_empty(), "SYNC stopped");
    // Taking over, the standby produces at the period it was given.
    active.close().await;
    sleep_ms(500).await;
    assert_eq!(standby.role().await.unwrap(), MasterRole::Active);
    let at = syncs(&mut spy, 200).await;
    assert!(at.len() >= 9, "{at:?}");
    assert!(
        gaps(&at).iter().all(|g| *g == Duration::from_millis(20)),
        "{:?}",
        gaps(&at)
    );
    standby.close().await;
}

/// `running_board` names the pair member that runs: the first one this master finds (B, when
/// A is not there yet), the other after a switch-over; a node that is no pair's A member is
/// refused, and a pair with no board running is a time-out after exactly the time given.
#[tokio::test(start_paused = true)]
async fn running_board_follows_the_pair_member_that_runs() {
    use duocan_redundancy::{Member, PairId, RedundantError};
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let net = RedundantNetwork::builder()
        .node_id(7)
        .pair(0x10, 0x50)
        .pair(0x11, 0x51)
        .open(buses[0].port(), buses[1].port())
        .unwrap();
    let b = on_both(0x50, &buses);
    assert_eq!(net.running_board(0x10, T).await.unwrap(), 0x50);
    let a = on_both(0x10, &buses);
    sleep_ms(2000).await;
    assert_eq!(
        net.running_board(0x10, T).await.unwrap(),
        0x50,
        "non-revertive"
    );
    net.switch_over(PairId(0), Member::A).await.unwrap();
    sleep_ms(500).await;
    assert_eq!(net.running_board(0x10, T).await.unwrap(), 0x10);
    let e = net.running_board(0x50, T).await.unwrap_err();
    assert!(
        matches!(e, RedundantError::Net(NetError::NoSuchNode(0x50))),
        "{e:?}"
    );
    let t0 = tokio::time::Instant::now();
    let e = net.running_board(0x11, T).await.unwrap_err();
    assert!(
        matches!(e, RedundantError::Net(NetError::Timeout { .. })),
        "{e:?}"
    );
    assert_eq!(tokio::time::Instant::now() - t0, T);
    net.close().await;
    a.shutdown().await;
    b.shutdown().await;
}

/// Both boards of a pair running with different inputs for longer than the discrepancy time
/// (100 ms): a discrepancy on the door's event stream, typed and one line; cleared when they
/// agree again.
#[tokio::test(start_paused = true)]
async fn a_discrepancy_between_a_and_b_reaches_the_event_stream() {
    use duocan_redundancy::link::events::{LinkEvent, LinkEventKind};
    use duocan_redundancy::net::RedundantEvent;
    use duocan_redundancy::PairId;
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let net = RedundantNetwork::builder()
        .node_id(7)
        .pair(0x10, 0x50)
        .open(buses[0].port(), buses[1].port())
        .unwrap();
    let boards = [on_both(0x10, &buses), on_both(0x50, &buses)];
    let running = net.running_board(0x10, T).await.unwrap();
    let other = if running == 0x10 { 0x50 } else { 0x10 };
    for (id, input) in [(running, 1u16), (other, 2)] {
        let node = net.add_node(id, sim_description().unwrap());
        let mut t1 = node.tpdo(1).read().await.unwrap();
        t1.event_timer_ms = Some(20);
        node.tpdo(1).save(&t1).await.unwrap();
        node.sdo().write(0x6000, 1, input).await.unwrap();
    }
    let mut events = net.events();
    net.node(other).start().await.unwrap();
    let discrepancy = |e: &NetEvent| {
        matches!(
            e.ext::<RedundantEvent>(),
            Some(RedundantEvent::Link(LinkEvent {
                kind: LinkEventKind::Discrepancy {
                    pair: PairId(0),
                    ..
                },
                ..
            }))
        )
    };
    let cleared = |e: &NetEvent| {
        matches!(
            e.ext::<RedundantEvent>(),
            Some(RedundantEvent::Link(LinkEvent {
                kind: LinkEventKind::DiscrepancyCleared {
                    pair: PairId(0),
                    ..
                },
                ..
            }))
        )
    };
    let seen = drain(&mut events, 500).await;
    let d = seen.iter().find(|e| discrepancy(e)).unwrap_or_else(|| {
        panic!("no discrepancy among {seen:#?}");
    });
    assert!(
        d.to_string().starts_with("pair 0 function 1: A sends "),
        "{d}"
    );
    net.node(other).sdo().write(0x6000, 1, 1u16).await.unwrap();
    let seen = drain(&mut events, 500).await;
    assert!(seen.iter().any(cleared), "{seen:#?}");
    net.close().await;
    for b in boards {
        b.shutdown().await;
    }
}
