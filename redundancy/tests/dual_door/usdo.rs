//! The front door on a CANopen FD network over two buses (`open_dual` with
//! `NetOptions::with_fd`): typed reads and writes go over USDO (CiA 1301), each request on both
//! buses, each answer taken once, and a transfer goes on when bus 1 is cut in its middle.

use duocan::frame::FdFrame;
use duocan::net::{sim_dictionary, NetError, NetOptions, Network, SIM_VENDOR};
use duocan::od::{DataType, DynamicDictionary, ObjectDef};
use duocan::port::mem::{Connector, MemBus};
use duocan::port::{AnyInput, Port};
use duocan::runtime::{Handle, Runtime};
use duocan::{Id, Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::net::{open_dual, DualLink};
use duocan_redundancy::{DualBus, DualBusConfig, DualBusNode};
use std::time::Duration;

/// The network's own USDO client node-ID.
const ME: NodeId = NodeId::must(127);
/// A domain of the node, for segmented transfers.
const DOMAIN: u16 = 0x2002;

/// Node `id` serving USDO, through its own dual-bus layer with both ports FD, on both buses.
fn fd_node(id: u8, buses: &[MemBus; 2]) -> Handle<DualBusNode<DynamicDictionary>> {
    let nid = NodeId::must(id);
    let mut od = sim_dictionary(nid);
    od.insert_all(&[ObjectDef::bytes(DOMAIN, 0, DataType::Domain, 4096)])
        .unwrap();
    let mut n = Node::new(NodeConfig::slave(nid).with_fd(true), od);
    n.boot(Instant::ZERO);
    let mut link = DualBus::new(DualBusConfig::default());
    link.set_port_fd(0, true);
    link.set_port_fd(1, true);
    Runtime::new(Station::new(link, n))
        .port(buses[0].port())
        .port(buses[1].port())
        .spawn()
        .unwrap()
}

/// Two buses, a watcher on each, the FD network on both (bus 1 through a connector that can
/// be pulled), node 5 serving USDO on both.
struct Rig {
    watch: [duocan::port::mem::MemPort; 2],
    cut: Connector,
    net: Network,
    node: Handle<DualBusNode<DynamicDictionary>>,
}

fn rig() -> Rig {
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let watch = [buses[0].port(), buses[1].port()];
    let (port1, cut) = buses[0].plugged_port();
    let opts = NetOptions::default()
        .with_sdo_timeout(Duration::from_millis(200))
        .with_fd(ME);
    let net = open_dual(port1, buses[1].port(), opts).unwrap();
    let node = fd_node(5, &buses);
    Rig {
        watch,
        cut,
        net,
        node,
    }
}

/// The CAN FD frames a watcher saw until its bus was quiet for 50 ms: USDO requests of the
/// network's client and answers of node 5.
async fn fd_frames(port: &mut duocan::port::mem::MemPort) -> (Vec<FdFrame>, Vec<FdFrame>) {
    let (mut requests, mut answers) = (vec![], vec![]);
    while let Ok(Ok(input)) = tokio::time::timeout(Duration::from_millis(50), port.recv_any()).await
    {
        match input {
            AnyInput::Fd(f, _) if f.id() == Id::Standard(0x600 + 127) => requests.push(f),
            AnyInput::Fd(f, _) if f.id() == Id::Standard(0x585) => answers.push(f),
            _ => {}
        }
    }
    (requests, answers)
}

/// The node's USDO server counters: (completed, aborted, busy, repeated segment requests).
async fn served(node: &Handle<DualBusNode<DynamicDictionary>>) -> (u32, u32, u32, u32) {
    node.call(|d, _| {
        let u = d.machine.usdo_server().unwrap().stats();
        (u.completed, u.aborted, u.busy, u.repeats)
    })
    .await
    .unwrap()
}

fn pattern(len: usize) -> Vec<u8> {
    (0..len).map(|i| (i * 31 + 7) as u8).collect()
}

#[tokio::test(start_paused = true)]
async fn typed_reads_and_writes_go_over_usdo_on_both_buses() {
    let mut r = rig();
    let sdo = r.net.node(5).sdo();
    assert_eq!(sdo.read::<u32>(0x1018, 1).await.unwrap(), SIM_VENDOR);
    sdo.write(0x1017, 0, 250u16).await.unwrap();
    assert_eq!(sdo.read::<u16>(0x1017, 0).await.unwrap(), 250);
    let blob = pattern(3000);
    sdo.write_bytes(DOMAIN, 0, blob.clone()).await.unwrap();
    assert_eq!(sdo.read_bytes(DOMAIN, 0).await.unwrap(), blob);
    // Every request reached the node once (a second copy of a segment request would count as
    // a repeat, of an expedited one as a transfer of its own).
    let (completed, aborted, busy, repeats) = served(&r.node).await;
    assert_eq!((completed, aborted, busy, repeats), (5, 0, 0, 0));
    // Each bus carried every request and every answer, in CAN FD frames.
    let [w1, w2] = &mut r.watch;
    let (req1, ans1) = fd_frames(w1).await;
    let (req2, ans2) = fd_frames(w2).await;
    assert!(req1.len() > 5, "segmented: {}", req1.len());
    assert_eq!((&req1, &ans1), (&req2, &ans2));
    r.net.close().await;
    r.node.shutdown().await;
}

#[tokio::test(start_paused = true)]
async fn a_usdo_transfer_goes_on_when_bus_1_is_cut_in_its_middle() {
    let mut r = rig();
    let sdo = r.net.node(5).sdo();
    let blob = pattern(3000);
    let write = tokio::spawn({
        let sdo = sdo.clone();
        let blob = blob.clone();
        async move { sdo.write_bytes(DOMAIN, 0, blob).await }
    });
    // Bus 1 is cut once it carried a few of the transfer's requests.
    let mut seen = 0;
    while seen < 4 {
        if let AnyInput::Fd(f, _) = r.watch[0].recv_any().await.unwrap() {
            seen += usize::from(f.id() == Id::Standard(0x600 + 127));
        }
    }
    r.cut.pull();
    write.await.unwrap().unwrap();
    let (req1, _) = fd_frames(&mut r.watch[0]).await;
    let (req2, _) = fd_frames(&mut r.watch[1]).await;
    assert!(
        req1.len() < req2.len(),
        "bus 1 was cut mid-transfer: {} of {} requests on it after the first 4",
        req1.len(),
        req2.len()
    );
    assert_eq!(sdo.read_bytes(DOMAIN, 0).await.unwrap(), blob);
    let (completed, aborted, busy, repeats) = served(&r.node).await;
    assert_eq!((completed, aborted, busy, repeats), (2, 0, 0, 0));
    r.net.close().await;
    r.node.shutdown().await;
}

#[tokio::test(start_paused = true)]
async fn an_fd_network_on_a_classic_link_is_refused() {
    let buses = [MemBus::new("bus1"), MemBus::new("bus2")];
    let e = Network::open_link(
        Box::new(DualLink::default()),
        (buses[0].port(), buses[1].port()),
        NetOptions::default().with_fd(ME),
    )
    .err()
    .expect("refused");
    assert!(
        matches!(&e, NetError::Port(m) if m.contains("carries CAN FD")),
        "{e}"
    );
    // With the link carrying CAN FD, it opens.
    let net = Network::open_link(
        Box::new(DualLink::default().fd()),
        (buses[0].port(), buses[1].port()),
        NetOptions::default().with_fd(ME),
    )
    .unwrap();
    net.close().await;
}
