//! The front door configuring and sending PDOs of up to 64 bytes on a CANopen FD network: the
//! mapping saved over USDO (more than 64 bits), RPDOs sent in CAN FD frames padded with 0xCC to
//! the next CAN FD length, the node's dictionary changed by them, and a TPDO the door
//! configured arriving decoded. On a classic network the same map is refused before anything
//! is written.

use crate::rt::TestNode;
use duocan::machine::{SinglePort, Station};
use duocan::net::{AnyValue, NetError, NetOptions, Network};
use duocan::port::mem::MemBus;
use duocan::port::{AnyInput, Port};
use duocan::runtime::{Handle, Runtime};
use duocan::{CobId, Id, NodeId};
use std::time::Duration;

fn fd_options() -> NetOptions {
    NetOptions::default()
        .with_sdo_timeout(Duration::from_millis(300))
        .with_fd(duocan::net::FD_CLIENT)
}

/// Node `id` on a CANopen FD network (operational at once): eight UNSIGNED64 entries
/// 0x6100–0x6107 and an UNSIGNED8 0x6110, all mappable and writable, with TPDO1 and RPDO1–2
/// disabled and unmapped, for the door to configure.
async fn fd_node(bus: &MemBus, id: u8) -> Handle<Station<SinglePort, TestNode>> {
    use duocan::od::{comm, Access, DataType, DefaultValue, ObjectDef};
    use duocan::pdo::params;
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    let mut defs: Vec<ObjectDef> = (0..8)
        .map(|i| {
            ObjectDef::new(0x6100 + i, 0, DataType::Unsigned64)
                .mappable()
                .access(Access::Rw)
        })
        .collect();
    defs.push(
        ObjectDef::new(0x6110, 0, DataType::Unsigned8)
            .mappable()
            .access(Access::Rw),
    );
    od.insert_all(&defs).unwrap();
    let off = |base: u32| DefaultValue::NodeIdPlus(0x8000_0000 + base);
    od.insert_all(&params::tpdo_comm(1, off(0x180), 254, 0, 0))
        .unwrap();
    od.insert_all(&params::tpdo_mapping::<9>(1, &[])).unwrap();
    for pdo in 1..=2 {
        let base = 0x200 + 0x100 * (u32::from(pdo) - 1);
        od.insert_all(&params::rpdo_comm(pdo, off(base), 255, 0))
            .unwrap();
        od.insert_all(&params::rpdo_mapping::<9>(pdo, &[])).unwrap();
    }
    let n = TestNode::new(
        duocan::NodeConfig::slave(NodeId::must(id))
            .with_fd(true)
            .with_auto_start(true),
        od,
    );
    let s = Runtime::new(Station::new(SinglePort::fd(), n))
        .port(bus.port())
        .spawn()
        .unwrap();
    s.boot().await.unwrap();
    s
}

