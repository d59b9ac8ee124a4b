//! The front door on a CANopen FD network (`NetOptions::with_fd`): the same typed reads and
//! writes as over SDO, the same values and errors, carried by USDO (CiA 1301) in CAN FD frames
//! to nodes that serve it (`NodeConfig::fd`), over the in-memory bus with FD.

use crate::rt::{pattern, sdo_node, TestNode};
use duocan::machine::{SinglePort, Station};
use duocan::net::{NetError, NetOptions, Network};
use duocan::port::mem::MemBus;
use duocan::port::{AnyInput, Port};
use duocan::runtime::{Handle, Runtime};
use duocan::sdo::SdoErrorKind;
use duocan::{AbortCode, Id, NodeId};
use std::time::Duration;

/// The network's own USDO client node-ID.
const ME: NodeId = NodeId::must(127);

fn fd_options() -> NetOptions {
    NetOptions::default()
        .with_sdo_timeout(Duration::from_millis(100))
        .with_fd(ME)
}

type FdStation = Station<SinglePort, TestNode>;

/// Node `id` with the SDO test entries, configured for FD, on an FD port of `bus`, booted.
async fn fd_node(bus: &MemBus, id: u8) -> Handle<FdStation> {
    // The classic tests' node and dictionary, rebuilt with the FD switch on.
    let mut classic = sdo_node(id, false, 0, &[]);
    let od = std::mem::replace(classic.od_mut(), duocan::od::DynamicDictionary::new(id));
    let n = TestNode::new(
        duocan::NodeConfig::slave(NodeId::must(id)).with_fd(true),
        od,
    );
    let s = Runtime::new(Station::new(SinglePort::fd(), n))
        .port(bus.port())
        .spawn()
        .unwrap();
    s.boot().await.unwrap();
    s
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn typed_values_and_strings_over_usdo() {
    let bus = MemBus::new("fd");
    let mut tester = bus.port();
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let s = fd_node(&bus, 5).await;
    let node = net.node(5);
    // The calls and values of the classic tests (`sdo.rs`).
    assert_eq!(node.sdo().read::<u32>(0x1018, 1).await.unwrap(), 0x1234);
    assert_eq!(node.sdo().read::<u32>(0x1018, 2).await.unwrap(), 5);
    assert_eq!(node.sdo().read::<u8>(0x1018, 0).await.unwrap(), 4);
    assert_eq!(
        node.sdo().read::<u32>(0x2000, 0).await.unwrap(),
        0xCAFE_F00D
    );
    node.sdo().write(0x1017, 0, 250u16).await.unwrap();
    assert_eq!(node.sdo().read::<u16>(0x1017, 0).await.unwrap(), 250);
    assert_eq!(s.read(0x1017, 0).await.unwrap(), 250u16.to_le_bytes());
    assert_eq!(
        node.sdo().read_string(0x2001, 0).await.unwrap(),
        "duocan node over a real bus"
    );
    let e = node.sdo().read::<u16>(0x1018, 1).await.unwrap_err();
    assert_eq!(
        e,
        NetError::WrongSize {
            node: NodeId::must(5),
            index: 0x1018,
            sub: 1,
            expected: 2,
            got: 4
        }
    );
    // On the bus: USDO requests from node 127 and answers from node 5, in CAN FD frames; no
    // classic SDO frame.
    let mut requests = 0;
    let mut answers = 0;
    while let Ok(Ok(input)) =
        tokio::time::timeout(Duration::from_millis(50), tester.recv_any()).await
    {
        match input {
            AnyInput::Fd(f, _) if f.id() == Id::Standard(0x600 + 127) => requests += 1,
            AnyInput::Fd(f, _) if f.id() == Id::Standard(0x585) => answers += 1,
            AnyInput::Frame(f, _) => {
                let raw = match f.id() {
                    Id::Standard(r) => r,
                    Id::Extended(_) => 0,
                };
                assert!(!(0x580..0x680).contains(&raw), "classic SDO frame {f:?}");
            }
            _ => {}
        }
    }
    assert_eq!((requests, answers), (8, 8));
    net.close().await;
    s.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn domains_and_strings_segmented_over_usdo() {
    let bus = MemBus::new("fd");
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let s = fd_node(&bus, 6).await;
    let sdo = net.node(6).sdo();
    let blob = pattern(3000, 7);
    sdo.write_bytes(0x2002, 0, blob.clone()).await.unwrap();
    assert_eq!(s.read(0x2002, 0).await.unwrap(), blob, "the node holds it");
    assert_eq!(sdo.read_bytes(0x2002, 0).await.unwrap(), blob);
    sdo.write_string(0x2001, 0, "written through the front door over USDO")
        .await
        .unwrap();
    assert_eq!(
        sdo.read_string(0x2001, 0).await.unwrap(),
        "written through the front door over USDO"
    );
    // Not UTF-8 is the same error as over SDO.
    sdo.write_bytes(0x2001, 0, vec![0xff, 0xfe]).await.unwrap();
    assert!(matches!(
        sdo.read_string(0x2001, 0).await,
        Err(NetError::NotText {
            index: 0x2001,
            sub: 0,
            ..
        })
    ));
    net.close().await;
    s.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn errors_are_the_sdo_errors() {
    let bus = MemBus::new("fd");
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let s = fd_node(&bus, 5).await;
    // Nobody answers for node 9: a timeout naming it and the object, after the 100 ms given.
    let started = std::time::Instant::now();
    let e = net.node(9).sdo().read::<u32>(0x1018, 1).await.unwrap_err();
    assert!(started.elapsed() >= Duration::from_millis(100));
    assert!(e.is_no_answer(), "{e:?}");
    assert_eq!(e.node().map(|n| n.raw()), Some(9));
    assert_eq!(e.abort_code(), Some(AbortCode::TIMEOUT));
    match &e {
        NetError::Sdo(s) => assert_eq!((s.index, s.sub), (0x1018, 1)),
        other => panic!("{other:?}"),
    }
    // The node's refusals are its abort codes, through the one-byte USDO codes and back.
    let e = net.node(5).sdo().read::<u32>(0x2100, 0).await.unwrap_err();
    match e {
        NetError::Sdo(s) => assert_eq!(s.kind, SdoErrorKind::Server(AbortCode::NO_OBJECT)),
        other => panic!("{other:?}"),
    }
    let e = net.node(5).sdo().write(0x1000, 0, 1u32).await.unwrap_err();
    assert_eq!(e.abort_code(), Some(AbortCode::READ_ONLY));
    net.close().await;
    s.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn transfers_to_several_nodes_at_once_take_turns() {
    let bus = MemBus::new("fd");
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let mut stations = Vec::new();
    for id in 1..=4 {
        stations.push(fd_node(&bus, id).await);
    }
    let mut tasks = Vec::new();
    for id in (1..=4).chain([2; 3]) {
        let node = net.node(id);
        tasks.push(tokio::spawn(async move {
            (id, node.sdo().read::<u32>(0x1018, 2).await)
        }));
    }
    for t in tasks {
        let (id, r) = t.await.unwrap();
        assert_eq!(r.unwrap(), u32::from(id));
    }
    net.close().await;
    for s in stations {
        s.shutdown().await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_classic_node_on_the_fd_network_does_not_answer_usdo() {
    // What "every node must serve USDO" means: a node without `NodeConfig::fd` is silent.
    let bus = MemBus::new("fd");
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let s = Runtime::new(Station::new(SinglePort::fd(), sdo_node(7, false, 0, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    s.boot().await.unwrap();
    let e = net.node(7).sdo().read::<u32>(0x1018, 2).await.unwrap_err();
    assert!(e.is_no_answer(), "{e:?}");
    net.close().await;
    s.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn streams_go_whole_over_usdo() {
    let bus = MemBus::new("fd");
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let s = fd_node(&bus, 6).await;
    let sdo = net.node(6).sdo();
    let blob = pattern(2500, 3);
    let mut told = Vec::new();
    let n = sdo
        .write_from(0x2002, 0, &blob[..], Some(2500), |p| told.push(p.done))
        .await
        .unwrap();
    assert_eq!((n, told), (2500, vec![2500]));
    assert_eq!(s.read(0x2002, 0).await.unwrap(), blob);
    let mut back = Vec::new();
    assert_eq!(
        sdo.read_to(0x2002, 0, &mut back, |_| {}).await.unwrap(),
        2500
    );
    assert_eq!(back, blob);
    // Without a size: up to the input's end. A size the input does not reach is an I/O error;
    // more than the door's limit is refused before anything is sent.
    let n = sdo.write_from(0x2002, 0, &blob[..100], None, |_| {}).await;
    assert_eq!(n.unwrap(), 100);
    let e = sdo
        .write_from(0x2002, 0, &blob[..10], Some(20), |_| {})
        .await
        .unwrap_err();
    assert!(matches!(e, NetError::Io { .. }), "{e:?}");
    let big = duocan::net::MAX_TRANSFER as u64 + 1;
    let e = sdo
        .write_from(0x2002, 0, tokio::io::empty(), Some(big), |_| {})
        .await
        .unwrap_err();
    match e {
        NetError::Sdo(e) => assert!(matches!(e.kind, SdoErrorKind::TooLong { .. }), "{e:?}"),
        other => panic!("{other:?}"),
    }
    assert_eq!(s.read(0x2002, 0).await.unwrap(), &blob[..100]);
    net.close().await;
    s.shutdown().await;
}

/// Node `id` on the FD network whose TPDO1 (0x180 + id, type 254, event timer 20 ms) maps eight
/// UNSIGNED64 entries: 64 bytes in every CAN FD frame.
async fn fd_tpdo_node(bus: &MemBus, id: u8) -> Handle<FdStation> {
    use duocan::od::{comm, Access, DataType, ObjectDef};
    use duocan::pdo::params;
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    let values: Vec<ObjectDef> = (0..8)
        .map(|i| {
            ObjectDef::new(0x6100 + i, 0, DataType::Unsigned64)
                .mappable()
                .access(Access::Rw)
                .default(duocan::od::DefaultValue::Unsigned(u64::MAX - u64::from(i)))
        })
        .collect();
    od.insert_all(&values).unwrap();
    od.insert_all(&params::tpdo_comm(
        1,
        params::predefined_tpdo_cob(1),
        254,
        0,
        20,
    ))
    .unwrap();
    let entries: Vec<u32> = (0..8).map(|i| (0x6100 + i) << 16 | 64).collect();
    od.insert_all(&params::tpdo_mapping::<9>(1, &entries))
        .unwrap();
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_64_byte_tpdo_in_can_fd_frames_is_decoded_by_the_door() {
    use duocan::net::{AnyValue, NetEvent};
    let bus = MemBus::new("fd-pdo");
    let net = Network::open_with(bus.port(), fd_options()).unwrap();
    let _s = fd_tpdo_node(&bus, 5).await;
    let mut events = net.events();
    // The mapping is read over USDO (the network learns it), then its frames are decoded.
    let map = net.node(5).tpdo(1).read().await.unwrap();
    assert_eq!(map.bits(), 512);
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
    assert_eq!((got.0, got.1), (NodeId::must(5), 1));
    let v: Vec<AnyValue> = got.2.iter().map(|p| p.value.clone()).collect();
    let want: Vec<AnyValue> = (0..8).map(|i| AnyValue::Unsigned(u64::MAX - i)).collect();
    assert_eq!(v, want);
}
