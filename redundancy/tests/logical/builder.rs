//! The redundant network's builder, sans-IO: its settings reach the machines (the failover
//! timings in simulated time are the configured heartbeat and timeout arithmetic), and bad
//! settings are errors naming the setting, never panics.

use duocan::od::comm;
use duocan::sim::{BusConfig, SimNetwork};
use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::supervisor::flying_master::{MasterReason, MasterRole};
use duocan_redundancy::supervisor::pairs::RoleReason;
use duocan_redundancy::{
    DualBus, DualBusConfig, LogicalNetwork, Member, NetworkEventKind as K, RedundantError,
    RedundantNetworkBuilder, Role,
};

fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

fn err(b: RedundantNetworkBuilder) -> RedundantError {
    let e = b.build().expect_err("the settings are refused");
    assert!(!e.to_string().is_empty());
    e
}

#[test]
fn bad_settings_are_errors_naming_the_setting() {
    let b = LogicalNetwork::builder;
    // A pair with one node twice, a node in two roles.
    let e = err(b().pair(0x10, 0x10));
    assert!(
        matches!(
            e,
            RedundantError::NodeTwice {
                first: Role::PairMember,
                second: Role::PairMember,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("0x10"), "{e}");
    let e = err(b().node_id(5).pair(0x10, 5));
    assert!(
        matches!(
            e,
            RedundantError::NodeTwice {
                first: Role::ThisMaster,
                ..
            }
        ),
        "{e}"
    );
    let e = err(b().node_id(5).peer_master(5));
    assert!(
        matches!(
            e,
            RedundantError::NodeTwice {
                second: Role::PeerMaster,
                ..
            }
        ),
        "{e}"
    );
    let e = err(b().pair(0x10, 0x50).pair(0x50, 0x60));
    assert!(matches!(e, RedundantError::NodeTwice { .. }), "{e}");
    // Node-IDs out of range, each named with its part.
    for (builder, role, id) in [
        (b().node_id(0), Role::ThisMaster, 0),
        (b().node_id(128), Role::ThisMaster, 128),
        (b().peer_master(200), Role::PeerMaster, 200),
        (b().pair(0x10, 0), Role::PairMember, 0),
    ] {
        assert_eq!(err(builder), RedundantError::BadNodeId { role, id });
    }
    // Zero durations, each named.
    for (builder, setting) in [
        (b().heartbeat(Duration::ZERO), "heartbeat"),
        (b().master_timeout(Duration::ZERO), "master_timeout"),
        (b().sync(Duration::ZERO), "sync"),
        (b().pair_heartbeat(Duration::ZERO), "pair_heartbeat"),
        (b().pair_timeout(Duration::ZERO), "pair_timeout"),
    ] {
        let e = err(builder);
        assert_eq!(e, RedundantError::ZeroDuration { setting });
        assert!(e.to_string().starts_with(setting), "{e}");
    }
    // A timeout no longer than the heartbeat it watches, a heartbeat 0x1017 cannot hold.
    let e = err(b().heartbeat(ms(50)).master_timeout(ms(50)));
    assert!(
        matches!(
            e,
            RedundantError::TimeoutTooShort {
                setting: "master_timeout",
                ..
            }
        ),
        "{e}"
    );
    let e = err(b().pair_heartbeat(ms(100)).pair_timeout(ms(60)));
    assert!(
        matches!(
            e,
            RedundantError::TimeoutTooShort {
                setting: "pair_timeout",
                ..
            }
        ),
        "{e}"
    );
    let e = err(b().heartbeat(ms(70_000)).master_timeout(ms(80_000)));
    assert!(
        matches!(
            e,
            RedundantError::TooLong {
                setting: "heartbeat",
                ..
            }
        ),
        "{e}"
    );
    // More peers than the flying master holds.
    let mut many = b();
    for n in 2..20 {
        many = many.peer_master(n);
    }
    assert!(matches!(
        err(many),
        RedundantError::TooMany {
            what: "peer masters",
            ..
        }
    ));
    // And good settings build.
    assert!(b()
        .pair(0x10, 0x50)
        .peer_master(2)
        .sync(ms(10))
        .build()
        .is_ok());
}

/// A booted duocan board on the dual bus.
fn board(id: u8) -> Station<DualBus, Node<duocan::od::DynamicDictionary>> {
    let mut n = Node::new(
        NodeConfig::slave(NodeId::must(id)),
        comm::standard_dictionary(id, Default::default()),
    );
    n.boot(Instant::ZERO);
    Station::new(DualBus::new(DualBusConfig::default()), n)
}

#[test]
fn the_settings_reach_the_machines_failovers_come_at_the_configured_times() {
    // Two networks of some 160 kB each, moved by value into the simulator: more than a test
    // thread's default stack holds in a debug build.
    std::thread::Builder::new()
        .stack_size(32 << 20)
        .spawn(failovers_at_the_configured_times)
        .unwrap()
        .join()
        .unwrap();
}

fn failovers_at_the_configured_times() {
    let (hb, master_timeout, pair_hb, pair_timeout) = (ms(20), ms(70), ms(30), ms(110));
    let mine = LogicalNetwork::builder()
        .node_id(2)
        .heartbeat(hb)
        .master_timeout(master_timeout)
        .sync(ms(10))
        .pair(0x10, 0x50)
        .pair_heartbeat(pair_hb)
        .pair_timeout(pair_timeout)
        .peer_master(1);
    let mut sim = SimNetwork::new(7);
    let buses = [
        sim.add_bus(BusConfig::new("can1", 1_000_000)),
        sim.add_bus(BusConfig::new("can2", 1_000_000)),
    ];
    let me = sim
        .add_device("master 2", mine.build().unwrap(), &buses)
        .unwrap();
    let peer = sim
        .add_device("master 1", mine.as_peer(1).build().unwrap(), &buses)
        .unwrap();
    let a = sim.add_device("board A", board(0x10), &buses).unwrap();
    sim.run_until(Instant::from_millis(50));
    sim.add_device("board B", board(0x50), &buses).unwrap();
    sim.run_until(Instant::from_secs(2));
    assert!(matches!(sim.device(me).role(), MasterRole::Standby(_)));
    assert!(sim.device(peer).role().is_active());
    // The peer goes silent at 2 s: this master takes over at its last heartbeat + 70 ms.
    for bus in 0..2 {
        sim.disconnect(peer.port(bus));
    }
    sim.run_until(Instant::from_secs(3));
    let takeover = sim.events(me).iter().find_map(|(_, e)| match &e.kind {
        K::MasterRole(r) if r.to == MasterRole::Active => Some(*r),
        _ => None,
    });
    let r = takeover.expect("no takeover");
    let MasterReason::HeartbeatLost { master, last } = r.reason else {
        panic!("{r}");
    };
    assert_eq!(master, NodeId::must(1));
    assert_eq!(r.at, last + master_timeout);
    assert!(
        last <= Instant::from_secs(2) && Instant::from_secs(2) <= last + hb,
        "{r}"
    );
    // The active member A goes silent at 3 s: B takes over at A's last heartbeat + 110 ms.
    assert_eq!(
        sim.device(me).pairs().next().unwrap().1.active,
        Some(Member::A)
    );
    for bus in 0..2 {
        sim.disconnect(a.port(bus));
    }
    sim.run_until(Instant::from_secs(4));
    let switch = sim.events(me).iter().find_map(|(_, e)| match &e.kind {
        K::PairRole(r) if r.to == Some(Member::B) => Some(*r),
        _ => None,
    });
    let r = switch.expect("no pair failover");
    let RoleReason::ActiveSilent { last } = r.reason else {
        panic!("{r}");
    };
    assert_eq!(r.at, last + pair_timeout);
    assert!(
        last <= Instant::from_secs(3) && Instant::from_secs(3) <= last + pair_hb,
        "{r}"
    );
}

#[test]
fn times_are_taken_as_std_durations_as_well() {
    let std_ms = std::time::Duration::from_millis;
    let with_std = LogicalNetwork::builder()
        .heartbeat(std_ms(20))
        .master_timeout(std_ms(70))
        .sync(std_ms(10))
        .pair_heartbeat(std_ms(30))
        .pair_timeout(std_ms(110))
        .boot_timeout(std_ms(900));
    let with_duocan = LogicalNetwork::builder()
        .heartbeat(ms(20))
        .master_timeout(ms(70))
        .sync(ms(10))
        .pair_heartbeat(ms(30))
        .pair_timeout(ms(110))
        .boot_timeout(ms(900));
    assert_eq!(format!("{with_std:?}"), format!("{with_duocan:?}"));
    // The same checks: a zero is refused whichever type carried it.
    let e = err(LogicalNetwork::builder().sync(std::time::Duration::ZERO));
    assert!(
        matches!(e, RedundantError::ZeroDuration { setting: "sync" }),
        "{e}"
    );
}
