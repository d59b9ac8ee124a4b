//! The redundant network's front door on two real SocketCAN interfaces:
//! `RedundantNetwork::builder()…open_named("vcan0,vcan1")` with the two boards of a pair on
//! both, SDO through the handle to a pair member, vcan0 set down (a bus failover on the flat
//! event stream) and SDO going on over vcan1; and the `redundant_pdo` example as it is, on
//! `DUOCAN_BUS=vcan0,vcan1` with a pair of boards carrying `duocan::net`'s simulated dictionary.
//! Runs inside duocan's qemu VM (`.ci/tier-vcan.sh`).

use duocan::net::NetEvent;
use duocan::od::comm;
use duocan::od::DynamicDictionary;
use duocan::port::socketcan::SocketCanPort;
use duocan::runtime::{Handle, Runtime};
use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::net::RedundantNetwork;
use duocan_redundancy::{DualBus, DualBusConfig, DualBusNode, LinkMode, PortState};
use std::process::Command;
use std::time::Duration as StdDuration;

#[path = "../../examples/redundant_pdo.rs"]
#[allow(dead_code)]
mod redundant_pdo;

/// The dual-bus layer as the VM needs it: its emulated CPU can hold a sender up between its two
/// copies of a frame (the boards', and the master's), so that they are on the wires, and
/// stamped, further apart than the default 5 ms skew window (as for the dual_vcan_failover
/// example).
fn link(guard: Duration) -> DualBusConfig {
    let mut cfg = DualBusConfig::with_guard_period(LinkMode::ActiveActive, guard);
    cfg.skew_window = Duration::from_millis(25);
    cfg.health.tx_stall = cfg.skew_window;
    cfg
}

/// Board `id` with dictionary `od` on vcan0 and vcan1, booted, through its own dual-bus layer.
fn board(id: u8, od: DynamicDictionary) -> Handle<DualBusNode<DynamicDictionary>> {
    let mut node = Node::new(NodeConfig::slave(NodeId::must(id)), od);
    node.boot(Instant::ZERO);
    Runtime::new(Station::new(
        DualBus::new(link(Duration::from_millis(50))),
        node,
    ))
    .name(format!("board {id:#x}"))
    .port(SocketCanPort::open("vcan0").unwrap())
    .port(SocketCanPort::open("vcan1").unwrap())
    .spawn()
    .unwrap()
}

/// vcan0 down until dropped (also when the test fails).
struct LinkDown;
impl Drop for LinkDown {
    fn drop(&mut self) {
        let _ = Command::new("ip")
            .args(["link", "set", "vcan0", "up"])
            .status();
    }
}

/// The product code (0x1018:2) of `node`; on failure, the network's status with the error (its
/// SDO and dual-bus counters tell a lost answer from a late copy).
async fn product(net: &RedundantNetwork, node: u8) -> u32 {
    match net.node(node).sdo().read(0x1018, 2).await {
        Ok(p) => p,
        Err(e) => {
            let counters = net
                .with(|n, _| {
                    let st = n.station();
                    format!(
                        "{:?}\n{:?}\n{:?}",
                        st.link.stats(),
                        st.link.merger().stats(),
                        n.supervisor().master().sdo().stats()
                    )
                })
                .await
                .unwrap_or_else(|e| e.to_string());
            panic!(
                "reading {node:#x}'s product code: {e}\n{}\n{counters}",
                net.status().await.unwrap_or_else(|e| e.to_string())
            )
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_redundant_front_door_fails_over_between_vcan0_and_vcan1() {
    let ms = Duration::from_millis;
    let net = RedundantNetwork::builder()
        .node_id(1)
        .heartbeat(ms(50))
        .master_timeout(ms(200))
        .pair(0x10, 0x50)
        .pair_heartbeat(ms(50))
        .pair_timeout(ms(300))
        .link(link(ms(50)))
        .open_named("vcan0,vcan1")
        .expect("vcan0 and vcan1 exist and are up");
    let mut events = net.events();
    let boards = [0x10u8, 0x50].map(|id| {
        let ident = comm::Identity {
            product: u32::from(id),
            ..Default::default()
        };
        board(id, comm::standard_dictionary(id, ident))
    });
    // Active (alone: after the power-on negotiation) with a pair member running.
    let until = tokio::time::Instant::now() + StdDuration::from_secs(30);
    loop {
        let active = net.active_members().await.unwrap();
        if active.iter().all(|(_, m)| m.is_some()) {
            break;
        }
        assert!(
            tokio::time::Instant::now() < until,
            "no active pair member in 30 s:\n{}",
            net.status().await.unwrap()
        );
        tokio::time::sleep(StdDuration::from_millis(50)).await;
    }
    assert_eq!(product(&net, 0x50).await, 0x50);

    let st = Command::new("ip")
        .args(["link", "set", "vcan0", "down"])
        .status()
        .expect("run ip");
    assert!(st.success());
    let down = LinkDown;
    let failover = tokio::time::timeout(StdDuration::from_secs(10), async {
        while let Some(e) = events.next().await {
            if let NetEvent::PortState {
                port: 0,
                to: PortState::Failed,
                ..
            } = e
            {
                return Some(e);
            }
        }
        None
    })
    .await
    .expect("a bus failover within 10 s of vcan0 going down")
    .expect("the event stream went on");
    assert!(failover.is_failover());
    // The line names the reason: the driver's report, or the silence that gave it away.
    let line = failover.to_string();
    assert!(line.starts_with("bus 1: failed ("), "{line}");
    // SDO goes on over vcan1.
    assert_eq!(product(&net, 0x10).await, 0x10);
    drop(down);
    net.close().await;
    for b in boards {
        b.shutdown().await;
    }
}

/// The `redundant_pdo` example, unchanged, on two real buses: the master it opens configures
/// the active board's TPDO, reads its inputs and writes its outputs by RPDO, as on the
/// simulated station. The boards are processes' worth of runtimes on vcan0 and vcan1 with the
/// dictionary the simulated station's boards carry (inputs on TPDO 1, outputs on RPDO 1).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_redundant_pdo_example_runs_on_vcan0_and_vcan1() {
    let boards = [0x10u8, 0x50].map(|id| board(id, duocan::net::sim_dictionary(NodeId::must(id))));
    // What the boards said, on vcan0, for a failure's message.
    let watch = duocan::net::Network::monitor(SocketCanPort::open("vcan0").unwrap()).unwrap();
    let mut heard = watch.events();
    let seen = tokio::spawn(async move {
        let mut lines = vec![];
        while let Some(e) = heard.next().await {
            lines.push(e.to_string());
        }
        lines
    });
    let run = redundant_pdo::run("vcan0,vcan1");
    let result = tokio::time::timeout(StdDuration::from_secs(60), run).await;
    watch.close().await;
    let seen = seen.await.unwrap().join("\n");
    let output = result
        .unwrap_or_else(|_| panic!("the example ends within 60 s; on vcan0:\n{seen}"))
        .unwrap_or_else(|e| panic!("the example runs: {e}; on vcan0:\n{seen}"));
    assert_eq!(
        output, 1234,
        "the output it wrote by RPDO, read back by SDO"
    );
    for b in boards {
        b.shutdown().await;
    }
}
