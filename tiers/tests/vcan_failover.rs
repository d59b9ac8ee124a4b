//! The dual-bus layer under duocan's tokio runtime on two real SocketCAN interfaces: vcan0 is
//! set down mid-run and up again. Runs inside duocan's qemu VM (`.ci/tier-vcan.sh`).

use duocan::machine::{Station, StationEvent};
use duocan::node::NodeEventKind;
use duocan::port::socketcan::SocketCanPort;
use duocan::port::{Port, PortInput};
use duocan::runtime::{Runtime, RuntimeEvent};
use duocan::Duration;
use duocan_redundancy::{DualBus, DualBusConfig, LinkEvent, LinkEventKind, LinkMode, PortState};
use std::sync::{Arc, Mutex};
use std::time::Duration as StdDuration;

// The root crate's helpers for runtime tests (nodes, waiting on events).
#[path = "../../tests/common/runtime.rs"]
mod rt;
use rt::wait_for;
#[path = "common/cut.rs"]
mod cut;
use cut::{port_reported, LinkDown};

type Dev = Station<DualBus, rt::TestNode>;
type Ev = RuntimeEvent<StationEvent<LinkEvent, duocan::NodeEvent>>;

const HB_MS: u16 = 25;

fn station(id: u8, master: bool, hb_ms: u16, consume: Option<(u8, u16)>) -> Dev {
    let link = DualBus::new(DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        Duration::from_millis(HB_MS as u64),
    ));
    let consume: Vec<_> = consume.into_iter().collect();
    Station::new(link, rt::node(id, master, hb_ms, &consume))
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

/// When each of node 5's frames arrived on `bus` (the kernel's stamps), read beside the master
/// until the bus goes down.
fn watch(bus: &str) -> Arc<Mutex<Vec<std::time::Instant>>> {
    let seen = Arc::<Mutex<Vec<_>>>::default();
    let s = seen.clone();
    let mut port = SocketCanPort::open(bus).unwrap();
    tokio::spawn(async move {
        while let Ok(input) = port.recv().await {
            if let PortInput::Frame(f, Some(at)) = input {
                if f.id().raw() & 0x7F == 5 {
                    s.lock().unwrap().push(at);
                }
            }
        }
    });
    seen
}

/// How many of node 5's frames on vcan0 (its first `n`) have no copy on vcan1 within `window`:
/// the slave's two writes of a frame further apart than that (the emulated CPU held its
/// runtime up between them) are two occurrences to the merger by its documented rule.
fn apart(
    bus0: &[std::time::Instant],
    bus1: &[std::time::Instant],
    n: usize,
    window: StdDuration,
) -> usize {
    let near = |a: std::time::Instant, b: std::time::Instant| {
        a.saturating_duration_since(b)
            .max(b.saturating_duration_since(a))
            <= window
    };
    bus0.iter()
        .take(n)
        .filter(|a| !bus1.iter().any(|b| near(**a, *b)))
        .count()
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
    let seen = [watch("vcan0"), watch("vcan1")];
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
    // The merger hands each heartbeat to the node once, although it arrives twice. What it
    // delivered is read first, then what the ports received: heartbeats keep coming meanwhile
    // (in the emulated VM a call takes a few of their periods), and only so is the bound
    // true whenever it is read. A heartbeat whose two copies the slave wrote further apart
    // than the skew window is two occurrences (see `apart`), delivered once or twice.
    let (delivered, window) = master
        .call(|d, _| (d.link.stats().delivered, d.link.merger().window()))
        .await
        .unwrap();
    let (a, b) = (
        master.port_counters(0).unwrap().rx_frames,
        master.port_counters(1).unwrap().rx_frames,
    );
    assert!(a >= 5 && b >= 5, "heartbeats on both buses: {a} {b}");
    // Wait until the watchers have read as much as the master had (they run beside it).
    let until = tokio::time::Instant::now() + StdDuration::from_secs(10);
    while seen
        .iter()
        .any(|s| s.lock().unwrap().len() < a.max(b) as usize)
        && tokio::time::Instant::now() < until
    {
        tokio::time::sleep(StdDuration::from_millis(20)).await;
    }
    let apart = {
        let (s0, s1) = (seen[0].lock().unwrap(), seen[1].lock().unwrap());
        let window = StdDuration::from_micros(window.as_micros());
        apart(&s0, &s1, a.max(b) as usize, window)
    };
    println!("{delivered} delivered of {a}+{b} received, {apart} written beyond the window");
    assert!(
        delivered <= a.max(b) + 2 + apart as u64,
        "{delivered} delivered of {a}+{b} received ({apart} written more than {window:?} apart)"
    );

    let down = LinkDown::new("vcan0");
    port_reported(&mut ev, 0, false, 5).await;
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
    port_reported(&mut ev, 0, true, 5).await;
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