/// The next CAN FD frame on `id` the tester port sees within 2 s.
async fn next_fd(wire: &mut impl Port, id: u16) -> duocan::frame::FdFrame {
    tokio::time::timeout(Duration::from_secs(2), async {
        loop {
            if let Ok(AnyInput::Fd(f, _)) = wire.recv_any().await {
                if f.id() == Id::Standard(id) {
                    return f;
                }
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("no CAN FD frame on {id:#05x} within 2 s"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_door_configures_a_64_byte_rpdo_and_its_frame_changes_the_nodes_dictionary() {
    let bus = MemBus::new("fd-rpdo");
    let mut wire = bus.port();
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let s = fd_node(&bus, 5).await;
    let node = net.node(5);
    // RPDO1: the eight UNSIGNED64 entries, 512 bits, saved over USDO.
    let mut map = node.rpdo(1).blank().unwrap();
    for i in 0..8 {
        map.add(0x6100 + i, 0, 64).unwrap();
    }
    map.cob_id = CobId(0x205);
    map.enabled = true;
    assert_eq!(map.bits(), 512);
    node.rpdo(1).save(&map).await.unwrap();
    assert_eq!(
        node.sdo().read::<u8>(0x1600, 0).await.unwrap(),
        8,
        "the mapping is on the node"
    );
    let values: Vec<AnyValue> = (0..8u64)
        .map(|k| AnyValue::Unsigned(0x0102_0304_0506_0708 * (k + 1)))
        .collect();
    node.rpdo(1).send(&values).await.unwrap();
    // On the wire: one 64-byte CAN FD frame, the values little-endian one after the other.
    let f = next_fd(&mut wire, 0x205).await;
    assert_eq!(f.data().len(), 64);
    assert_eq!(
        f.data()[8..16],
        (0x0102_0304_0506_0708u64 * 2).to_le_bytes()
    );
    // The node applied it: every entry holds its value.
    for k in 0..8u16 {
        let want = 0x0102_0304_0506_0708u64 * (u64::from(k) + 1);
        let mut got = Vec::new();
        for _ in 0..100 {
            got = s.read(0x6100 + k, 0).await.unwrap();
            if got == want.to_le_bytes() {
                break;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        assert_eq!(got, want.to_le_bytes(), "0x{:04x}", 0x6100 + k);
    }

    // RPDO2: 72 bits, 9 bytes, in a 12-byte frame padded with 0xCC; by name of nothing, in
    // order; the node takes its 9 bytes.
    let mut map = node.rpdo(2).blank().unwrap();
    map.add(0x6107, 0, 64).unwrap().add(0x6110, 0, 8).unwrap();
    map.cob_id = CobId(0x305);
    map.enabled = true;
    node.rpdo(2).save(&map).await.unwrap();
    node.rpdo(2)
        .send(&[AnyValue::Unsigned(u64::MAX), AnyValue::Unsigned(0xA5)])
        .await
        .unwrap();
    let f = next_fd(&mut wire, 0x305).await;
    let mut want = vec![0xFF; 8];
    want.extend([0xA5, 0xCC, 0xCC, 0xCC]);
    assert_eq!(f.data(), &want[..]);
    for _ in 0..100 {
        if s.read(0x6110, 0).await.unwrap() == [0xA5] {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(s.read(0x6110, 0).await.unwrap(), [0xA5]);
    assert_eq!(s.read(0x6107, 0).await.unwrap(), u64::MAX.to_le_bytes());
    // A value too wide for its entry is refused, nothing sent.
    let e = node
        .rpdo(2)
        .send(&[AnyValue::Unsigned(1), AnyValue::Unsigned(256)])
        .await
        .unwrap_err();
    assert!(matches!(e, NetError::BadValue { .. }), "{e:?}");
    net.close().await;
    s.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tpdo_the_door_configured_over_64_bits_arrives_decoded() {
    use duocan::net::NetEvent;
    let bus = MemBus::new("fd-tpdo");
    let mut wire = bus.port();
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let s = fd_node(&bus, 6).await;
    for k in 0..5u16 {
        let v = 1000 + u64::from(k);
        s.write(0x6100 + k, 0, v.to_le_bytes().to_vec())
            .await
            .unwrap();
    }
    s.write(0x6110, 0, vec![7]).await.unwrap();
    let node = net.node(6);
    let mut events = net.events();
    // TPDO1: five UNSIGNED64 and one UNSIGNED8, 328 bits (41 bytes), every 20 ms.
    let mut map = node.tpdo(1).read().await.unwrap();
    map.clear();
    for k in 0..5 {
        map.add(0x6100 + k, 0, 64).unwrap();
    }
    map.add(0x6110, 0, 8).unwrap();
    map.cob_id = CobId(0x186);
    map.enabled = true;
    map.transmission_type = 254;
    map.event_timer_ms = Some(20);
    node.tpdo(1).save(&map).await.unwrap();
    // Read back over USDO: what the node holds is what was saved.
    let back = node.tpdo(1).read().await.unwrap();
    assert_eq!((back.bits(), back.event_timer_ms), (328, Some(20)));
    let got = tokio::time::timeout(Duration::from_secs(2), async {
        loop {
            if let Some(NetEvent::Pdo {
                node, pdo, values, ..
            }) = events.next().await
            {
                return (node, pdo, values);
            }
        }
    })
    .await
    .expect("a decoded TPDO within 2 s");
    assert_eq!((got.0, got.1), (NodeId::must(6), 1));
    let v: Vec<AnyValue> = got.2.iter().map(|p| p.value.clone()).collect();
    let mut want: Vec<AnyValue> = (0..5).map(|k| AnyValue::Unsigned(1000 + k)).collect();
    want.push(AnyValue::Unsigned(7));
    assert_eq!(v, want);
    // Its frame: 41 bytes in a 48-byte CAN FD frame, the padding 0xCC.
    let f = next_fd(&mut wire, 0x186).await;
    assert_eq!(f.data().len(), 48);
    assert_eq!(f.data()[40], 7);
    assert!(f.data()[41..].iter().all(|&b| b == 0xCC), "{:x?}", f.data());
    net.close().await;
    s.shutdown().await;
}

/// On a classic network a map cannot grow over 64 bits (the error says FD carries 512), and
/// one that has more (built for an FD network) is refused when saved, before a write reaches
/// the node; on an FD network a map cannot grow over 512 bits.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_classic_network_refuses_a_mapping_over_64_bits() {
    let fd = Network::simulated([5], fd_options()).unwrap();
    let mut map = fd.node(5).rpdo(2).blank().unwrap();
    for _ in 0..4 {
        map.add(0x6200, 1, 16).unwrap();
    }
    map.add(0x6200, 2, 8).unwrap();
    map.cob_id = CobId(0x305);
    map.enabled = true;
    let mut wide = fd.node(5).rpdo(2).blank().unwrap();
    for _ in 0..8 {
        wide.add(0x6100, 0, 64).unwrap();
    }
    assert!(wide.add(0x6110, 0, 1).is_err(), "513 bits");
    fd.close().await;

    let net = Network::simulated([5], NetOptions::default()).unwrap();
    let node = net.node(5);
    let mut classic = node.rpdo(2).blank().unwrap();
    classic.add(0x6200, 1, 64).unwrap();
    let e = classic.add(0x6200, 2, 8).unwrap_err();
    assert!(e.to_string().contains("on a CANopen FD network 512"), "{e}");
    // The 72-bit map built on the FD network, saved on the classic one.
    map.node = NodeId::must(5);
    let e = node.rpdo(2).save(&map).await.unwrap_err();
    match &e {
        NetError::Pdo { why, .. } => assert!(why.contains("longer than 64 bits"), "{why}"),
        other => panic!("{other:?}"),
    }
    // Nothing was written: RPDO2 is still disabled and unmapped.
    assert_eq!(node.sdo().read::<u8>(0x1601, 0).await.unwrap(), 0);
    net.close().await;
}

/// End to end over the in-memory FD bus, each node on its runtime: a master's
/// destination-address MPDO of eight bytes leaves as one 12-byte CAN FD frame and writes the
/// UNSIGNED64 of node 5, whose dictionary shows it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_fd_mpdo_between_two_runtime_stations_writes_eight_bytes() {
    use duocan::od::{comm, Access, DataType, DefaultValue, ObjectDef};
    use duocan::pdo::params;
    const DAM_COB: u16 = 0x300;
    let station = |id: u8, tx: bool| {
        let mut od = comm::standard_dictionary(id, comm::Identity::default());
        od.insert_all(&[ObjectDef::new(0x2200, 0, DataType::Unsigned64)
            .mappable()
            .access(Access::Rw)])
            .unwrap();
        let cob = DefaultValue::Unsigned(DAM_COB.into());
        let mut mapping = if tx {
            od.insert_all(&params::tpdo_comm(1, cob, 254, 0, 0))
                .unwrap();
            params::tpdo_mapping::<2>(1, &[]).to_vec()
        } else {
            od.insert_all(&params::rpdo_comm(1, cob, 254, 0)).unwrap();
            params::rpdo_mapping::<2>(1, &[]).to_vec()
        };
        // 0xFF: a destination-address MPDO.
        mapping[0] = ObjectDef::u8(mapping[0].index, 0, Access::Rw, 0xFF);
        od.insert_all(&mapping).unwrap();
        let n = TestNode::new(
            duocan::NodeConfig::slave(NodeId::must(id))
                .with_fd(true)
                .with_auto_start(true),
            od,
        );
        Station::new(SinglePort::fd(), n)
    };
    let bus = MemBus::new("fd-mpdo");
    let mut wire = bus.port();
    let master = Runtime::new(station(1, true))
        .port(bus.port())
        .spawn()
        .unwrap();
    let n5 = Runtime::new(station(5, false))
        .port(bus.port())
        .spawn()
        .unwrap();
    master.boot().await.unwrap();
    n5.boot().await.unwrap();
    let v = 0xFEDC_BA98_7654_3210u64;
    master
        .call(move |s, now| {
            s.machine
                .mpdo_send_dam(now, 1, 5, 0x2200, 0, &v.to_le_bytes())
        })
        .await
        .unwrap()
        .unwrap();
    let f = next_fd(&mut wire, DAM_COB).await;
    assert_eq!(f.data().len(), 12);
    assert_eq!(f.data()[..4], [0x85, 0x00, 0x22, 0x00]);
    let mut got = Vec::new();
    for _ in 0..100 {
        got = n5.read(0x2200, 0).await.unwrap();
        if got == v.to_le_bytes() {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(got, v.to_le_bytes());
    master.shutdown().await;
    n5.shutdown().await;
}

/// The simulated nodes of `sim-nodes:fd` through the door: RPDO1 sent by name in a CAN FD
/// frame changes node 5's outputs (read back over USDO), and TPDO1, given an event timer by
/// the door, arrives decoded by name.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_simulated_fd_nodes_pdos_through_the_door() {
    use duocan::NmtState;
    let net = Network::open_named("sim-nodes:fd").unwrap();
    let node = net.add_node(5, duocan::net::sim_description().unwrap());
    node.start().await.unwrap();
    node.wait_for_state(NmtState::Operational, Duration::from_secs(2))
        .await
        .unwrap();
    node.rpdo(1)
        .send_named(&[("Output 1", 4321u16.into())])
        .await
        .unwrap();
    let mut out = 0u16;
    for _ in 0..100 {
        out = node.sdo().read(0x6200, 1).await.unwrap();
        if out == 4321 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    assert_eq!(out, 4321);
    node.sdo().write(0x6000, 1, 77u16).await.unwrap();
    node.tpdo(1)
        .edit(|m| m.event_timer_ms = Some(20))
        .await
        .unwrap();
    let v = node.wait_for_pdo(1, Duration::from_secs(2)).await.unwrap();
    assert_eq!(v.get("Input 1"), Some(&AnyValue::Unsigned(77)));
    net.close().await;
}
