//! The dual-bus layer under duocan's tokio runtime on two real SocketCAN interfaces: vcan0 is
//! set down mid-run and up again. Runs inside duocan's qemu VM (`.ci/tier-vcan.sh`).

use duocan::machine::{PortStatus, Station, StationEvent};
use duocan::node::NodeEventKind;
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::port::socketcan::SocketCanPort;
use duocan::runtime::{Runtime, RuntimeEvent};
use duocan::{Duration, Node, NodeConfig, NodeId};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEvent, LinkEventKind, Mode, PortState};
use std::process::Command;
use std::time::Duration as StdDuration;
use tokio::sync::broadcast;

type Dev = Station<DualBus, Node<DynamicDictionary>>;
type Ev = RuntimeEvent<StationEvent<LinkEvent, duocan::NodeEvent>>;

const HB_MS: u16 = 25;

fn station(id: u8, master: bool, hb_ms: u16, consume: Option<(u8, u16)>) -> Dev {
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    od.write_local(comm::HEARTBEAT_PRODUCER, 0, &hb_ms.to_le_bytes())
        .unwrap();
    if let Some((n, t)) = consume {
        let v = ((n as u32) << 16) | t as u32;
        od.write_local(comm::HEARTBEAT_CONSUMER, 1, &v.to_le_bytes())
            .unwrap();
    }
    let nid = NodeId::new(id).unwrap();
    let cfg = if master {
        NodeConfig::master(nid)
    } else {
        NodeConfig::slave(nid)
    };
    let link = DualBus::new(DualBusConfig::with_guard_period(
        Mode::ActiveActive,
        Duration::from_millis(HB_MS as u64),
    ));
    Station::new(link, Node::new(cfg, od))
}

fn ip(args: &[&str]) {
    let st = Command::new("ip").args(args).status().expect("run ip");
    assert!(st.success(), "ip {args:?} failed");
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

async fn wait_for<T>(
    rx: &mut broadcast::Receiver<Ev>,
    secs: u64,
    what: &str,
    mut pick: impl FnMut(&Ev) -> Option<T>,
) -> T {
    let r = tokio::time::timeout(StdDuration::from_secs(secs), async {
        loop {
            match rx.recv().await {
                Ok(e) => {
                    if let Some(t) = pick(&e) {
                        return t;
                    }
                }
                Err(broadcast::error::RecvError::Lagged(_)) => {}
                Err(broadcast::error::RecvError::Closed) => panic!("runtime closed"),
            }
        }
    })
    .await;
    r.unwrap_or_else(|_| panic!("timed out after {secs} s waiting for {what}"))
}

fn link_port(e: &Ev) -> Option<(u8, PortState)> {
    match e {
        RuntimeEvent::Device(StationEvent::Link(LinkEvent {
            kind: LinkEventKind::Port { port, to, .. },
            ..
        })) => Some((*port, *to)),
        _ => None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn frames_keep_flowing_on_vcan1_while_vcan0_is_down_and_vcan0_recovers() {
    let master = Runtime::new(station(1, true, 0, Some((5, 300))))
        .name("master")
        .port(SocketCanPort::open("vcan0").unwrap())
        .port(SocketCanPort::open("vcan1").unwrap())
        .spawn()
        .unwrap();
    let slave = Runtime::new(station(5, false, HB_MS, None))
        .name("slave")
        .port(SocketCanPort::open("vcan0").unwrap())
        .port(SocketCanPort::open("vcan1").unwrap())
        .spawn()
        .unwrap();
    let mut ev = master.subscribe();
    master.call(|d, now| d.machine.boot(now)).await.unwrap();
    slave.call(|d, now| d.machine.boot(now)).await.unwrap();
    for p in [0, 1] {
        let until = tokio::time::Instant::now() + StdDuration::from_secs(10);
        while master.port_counters(p).unwrap().rx_frames < 5 {
            assert!(
                tokio::time::Instant::now() < until,
                "no heartbeats on port {p}"
            );
            tokio::time::sleep(StdDuration::from_millis(20)).await;
        }
    }
    let (a, b) = (
        master.port_counters(0).unwrap().rx_frames,
        master.port_counters(1).unwrap().rx_frames,
    );
    assert!(a >= 5 && b >= 5, "heartbeats on both buses: {a} {b}");
    // The merger hands each heartbeat to the node once, although it arrives twice.
    let delivered = master.call(|d, _| d.link.stats().delivered).await.unwrap();
    assert!(
        delivered <= a.max(b) + 2,
        "{delivered} delivered of {a}+{b} received"
    );

    ip(&["link", "set", "vcan0", "down"]);
    let down = LinkDown;
    wait_for(&mut ev, 5, "runtime reports port 0 down", |e| match e {
        RuntimeEvent::Port {
            port: 0,
            status: PortStatus::Down(_),
            ..
        } => Some(()),
        _ => None,
    })
    .await;
    wait_for(&mut ev, 5, "layer marks port 0 failed", |e| {
        (link_port(e) == Some((0, PortState::Failed))).then_some(())
    })
    .await;
    // Behaviour, not speed: the emulated CPU may be slow, so wait (generously) for 15 more
    // frames on vcan1 instead of counting within a fixed window.
    let before = master.port_counters(1).unwrap().rx_frames;
    let mut lost = false;
    let until = tokio::time::Instant::now() + StdDuration::from_secs(20);
    while master.port_counters(1).unwrap().rx_frames - before < 15 {
        assert!(
            tokio::time::Instant::now() < until,
            "frames stopped on vcan1 while vcan0 was down: {} in 20 s",
            master.port_counters(1).unwrap().rx_frames - before
        );
        if let Ok(Ok(RuntimeEvent::Device(StationEvent::Machine(n)))) =
            tokio::time::timeout(StdDuration::from_millis(50), ev.recv()).await
        {
            lost |= matches!(n.kind, NodeEventKind::HeartbeatTimeout { .. });
        }
    }
    assert!(!lost, "the node above never lost the slave's heartbeat");

    drop(down);
    wait_for(&mut ev, 5, "runtime reports port 0 up", |e| match e {
        RuntimeEvent::Port {
            port: 0,
            status: PortStatus::Up,
            ..
        } => Some(()),
        _ => None,
    })
    .await;
    wait_for(&mut ev, 10, "layer trusts port 0 again", |e| {
        (link_port(e) == Some((0, PortState::Ok))).then_some(())
    })
    .await;
    let p0 = master.port_counters(0).unwrap().rx_frames;
    let until = tokio::time::Instant::now() + StdDuration::from_secs(20);
    while master.port_counters(0).unwrap().rx_frames - p0 < 5 {
        assert!(
            tokio::time::Instant::now() < until,
            "frames flow on vcan0 again"
        );
        tokio::time::sleep(StdDuration::from_millis(20)).await;
    }
    master.shutdown().await;
    slave.shutdown().await;
}
