//! The redundant network's front door on the simulated station (`open_named("sim-pairs")`), on
//! tokio's paused clock (deterministic): the builder's settings reach the running machines
//! (the failovers come exactly when the configured heartbeats and timeouts say), SDO goes
//! and NMT go through the handle to pair members, and the scripted faults give one failover of each kind.

use duocan::net::{NetError, NetEvent};
use duocan::od::DynamicDictionary;
use duocan::sdo::{SdoErrorKind, SdoOptions};
use duocan::{AbortCode, Duration, Instant, NmtState, NodeId};
use duocan_redundancy::net::{
    RedundantEvent, RedundantNetwork, SIM_BUS_FAILS, SIM_B_BOOTS, SIM_END, SIM_MEMBER_FAILS,
    SIM_PEERS_FAIL,
};
use duocan_redundancy::supervisor::flying_master::{MasterReason, MasterRole, MasterRoleChange};
use duocan_redundancy::supervisor::pairs::{RoleChange, RoleReason};
use duocan_redundancy::{LogicalNetwork, Member, NetProfile, NetworkError, RedundantError};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn after(d: Duration) -> Instant {
    Instant::ZERO + d
}

/// Every event until the simulation ends.
async fn all_events(net: &RedundantNetwork) -> Vec<NetEvent> {
    let mut events = net.events();
    let mut out = vec![];
    while let Some(e) = events.next().await {
        out.push(e);
    }
    out
}

/// Waits (simulated time) until a pair has an active member.
async fn until_pair_active(net: &RedundantNetwork) {
    for _ in 0..400 {
        let active = net.active_members().await.unwrap();
        if active.iter().all(|(_, m)| m.is_some()) && !active.is_empty() {
            return;
        }
        tokio::time::sleep(std::time::Duration::from_millis(10)).await;
    }
    panic!("no active pair member:\n{}", net.status().await.unwrap());
}

#[tokio::test(start_paused = true)]
async fn the_simulated_station_plays_one_failover_of_each_kind_at_the_configured_times() {
    let (hb, master_timeout, pair_hb, pair_timeout) = (ms(20), ms(50), ms(25), ms(80));
    let net = RedundantNetwork::builder()
        .node_id(2)
        .heartbeat(hb)
        .master_timeout(master_timeout)
        .sync(ms(10))
        .pair(0x10, 0x50)
        .pair_heartbeat(pair_hb)
        .pair_timeout(pair_timeout)
        .peer_master(1)
        .open_named("sim-pairs")
        .unwrap();
    let events = all_events(&net).await;
    let failovers: Vec<&NetEvent> = events.iter().filter(|e| e.is_failover()).collect();
    let lines: Vec<String> = failovers.iter().map(ToString::to_string).collect();
    assert_eq!(
        lines,
        [
            "bus 1: failed (port down: interface down)",
            "this master: active",
            "pair 0x10/0x50: B active"
        ],
        "{events:#?}"
    );
    // The bus fails when its port does.
    assert_eq!(failovers[0].at(), Some(after(SIM_BUS_FAILS)));
    // What the application does not see but a maintainer must: from the cut on, the members
    // are heard on bus 2 only (reported once each, when their first frame misses bus 1).
    let reach: Vec<String> = events
        .iter()
        .filter(|e| matches!(e, NetEvent::Reach { .. }))
        .filter(|e| e.at() >= Some(after(SIM_BUS_FAILS)))
        .map(ToString::to_string)
        .collect();
    for node in ["0x10", "0x50"] {
        let line = format!("node {node}: heard on bus 2 only");
        assert_eq!(reach.iter().filter(|l| **l == line).count(), 1, "{reach:?}");
    }
    // The takeover: exactly the peer's last heartbeat + the master timeout, and that last
    // heartbeat is the one before the peer stopped (it beats every `hb`).
    let Some(&RedundantEvent::MasterRole(MasterRoleChange {
        from: MasterRole::Standby(_),
        reason: MasterReason::HeartbeatLost { master, last },
        at,
        ..
    })) = failovers[1].ext()
    else {
        panic!("{:?}", failovers[1]);
    };
    assert_eq!(master.raw(), 1);
    assert_eq!(at, last + master_timeout);
    let stopped = after(SIM_PEERS_FAIL);
    assert!(last <= stopped && stopped <= last + hb, "last {last}");
    // The pair: A (booted first, active) stops; B takes over exactly at A's last heartbeat
    // + the pair timeout.
    let Some(&RedundantEvent::PairRole(RoleChange {
        from: Some(Member::A),
        to: Some(Member::B),
        reason: RoleReason::ActiveSilent { last },
        at,
        ..
    })) = failovers[2].ext()
    else {
        panic!("{:?}", failovers[2]);
    };
    assert_eq!(at, last + pair_timeout);
    let stopped = after(SIM_MEMBER_FAILS);
    assert!(last <= stopped && stopped <= last + pair_hb, "last {last}");
    // The network closed itself at the end of the simulation.
    assert!(net.now() >= after(SIM_END));
    assert_eq!(net.role().await, Err(RedundantError::Closed));
}

