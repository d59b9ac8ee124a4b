//! Helpers for tests that run devices under the tokio runtime on real ports.
#![allow(dead_code)]

use duocan::machine::{SinglePort, Station, StationEvent};
use duocan::node::{NodeEvent, NodeEventKind};
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::runtime::RuntimeEvent;
use duocan::{Node, NodeConfig, NodeId};
use std::time::Duration;
use tokio::sync::broadcast;

pub type TestNode = Node<DynamicDictionary>;

/// A node with heartbeat period `hb_ms` (0: off) and heartbeat consumers `(node, timeout_ms)`.
pub fn node(id: u8, master: bool, hb_ms: u16, consume: &[(u8, u16)]) -> TestNode {
    let nid = NodeId::new(id).expect("valid node-ID");
    let mut od = comm::standard_dictionary(
        id,
        comm::Identity {
            vendor: 0x1234,
            product: id as u32,
            ..Default::default()
        },
    );
    od.write_local(comm::HEARTBEAT_PRODUCER, 0, &hb_ms.to_le_bytes())
        .expect("0x1017 writable");
    for (i, (n, t)) in consume.iter().enumerate() {
        let v = ((*n as u32) << 16) | *t as u32;
        od.write_local(comm::HEARTBEAT_CONSUMER, i as u8 + 1, &v.to_le_bytes())
            .expect("0x1016 writable");
    }
    let cfg = if master {
        NodeConfig::master(nid)
    } else {
        NodeConfig::slave(nid)
    };
    Node::new(cfg, od)
}

pub fn single(n: TestNode) -> Station<SinglePort, TestNode> {
    Station::single(n)
}

/// Machine events that may carry a node event.
pub trait NodeEv {
    fn node_ev(&self) -> Option<NodeEventKind>;
}

impl NodeEv for NodeEvent {
    fn node_ev(&self) -> Option<NodeEventKind> {
        Some(self.kind)
    }
}

impl<B> NodeEv for duocan::machine::CompositeEvent<NodeEvent, B> {
    fn node_ev(&self) -> Option<NodeEventKind> {
        match self {
            duocan::machine::CompositeEvent::A(n) => Some(n.kind),
            duocan::machine::CompositeEvent::B(_) => None,
        }
    }
}

/// The node event inside a runtime event of a station, if it is one.
pub fn node_event<L, M: NodeEv>(e: &RuntimeEvent<StationEvent<L, M>>) -> Option<NodeEventKind> {
    match e {
        RuntimeEvent::Device(StationEvent::Machine(n)) => n.node_ev(),
        _ => None,
    }
}

/// Waits up to `secs` for an event `pick` accepts.
pub async fn wait_for<E: Clone, T>(
    rx: &mut broadcast::Receiver<E>,
    secs: u64,
    what: &str,
    mut pick: impl FnMut(&E) -> Option<T>,
) -> T {
    let r = tokio::time::timeout(Duration::from_secs(secs), async {
        loop {
            match rx.recv().await {
                Ok(e) => {
                    if let Some(t) = pick(&e) {
                        return t;
                    }
                }
                Err(broadcast::error::RecvError::Lagged(_)) => {}
                Err(broadcast::error::RecvError::Closed) => {
                    panic!("runtime closed waiting for {what}")
                }
            }
        }
    })
    .await;
    match r {
        Ok(t) => t,
        Err(_) => panic!("timed out after {secs} s waiting for {what}"),
    }
}

/// Collects every event for `ms` milliseconds.
pub async fn collect<E: Clone>(rx: &mut broadcast::Receiver<E>, ms: u64) -> Vec<E> {
    let mut out = Vec::new();
    let until = tokio::time::Instant::now() + Duration::from_millis(ms);
    loop {
        match tokio::time::timeout_at(until, rx.recv()).await {
            Ok(Ok(e)) => out.push(e),
            Ok(Err(broadcast::error::RecvError::Lagged(_))) => {}
            Ok(Err(_)) | Err(_) => return out,
        }
    }
}

