//! Streamed SDO (`write_from`, `read_to`) through both doors on two buses: the plain door over
//! the dual link and the redundant master's. The door writes the transfer once, whatever sits
//! below: 64 KiB each way, with progress, to a node on both buses.

use crate::doors::{on_both, open, BOTH};
use duocan::net::{Network, TransferProgress};
use duocan::od::{Access, DataType, DynamicDictionary, ObjectDef};
use duocan::port::mem::MemBus;
use duocan::runtime::Handle;
use duocan::sdo::SdoServerConfig;
use duocan::{Instant, Node, NodeConfig, NodeId};
use duocan_redundancy::DualBusNode;

/// A DOMAIN on the node, and the size streamed through it.
const BIG: u16 = 0x2010;
const SIZE: usize = 64 * 1024;

/// Simulated node 5 on both buses, with a 64 KiB domain its server takes whole.
fn big_node(buses: &[MemBus; 2]) -> Handle<DualBusNode<DynamicDictionary>> {
    let id = NodeId::must(5);
    let mut n = Node::new(NodeConfig::slave(id), duocan::net::sim_dictionary(id));
    n.od_mut()
        .insert(ObjectDef::bytes(BIG, 0, DataType::Domain, SIZE as u32).access(Access::Rw))
        .unwrap();
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(SIZE));
    n.boot(Instant::ZERO);
    on_both(n, buses)
}

/// Checks a run of progress reports: never falling, ending at the size, some along the way.
fn rising(reports: &[TransferProgress]) {
    for w in reports.windows(2) {
        assert!(w[0].done <= w[1].done, "{w:?}");
    }
    assert_eq!(reports.last().map(|p| p.done), Some(SIZE as u64));
    assert!(reports.len() > 3, "reported along the way: {reports:?}");
}

/// 64 KiB written from a reader and read back into a writer, byte for byte.
async fn streams_64_kib(net: &Network) {
    let blob: Vec<u8> = (0..SIZE).map(|i| (i * 7 + i / 251) as u8).collect();
    let sdo = net.node(5).sdo();
    let mut sent = vec![];
    let n = sdo
        .write_from(BIG, 0, &blob[..], Some(SIZE as u64), |p| sent.push(p))
        .await
        .unwrap();
    assert_eq!(n, SIZE as u64);
    rising(&sent);
    let mut back = Vec::new();
    let mut got = vec![];
    let n = sdo
        .read_to(BIG, 0, &mut back, |p| got.push(p))
        .await
        .unwrap();
    assert_eq!(n, SIZE as u64);
    rising(&got);
    assert!(back == blob, "the value read back is the value written");
}

#[tokio::test(start_paused = true)]
async fn both_doors_stream_64_kib_each_way() {
    for door in BOTH {
        let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
        let net = open(door, &buses).await;
        let node = big_node(&buses);
        streams_64_kib(&net).await;
        net.close().await;
        node.shutdown().await;
    }
}