#[tokio::test(start_paused = true)]
async fn a_member_not_heard_within_the_boot_timeout_is_reported_once() {
    // The simulated station powers member B on at `SIM_B_BOOTS` (1 s): with a boot timeout of
    // 400 ms, B is reported at exactly 400 ms, A (heard at once) not then. A stops for good at
    // `SIM_MEMBER_FAILS`: reset at its silence, it is not heard for 400 ms after the reset.
    let net = RedundantNetwork::builder()
        .node_id(2)
        .pair(0x10, 0x50)
        .boot_timeout(ms(400))
        .peer_master(1)
        .open_named("sim-pairs")
        .unwrap();
    let events = all_events(&net).await;
    let not_heard: Vec<&NetEvent> = events
        .iter()
        .filter(|e| matches!(e, NetEvent::NotHeard { .. }))
        .collect();
    assert_eq!(not_heard.len(), 2, "{not_heard:#?}");
    assert_eq!(
        *not_heard[0],
        NetEvent::NotHeard {
            node: NodeId::must(0x50),
            since: Instant::ZERO,
            at: after(ms(400)),
        }
    );
    assert!(ms(400) < SIM_B_BOOTS);
    assert_eq!(not_heard[0].to_string(), "node 0x50: not heard for 400 ms");
    let NetEvent::NotHeard { node, since, at } = *not_heard[1] else {
        unreachable!()
    };
    let reset = events.iter().find_map(|e| match e.ext() {
        Some(RedundantEvent::PairRole(r)) if r.at > after(SIM_MEMBER_FAILS) => Some(r.at),
        _ => None,
    });
    assert_eq!(
        (node.raw(), Some(since), at - since),
        (0x10, reset, ms(400)),
        "{events:#?}"
    );
}