/// Application entries for SDO tests: 0x2000 u32 (expedited), 0x2001 visible string and
/// 0x2002 domain (segmented and block), all writable.
pub fn add_sdo_entries(od: &mut DynamicDictionary) {
    use duocan::od::{Access, DataType, DefaultValue, ObjectDef};
    od.insert(ObjectDef::u32(0x2000, 0, Access::Rw, 0xCAFE_F00D).named("Value"))
        .expect("new entry");
    od.insert(
        ObjectDef::bytes(0x2001, 0, DataType::VisibleString, 64)
            .access(Access::Rw)
            .default(DefaultValue::Bytes(b"duocan node over a real bus"))
            .named("Text"),
    )
    .expect("new entry");
    od.insert(
        ObjectDef::bytes(0x2002, 0, DataType::Domain, 4096)
            .access(Access::Rw)
            .named("Blob"),
    )
    .expect("new entry");
}

/// A node with the SDO test entries.
pub fn sdo_node(id: u8, master: bool, hb_ms: u16, consume: &[(u8, u16)]) -> TestNode {
    let mut n = node(id, master, hb_ms, consume);
    add_sdo_entries(n.od_mut());
    n
}

/// A master: node plus SDO client.
pub type Master = Station<SinglePort, duocan::machine::Composite<TestNode, duocan::sdo::SdoClient>>;

pub fn master(id: u8, consume: &[(u8, u16)]) -> Master {
    Station::single(duocan::machine::Composite::new(
        sdo_node(id, true, 0, consume),
        duocan::sdo::SdoClient::new(8192),
    ))
}

/// `len` bytes of a recognisable pattern.
pub fn pattern(len: usize, seed: u8) -> Vec<u8> {
    (0..len)
        .map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed))
        .collect()
}

/// Adds RPDO1 on `cob_id` mapping 0x2100:00 (u16) to a node's dictionary.
pub fn add_rpdo1(n: &mut TestNode, cob_id: u32) {
    use duocan::od::{Access, DefaultValue, ObjectDef};
    use duocan::pdo::params;
    let od = n.od_mut();
    od.upsert(
        ObjectDef::u16(0x2100, 0, Access::Rw, 0)
            .mappable()
            .named("Peer value"),
    );
    for d in params::rpdo_comm(1, DefaultValue::Unsigned(cob_id as u64), 254, 0) {
        od.upsert(d);
    }
    for d in params::rpdo_mapping::<9>(1, &[0x2100_0010]) {
        od.upsert(d);
    }
}

/// Waits until `count()` has grown by `n` — behaviour, not speed: the VM's emulated CPU may be
/// slow under load — collecting the events meanwhile. Panics after `secs` naming `what`.
pub async fn until_grown<E: Clone>(
    rx: &mut broadcast::Receiver<E>,
    count: impl Fn() -> u64,
    n: u64,
    secs: u64,
    what: &str,
) -> Vec<E> {
    let start = count();
    let until = tokio::time::Instant::now() + Duration::from_secs(secs);
    let mut out = Vec::new();
    while count() - start < n {
        assert!(
            tokio::time::Instant::now() < until,
            "{what}: only {} of {n} in {secs} s",
            count() - start
        );
        match tokio::time::timeout(Duration::from_millis(20), rx.recv()).await {
            Ok(Ok(e)) => out.push(e),
            Ok(Err(broadcast::error::RecvError::Closed)) => panic!("runtime closed"),
            _ => {}
        }
    }
    out
}

/// The SDO error of a handle call that must have failed with one (anything else fails the test).
pub fn sdo_error<T: std::fmt::Debug>(
    r: Result<T, duocan::runtime::RuntimeError>,
) -> duocan::sdo::SdoError {
    match r {
        Err(duocan::runtime::RuntimeError::Sdo(e)) => e,
        other => panic!("expected an SDO error, got {other:?}"),
    }
}
