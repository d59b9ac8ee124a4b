//! SDO through a remote node: exact values, strings, domains, errors, concurrency.

use crate::rt::{pattern, sdo_node, single};
use duocan::net::{NetError, NetOptions, Network, SIM_DEVICE_NAME, SIM_VENDOR};
use duocan::port::mem::MemBus;
use duocan::runtime::Runtime;
use duocan::sdo::{SdoErrorKind, TransferMode};
use duocan::AbortCode;
use std::time::Duration;

fn quick() -> NetOptions {
    NetOptions::default().with_sdo_timeout(Duration::from_millis(100))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn typed_values_and_strings_from_a_simulated_node() {
    let net = Network::simulated([5], quick()).unwrap();
    let node = net.node(5);
    assert_eq!(node.sdo().read::<u32>(0x1018, 1).await.unwrap(), SIM_VENDOR);
    assert_eq!(
        node.sdo().read::<u32>(0x1018, 2).await.unwrap(),
        5,
        "product = node-ID"
    );
    assert_eq!(node.sdo().read::<u8>(0x1018, 0).await.unwrap(), 4);
    assert_eq!(
        node.sdo().read_string(0x1008, 0).await.unwrap(),
        SIM_DEVICE_NAME
    );
    node.sdo().write(0x1017, 0, 250u16).await.unwrap();
    assert_eq!(node.sdo().read::<u16>(0x1017, 0).await.unwrap(), 250);
    // A type of the wrong size is an error naming node, object and both sizes.
    let e = node.sdo().read::<u16>(0x1018, 1).await.unwrap_err();
    assert_eq!(
        e,
        NetError::WrongSize {
            node: duocan::NodeId::new(5).unwrap(),
            index: 0x1018,
            sub: 1,
            expected: 2,
            got: 4
        }
    );
    assert!(e.to_string().contains("node 5, object 0x1018 sub 1"), "{e}");
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_that_does_not_answer_is_a_timeout_error_naming_it() {
    let net = Network::simulated([5], quick()).unwrap();
    let started = std::time::Instant::now();
    let e = net.node(9).sdo().read::<u32>(0x1018, 1).await.unwrap_err();
    let took = started.elapsed();
    assert!(e.is_no_answer(), "{e:?}");
    assert_eq!(e.node().map(|n| n.raw()), Some(9));
    assert_eq!(e.abort_code(), Some(AbortCode::TIMEOUT));
    match &e {
        NetError::Sdo(s) => assert_eq!((s.index, s.sub), (0x1018, 1)),
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("node 9"), "{e}");
    // The configured 100 ms, not the default second.
    assert!(
        took >= Duration::from_millis(100) && took < Duration::from_millis(900),
        "{took:?}"
    );
    // The node's refusal is the node's abort code.
    let e = net.node(5).sdo().read::<u32>(0x2100, 0).await.unwrap_err();
    assert_eq!(e.abort_code(), Some(AbortCode::NO_OBJECT));
    match e {
        NetError::Sdo(s) => assert_eq!(s.kind, SdoErrorKind::Server(AbortCode::NO_OBJECT)),
        other => panic!("{other:?}"),
    }
    // Bad input is an error value, not a panic.
    assert_eq!(
        net.node(0).sdo().read::<u8>(0x1000, 0).await.unwrap_err(),
        NetError::NoSuchNode(0)
    );
    assert_eq!(
        net.node(200).state().await.unwrap_err(),
        NetError::NoSuchNode(200)
    );
    net.close().await;
    assert_eq!(
        net.node(5).sdo().read::<u32>(0x1018, 1).await.unwrap_err(),
        NetError::Closed
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn domains_in_every_mode() {
    let bus = MemBus::new("mem");
    let net = Network::open_with(bus.port(), quick()).unwrap();
    let s = Runtime::new(single(sdo_node(6, false, 0, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    s.boot().await.unwrap();
    let sdo = net.node(6).sdo();
    let blob = pattern(3000, 7);
    sdo.clone()
        .with_mode(TransferMode::Block)
        .write_bytes(0x2002, 0, blob.clone())
        .await
        .unwrap();
    assert_eq!(s.read(0x2002, 0).await.unwrap(), blob, "the node holds it");
    assert_eq!(sdo.read_bytes(0x2002, 0).await.unwrap(), blob);
    sdo.clone()
        .with_mode(TransferMode::Segmented)
        .write_string(0x2001, 0, "written through the front door")
        .await
        .unwrap();
    assert_eq!(
        sdo.read_string(0x2001, 0).await.unwrap(),
        "written through the front door"
    );
    // Not UTF-8 is an error naming the object, the bytes are still readable.
    sdo.write_bytes(0x2001, 0, vec![0xff, 0xfe]).await.unwrap();
    assert!(matches!(
        sdo.read_string(0x2001, 0).await,
        Err(NetError::NotText {
            index: 0x2001,
            sub: 0,
            ..
        })
    ));
    assert_eq!(sdo.read_bytes(0x2001, 0).await.unwrap(), [0xff, 0xfe]);
    net.close().await;
    s.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn many_nodes_at_once_and_one_node_many_times() {
    let net = Network::simulated(1..=10, quick()).unwrap();
    // Ten nodes at once (more than the client's eight sessions) and six reads of node 5 at
    // once: none fails with "busy" or "no session", each gets its own node's value.
    let mut tasks = Vec::new();
    for id in (1..=10).chain([5; 6]) {
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
}