#[tokio::test(start_paused = true)]
async fn sdo_through_the_handle_to_a_pair_member_on_either_bus() {
    let net = RedundantNetwork::builder()
        .node_id(1)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .pair(0x10, 0x50)
        .pair_heartbeat(ms(25))
        .pair_timeout(ms(80))
        .open_named("sim-pairs")
        .unwrap();
    until_pair_active(&net).await;
    assert_eq!(net.role().await.unwrap(), MasterRole::Active);
    // A member's heartbeat the master guards already: watching it leaves its table as it is.
    let table = |n: &mut LogicalNetwork<DynamicDictionary, NetProfile>, _| {
        use duocan::od::ObjectDictionary;
        (0..=127u8)
            .map(|s| n.od().get_u32(0x1016, s))
            .collect::<Vec<_>>()
    };
    let before = net.with(table).await.unwrap();
    assert!(
        before.iter().any(|v| v.is_some_and(|v| v >> 16 == 0x10)),
        "{before:x?}"
    );
    net.node(0x10)
        .watch_heartbeat(std::time::Duration::from_millis(500))
        .await
        .unwrap();
    assert_eq!(net.with(table).await.unwrap(), before);
    // B boots later than A (so that A is the active member); then it is configured too.
    tokio::time::sleep(std::time::Duration::from_micros(
        SIM_B_BOOTS.as_micros() + 100_000,
    ))
    .await;
    // The standby member B answers like any node.
    let b = net.node(0x50);
    let vendor: u32 = b.sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(vendor, duocan::net::SIM_VENDOR);
    assert_eq!(b.sdo().read::<u32>(0x1018, 2).await.unwrap(), 0x50);
    // A write and its read-back (the producer time the master configured, changed).
    b.sdo().write(0x1017, 0, 30u16).await.unwrap();
    assert_eq!(b.sdo().read::<u16>(0x1017, 0).await.unwrap(), 30);
    // The wrong type is an error naming node and object, not garbage.
    let e = b.sdo().read::<u8>(0x1018, 1).await.unwrap_err();
    assert!(
        matches!(
            e,
            NetError::WrongSize {
                index: 0x1018,
                sub: 1,
                expected: 1,
                got: 4,
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(e.node().map(|n| n.raw()), Some(0x50));
    // An object the node does not have: the abort, with the node.
    let e = b.sdo().read::<u32>(0x6100, 0).await.unwrap_err();
    assert!(matches!(e, NetError::Sdo(_)), "{e}");
    assert!(e.to_string().contains("0x6100"), "{e}");
    // After bus 1 failed, SDO goes on over bus 2 (at about 2.3 s: bus 1 fails at 2 s, A stops
    // at 4 s).
    tokio::time::sleep(std::time::Duration::from_millis(2500) - SIM_B_BOOTS.into()).await;
    let status = net.status().await.unwrap();
    assert!(status.contains("failed"), "{status}");
    let a = net.node(0x10);
    assert_eq!(a.sdo().read::<u32>(0x1018, 2).await.unwrap(), 0x10);
    // NMT through the handle: the standby member stopped, as the master then sees it.
    b.stop().await.unwrap();
    let mut state = None;
    for _ in 0..50 {
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        state = net.slave(0x50).await.unwrap().state;
        if state == Some(NmtState::Stopped) {
            break;
        }
    }
    assert_eq!(state, Some(NmtState::Stopped));
    // A node-ID outside 1-127 is an error of the call.
    let e = net.node(0).sdo().read::<u32>(0x1000, 0).await.unwrap_err();
    assert_eq!(e, NetError::NoSuchNode(0), "{e}");
    let e = net.slave(0).await.unwrap_err();
    assert_eq!(e, RedundantError::Net(NetError::NoSuchNode(0)), "{e}");
    net.close().await;
    assert_eq!(a.sdo().read::<u32>(0x1018, 2).await, Err(NetError::Closed));
}

#[tokio::test(start_paused = true)]
async fn a_standby_master_refuses_sdo_until_it_takes_over() {
    let net = RedundantNetwork::builder()
        .node_id(2)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .pair(0x10, 0x50)
        .peer_master(1)
        .open_named("sim-pairs")
        .unwrap();
    until_pair_active(&net).await;
    assert!(matches!(net.role().await.unwrap(), MasterRole::Standby(_)));
    let e = net
        .node(0x10)
        .sdo()
        .read::<u32>(0x1018, 1)
        .await
        .unwrap_err();
    assert_eq!(
        e,
        NetError::Standby {
            node: NodeId::new(0x10)
        }
    );
    assert!(e.to_string().contains("standby"), "{e}");
    // NMT too: to a node, and to all.
    let e = net.node(0x10).start().await.unwrap_err();
    assert_eq!(
        e,
        NetError::Standby {
            node: NodeId::new(0x10)
        }
    );
    let e = net.nmt_all(duocan::NmtCommand::Start).await.unwrap_err();
    assert_eq!(e, NetError::Standby { node: None });
    // After the peer stopped, this master is active and SDO works.
    tokio::time::sleep(std::time::Duration::from_millis(3500)).await;
    assert_eq!(net.role().await.unwrap(), MasterRole::Active);
    let v: u32 = net.node(0x50).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(v, duocan::net::SIM_VENDOR);
    net.close().await;
}

#[tokio::test]
async fn names_that_are_not_two_interfaces_are_errors_naming_the_port() {
    let b = RedundantNetwork::builder();
    let e = b.open_named("can0").err().unwrap();
    assert!(matches!(e, RedundantError::Port { port: 0, .. }), "{e}");
    assert!(e.to_string().contains("can0,can1"), "{e}");
    // A simulated network by another door's name says which one this door opens.
    for name in ["sim", "sim-station", "sim-nodes", "sim:faults"] {
        let e = b.open_named(name).err().unwrap();
        let text = e.to_string();
        assert!(
            text.contains("is sim-pairs") && text.contains("sim-station:faults"),
            "{name}: {text}"
        );
    }
    // Bad settings come first, before any port is touched.
    let e = b
        .clone()
        .node_id(200)
        .open_named("sim-pairs")
        .err()
        .unwrap();
    assert!(
        matches!(e, RedundantError::BadNodeId { id: 200, .. }),
        "{e}"
    );
}

/// Master 7 opened on two in-memory buses with nobody else on them: active after the power-on
/// negotiation (2 s on the paused clock).
async fn alone_on_two_buses() -> RedundantNetwork {
    let buses = [
        duocan::port::mem::MemBus::new("can1"),
        duocan::port::mem::MemBus::new("can2"),
    ];
    let net = RedundantNetwork::builder()
        .node_id(7)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .open(buses[0].port(), buses[1].port())
        .unwrap();
    tokio::time::sleep(std::time::Duration::from_secs(2)).await;
    assert_eq!(net.role().await.unwrap(), MasterRole::Active);
    net
}

#[tokio::test(start_paused = true)]
async fn open_on_two_ports_runs_the_builders_network() {
    let net = alone_on_two_buses().await;
    let status = net.status().await.unwrap();
    assert!(status.contains("master node 0x07"), "{status}");
    // A node nobody answers for: the SDO timeout, naming the node.
    let e = net
        .node(0x33)
        .sdo()
        .read::<u32>(0x1000, 0)
        .await
        .unwrap_err();
    assert_eq!(e.node().map(|n| n.raw()), Some(0x33), "{e}");
    // The door's view of the two buses is the master's dual-bus layer's.
    let ports = net.ports().await.unwrap();
    let names: Vec<&str> = ports.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["can1", "can2"]);
    assert!(ports.iter().all(|p| p.health.is_some()), "{ports:?}");
    assert_eq!(
        net.heard_on(0x33).await.unwrap(),
        Some([false, false].into())
    );
    net.close().await;
    assert!(net.events().next().await.is_none());
}

/// The supervisor shares the SDO client with the front door (it checks and configures pair
/// members over SDO): a front-door call that finds the node's client busy waits for the
/// running transfer instead of failing with "busy".
#[tokio::test(start_paused = true)]
async fn a_call_waits_for_the_networks_own_transfer_to_the_node() {
    let net = RedundantNetwork::builder()
        .node_id(1)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .pair(0x10, 0x50)
        .open_named("sim-pairs")
        .unwrap();
    until_pair_active(&net).await;
    // Member B is silent until it boots, and the supervisor probes it meanwhile: the client
    // is busy with its transfers to B.
    let b = NodeId::must(0x50);
    let start = move |n: &mut LogicalNetwork<DynamicDictionary, NetProfile>, now| {
        n.sdo_read(now, b, 0x1018, 1)
    };
    let busy = |r: &Result<_, NetworkError>| matches!(r, Err(NetworkError::Sdo(e)) if e.kind == SdoErrorKind::Busy);
    assert!(net.now() < after(SIM_B_BOOTS));
    assert!(busy(&net.with(start).await.unwrap()));
    // Once B has booted, the supervisor checks and configures it over SDO: find an instant
    // when one of its transfers runs.
    tokio::time::sleep(std::time::Duration::from(
        SIM_B_BOOTS - (net.now() - Instant::ZERO),
    ))
    .await;
    while !busy(&net.with(start).await.unwrap()) {
        assert!(net.now() < after(SIM_B_BOOTS + ms(200)), "{}", net.now());
        tokio::time::sleep(std::time::Duration::from_micros(100)).await;
    }
    // A call in that same instant waits for it, then runs: B answers.
    let product: u32 = net.node(0x50).sdo().read(0x1018, 2).await.unwrap();
    assert_eq!(product, 0x50);
    net.close().await;
}

/// The wait is bounded by the call's own SDO timeout: a node whose client stays busy longer
/// is the "busy" error at that timeout, not a call that hangs.
#[tokio::test(start_paused = true)]
async fn the_wait_for_a_busy_client_ends_at_the_calls_timeout() {
    let net = alone_on_two_buses().await;
    // Nobody answers for 0x33: a transfer with a 1 s timeout holds its client for 1 s.
    let silent = NodeId::must(0x33);
    let long = SdoOptions::default().with_timeout(ms(1000));
    net.with(move |n, now| n.sdo_read_with(now, silent, 0x1000, 0, long))
        .await
        .unwrap()
        .unwrap();
    let node = net.node(0x33);
    // A call with a 100 ms timeout gives up after exactly that long: the door answers a
    // start still refused at its deadline, which is one of the device's own timeouts.
    let t0 = tokio::time::Instant::now();
    let e = node
        .sdo()
        .with_options(SdoOptions::default().with_timeout(ms(100)))
        .read::<u32>(0x1000, 0)
        .await
        .unwrap_err();
    let waited = t0.elapsed();
    assert!(
        matches!(e, NetError::Sdo(s) if s.kind == SdoErrorKind::Busy),
        "{e}"
    );
    assert_eq!(waited, std::time::Duration::from_millis(100));
    // A call with a 2 s timeout outlasts it: the very instant the first transfer times out
    // (1 s after it started), the call runs its own, which times out in turn (nobody answers).
    let e = node
        .sdo()
        .with_options(SdoOptions::default().with_timeout(ms(2000)))
        .read::<u32>(0x1000, 0)
        .await
        .unwrap_err();
    let waited = t0.elapsed();
    assert!(
        matches!(e, NetError::Sdo(s) if s.kind == SdoErrorKind::Client(AbortCode::TIMEOUT)),
        "{e}"
    );
    assert_eq!(waited, std::time::Duration::from_millis(3000));
    net.close().await;
}

/// Opens a network on the simulated plant `name` and collects its events for twice
/// [`SIM_END`] (the end of `sim-pairs`' script): the stream must still be open then.
async fn events_past_the_scripts_end(
    name: &str,
    node_id: u8,
    peer: u8,
) -> (RedundantNetwork, Vec<NetEvent>) {
    let net = RedundantNetwork::builder()
        .node_id(node_id)
        .heartbeat(ms(20))
        .master_timeout(ms(50))
        .pair(0x10, 0x50)
        .pair_heartbeat(ms(25))
        .pair_timeout(ms(80))
        .peer_master(peer)
        .open_named(name)
        .unwrap();
    let mut events = net.events();
    let until =
        tokio::time::Instant::now() + std::time::Duration::from_micros(2 * SIM_END.as_micros());
    let mut seen = vec![];
    while let Ok(Some(e)) = tokio::time::timeout_at(until, events.next()).await {
        seen.push(e);
    }
    assert!(
        tokio::time::Instant::now() >= until,
        "the stream ended early: {seen:#?}"
    );
    (net, seen)
}

/// The pair's running board is `m`, board 0x50 answers, and the network closes.
async fn runs_answers_and_closes(net: RedundantNetwork, m: Member) {
    let active = net.active_members().await.unwrap();
    assert_eq!(active.len(), 1);
    assert_eq!(active[0].1, Some(m), "{}", net.status().await.unwrap());
    assert_eq!(
        net.node(0x50).sdo().read::<u32>(0x1018, 2).await.unwrap(),
        0x50
    );
    net.close().await;
}

fn failovers(events: &[NetEvent]) -> Vec<String> {
    events
        .iter()
        .filter(|e| e.is_failover())
        .map(ToString::to_string)
        .collect()
}

/// `sim-pairs:quiet`: the same plant without the faults, running until the network is closed:
/// past the scripted run's end (twice [`SIM_END`]) the network is still open, nothing failed
/// over, and the pair's A member is still the active one.
#[tokio::test(start_paused = true)]
async fn the_quiet_simulated_station_runs_without_faults_until_closed() {
    let (net, seen) = events_past_the_scripts_end("sim-pairs:quiet", 1, 2).await;
    let failovers = failovers(&seen);
    // The one role change at power-on (the negotiation), no bus, master or pair failover.
    assert!(
        failovers.iter().all(|l| l == "this master: active"),
        "{failovers:#?}"
    );
    runs_answers_and_closes(net, Member::A).await;
}

/// `sim-pairs:failover`: the faults of `sim-pairs` (bus 1 cut, the peer stopped, the running
/// member stopped), then the plant runs on what is left: past the scripted run's end (twice
/// [`SIM_END`]) the network is still open, B runs the pair, this master is active, and B
/// answers.
#[tokio::test(start_paused = true)]
async fn the_failover_simulated_station_fails_then_runs_on_until_closed() {
    let (net, seen) = events_past_the_scripts_end("sim-pairs:failover", 2, 1).await;
    assert_eq!(
        failovers(&seen),
        [
            "bus 1: failed (port down: interface down)",
            "this master: active",
            "pair 0x10/0x50: B active"
        ]
    );
    // The faults are timed from the moment every pair has a running board once the B boards
    // are on (seen within the script's 100 ms poll).
    let at = |line: &str| {
        seen.iter()
            .find(|e| e.to_string().starts_with(line))
            .and_then(NetEvent::at)
            .unwrap_or_else(|| panic!("no {line:?} in {seen:#?}"))
    };
    let (a_runs, cut) = (at("pair 0x10/0x50: A active"), at("bus 1: failed"));
    let ready = a_runs.max(after(SIM_B_BOOTS));
    assert!(
        cut >= ready + SIM_BUS_FAILS && cut <= ready + SIM_BUS_FAILS + ms(110),
        "A ran at {a_runs}, bus 1 failed at {cut}"
    );
    runs_answers_and_closes(net, Member::B).await;
}
