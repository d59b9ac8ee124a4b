//! The runtime end to end: nodes on an in-memory bus, requests, the tap, the clock.

use super::*;

proptest::proptest! {
    /// The clock's microseconds are the standard library's, without its 128-bit division.
    #[test]
    fn micros_are_the_standard_librarys(secs in 0u64..1 << 40, nanos in 0u32..1_000_000_000) {
        let d = std::time::Duration::new(secs, nanos);
        proptest::prop_assert_eq!(
            micros(d),
            Instant::from_micros(u64::try_from(d.as_micros()).unwrap())
        );
    }
}
use crate::machine::{Station, StationEvent};
use crate::node::{NodeEvent, NodeEventKind};
use crate::od::{comm, DynamicDictionary};
use crate::port::mem::MemBus;
use crate::{NmtCommand, NmtState, NmtTarget, Node, NodeConfig, NodeId};
use std::time::Duration as StdDuration;

type Dev = Station<crate::machine::SinglePort, Node<DynamicDictionary>>;

fn node(id: u8, master: bool, hb_ms: u16) -> Dev {
    let nid = NodeId::new(id).unwrap();
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    use crate::od::ObjectDictionary;
    od.write_local(comm::HEARTBEAT_PRODUCER, 0, &hb_ms.to_le_bytes())
        .unwrap();
    let cfg = if master {
        NodeConfig::master(nid)
    } else {
        NodeConfig::slave(nid)
    };
    Station::single(Node::new(cfg, od))
}

fn node_event(
    e: &RuntimeEvent<StationEvent<std::convert::Infallible, NodeEvent>>,
) -> Option<NodeEventKind> {
    match e {
        RuntimeEvent::Device(StationEvent::Machine(n)) => Some(n.kind),
        _ => None,
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn master_starts_a_slave_and_hears_its_heartbeat() {
    let bus = MemBus::new("mem0");
    let slave = Runtime::new(node(5, false, 20))
        .name("slave")
        .port(bus.port())
        .spawn()
        .unwrap();
    let master = Runtime::new(node(1, true, 0))
        .name("master")
        .port(bus.port())
        .spawn()
        .unwrap();
    let mut ev = master.subscribe();
    slave.boot().await.unwrap();
    master.boot().await.unwrap();
    master
        .nmt(NmtCommand::Start, NmtTarget::Node(NodeId::new(5).unwrap()))
        .await
        .unwrap();
    let seen = tokio::time::timeout(StdDuration::from_secs(5), async {
        loop {
            let e = ev.recv().await.unwrap();
            if let Some(NodeEventKind::RemoteState {
                node,
                to: NmtState::Operational,
                ..
            }) = node_event(&e)
            {
                return node;
            }
        }
    })
    .await
    .expect("master saw the slave operational");
    assert_eq!(seen.raw(), 5);
    assert_eq!(slave.nmt_state().await.unwrap(), NmtState::Operational);
    assert_eq!(slave.read(0x1017, 0).await.unwrap(), 20u16.to_le_bytes());
    // Heartbeats come from the node's deadlines: about 1 per 20 ms, not per runtime tick.
    let before = master.port_counters(0).unwrap().rx_frames;
    tokio::time::sleep(StdDuration::from_millis(400)).await;
    let n = master.port_counters(0).unwrap().rx_frames - before;
    assert!((10..=22).contains(&n), "{n} heartbeats in 400 ms at 20 ms");
    // A write through the handle takes effect: heartbeat off, frames stop.
    slave
        .write(0x1017, 0, 0u16.to_le_bytes().to_vec())
        .await
        .unwrap();
    tokio::time::sleep(StdDuration::from_millis(50)).await;
    let before = master.port_counters(0).unwrap().rx_frames;
    tokio::time::sleep(StdDuration::from_millis(200)).await;
    assert_eq!(master.port_counters(0).unwrap().rx_frames, before);
    slave.shutdown().await;
    master.shutdown().await;
    assert!(master.nmt_state().await.is_err(), "closed runtime says so");
}

#[tokio::test]
async fn port_count_must_match() {
    let bus = MemBus::new("m");
    let e = Runtime::new(node(1, true, 0))
        .port(bus.port())
        .port(bus.port())
        .spawn();
    assert_eq!(
        e.err(),
        Some(StartError::PortCount {
            device: 1,
            given: 2
        })
    );
}

#[tokio::test]
async fn request_waits_for_the_completing_event() {
    let bus = MemBus::new("m");
    let master = Runtime::new(node(1, true, 0))
        .port(bus.port())
        .spawn()
        .unwrap();
    let slave = Runtime::new(node(9, false, 0))
        .port(bus.port())
        .spawn()
        .unwrap();
    slave.boot().await.unwrap();
    // Start: boot the master; done: the event that says it is operational.
    let r = master.request(
        |d, now| {
            d.machine.boot(now);
            Ok::<_, RuntimeError>(d.machine.id())
        },
        |id, e| match e {
            StationEvent::Machine(NodeEvent {
                kind:
                    NodeEventKind::StateChanged {
                        to: NmtState::Operational,
                        ..
                    },
                at,
            }) => Some(Ok((*id, *at))),
            _ => None,
        },
    );
    let (id, _at) = tokio::time::timeout(StdDuration::from_secs(5), r)
        .await
        .unwrap()
        .unwrap();
    assert_eq!(id.raw(), 1);
}

#[derive(Clone, Default)]
struct Shared(Arc<std::sync::Mutex<Vec<u8>>>);
impl std::io::Write for Shared {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[tokio::test]
async fn the_tap_records_what_each_port_sends_and_receives() {
    use crate::capture::{
        candump,
        recorder::{Filter, Recorder},
    };
    let bus = MemBus::new("m");
    let log = Shared::default();
    let rec = Arc::new(
        Recorder::with_epoch(0)
            .port_names(["mem0"])
            .candump(Filter::All, log.clone()),
    );
    let master = Runtime::new(node(1, true, 0))
        .port(bus.port())
        .tap(rec.clone())
        .spawn()
        .unwrap();
    let slave = Runtime::new(node(5, false, 0))
        .port(bus.port())
        .spawn()
        .unwrap();
    let mut ev = master.subscribe();
    master.boot().await.unwrap();
    slave.boot().await.unwrap();
    tokio::time::timeout(StdDuration::from_secs(5), async {
        loop {
            if let Some(NodeEventKind::BootUp { .. }) = node_event(&ev.recv().await.unwrap()) {
                return;
            }
        }
    })
    .await
    .unwrap();
    let text = String::from_utf8(log.0.lock().unwrap().clone()).unwrap();
    let frames: Vec<_> = text
        .lines()
        .map(|l| candump::parse_line(l).unwrap())
        .map(|e| (e.interface, e.record.frame().copied().unwrap()))
        .collect();
    let boot = |id: u16| crate::Frame::from_array(crate::Id::Standard(0x700 + id), [0]);
    assert_eq!(
        frames,
        [("mem0".to_string(), boot(1)), ("mem0".to_string(), boot(5))],
        "the master's own boot-up (sent) and the slave's (received)"
    );
}
