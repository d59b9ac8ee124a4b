//! python `canopen` / python-can as an independent peer on the udp_multicast bus.
//!
//! Needs a private network namespace with loopback multicast and `DUOCAN_PYTHON` pointing at a
//! python with `python-can`, `canopen` and `msgpack`: `.ci/tier-python.sh` sets up both.

#[path = "common/peer.rs"]
mod peer;
#[path = "../../tests/common/runtime.rs"]
mod rt;

use duocan::node::NodeEventKind as K;
use duocan::port::udp::{encode, UdpBusConfig, UdpPort};
use duocan::port::{AnyInput, Port, PortInput};
use duocan::runtime::Runtime;
use duocan::sdo::{SdoErrorKind, SdoOptions, TransferMode};
use duocan::AbortCode;
use duocan::{FdFrame, Frame, Id, NmtCommand, NmtState, NmtTarget, NodeId};
use peer::{group, Peer};
use rt::{node, node_event, pattern, sdo_error, single, wait_for};
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_node_heartbeat_is_consumed_and_duocan_nmt_drives_it() {
    let cfg = UdpBusConfig::numbered(0);
    let master = Runtime::new(single(node(1, true, 0, &[(0x22, 500)])))
        .name("master")
        .port(UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)"))
        .spawn()
        .unwrap();
    let mut ev = master.subscribe();
    master.boot().await.unwrap();
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["node", "0x22", "100", &g, &p]).await;
    peer.expect("STATE PRE-OPERATIONAL", 10).await;
    wait_for(&mut ev, 10, "python boot-up", |e| match node_event(e) {
        Some(K::BootUp { node }) if node.raw() == 0x22 => Some(()),
        _ => None,
    })
    .await;
    wait_for(
        &mut ev,
        5,
        "python heartbeat pre-operational",
        |e| match node_event(e) {
            Some(K::RemoteState {
                node,
                to: NmtState::PreOperational,
                ..
            }) if node.raw() == 0x22 => Some(()),
            _ => None,
        },
    )
    .await;

    let target = NmtTarget::Node(NodeId::new(0x22).unwrap());
    for (cmd, py, st) in [
        (
            NmtCommand::Start,
            "STATE OPERATIONAL",
            NmtState::Operational,
        ),
        (NmtCommand::Stop, "STATE STOPPED", NmtState::Stopped),
        (
            NmtCommand::EnterPreOperational,
            "STATE PRE-OPERATIONAL",
            NmtState::PreOperational,
        ),
    ] {
        master.nmt(cmd, target).await.unwrap();
        peer.expect(py, 5).await;
        wait_for(
            &mut ev,
            5,
            "python heartbeat with the new state",
            |e| match node_event(e) {
                Some(K::RemoteState { node, to, .. }) if node.raw() == 0x22 && to == st => Some(()),
                _ => None,
            },
        )
        .await;
    }
    // NMT to another node-ID leaves it alone; broadcast start reaches it.
    master
        .nmt(
            NmtCommand::Start,
            NmtTarget::Node(NodeId::new(0x23).unwrap()),
        )
        .await
        .unwrap();
    master.nmt(NmtCommand::Start, NmtTarget::All).await.unwrap();
    let l = peer.expect("STATE", 5).await;
    assert_eq!(
        l, "STATE OPERATIONAL",
        "only the broadcast changed the state"
    );

    // The peer goes away: the consumer times out 500 ms after its last heartbeat.
    peer.stop().await;
    wait_for(
        &mut ev,
        5,
        "heartbeat timeout of 0x22",
        |e| match node_event(e) {
            Some(K::HeartbeatTimeout { node, .. }) if node.raw() == 0x22 => Some(()),
            _ => None,
        },
    )
    .await;
    assert_eq!(master.port_counters(0).unwrap().rx_invalid, 0);
    master.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_datagrams_are_counted_and_the_runtime_keeps_going() {
    let cfg = UdpBusConfig::numbered(1);
    let mut port = UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let counters = port.counters();
    // Raw junk from a plain socket: not msgpack, truncated, a map with wrong types, bad DLC.
    let junk = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let good = encode(&Frame::from_array(Id::Standard(0x181), [1, 2]), 0.0, None);
    let mut wrong_type = good.clone();
    let i = wrong_type.windows(3).position(|w| w == b"dlc").unwrap();
    wrong_type[i + 3] = 0xc3; // dlc: true
    let datagrams: Vec<Vec<u8>> = vec![
        b"definitely not msgpack".to_vec(),
        good[..good.len() / 2].to_vec(),
        vec![0x92, 0x01, 0x02],
        wrong_type,
        vec![],
    ];
    for d in &datagrams {
        junk.send_to(d, (cfg.group, cfg.port)).unwrap();
    }
    junk.send_to(&good, (cfg.group, cfg.port)).unwrap();
    let got = tokio::time::timeout(Duration::from_secs(5), port.recv())
        .await
        .expect("the good frame arrives")
        .unwrap();
    assert!(
        matches!(got, PortInput::Frame(f, Some(_)) if f == Frame::from_array(Id::Standard(0x181), [1, 2])),
        "{got:?}"
    );
    assert_eq!(counters.snapshot().rx_invalid, datagrams.len() as u64);

    // python-can's own CAN FD and error frames, then a good frame, into a running runtime.
    let master = Runtime::new(single(node(1, true, 0, &[])))
        .port(port)
        .spawn()
        .unwrap();
    master.boot().await.unwrap();
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["junk", &g, &p]).await;
    peer.expect("SENT 2", 10).await;
    tokio::time::timeout(Duration::from_secs(5), async {
        while master.port_counters(0).unwrap().rx_frames < 2 {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    })
    .await
    .expect("the good python frame arrived");
    assert_eq!(
        master.port_counters(0).unwrap().rx_invalid,
        datagrams.len() as u64 + 2
    );
    assert_eq!(
        master.nmt_state().await.unwrap(),
        NmtState::Operational,
        "runtime still answers"
    );
    peer.stop().await;
    master.shutdown().await;
}

/// python-can (`fd=True`) and a duocan UDP port opened for CAN FD exchange CAN FD frames both
/// ways: identifiers, lengths up to 64, bytes, BRS and ESI all arrive as sent.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_can_and_duocan_exchange_can_fd_frames() {
    let cfg = UdpBusConfig::numbered(41).with_fd();
    let mut port = UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["fd", &g, &p]).await;
    peer.send_line("go").await;
    peer.expect("SENT 5", 10).await;
    let mut got = Vec::new();
    while got.len() < 5 {
        let x = tokio::time::timeout(Duration::from_secs(5), port.recv_any())
            .await
            .expect("python's frames arrive")
            .unwrap();
        match x {
            AnyInput::Fd(f, Some(_)) => got.push(Ok(f)),
            AnyInput::Frame(f, Some(_)) => got.push(Err(f)),
            other => panic!("unexpected {other:?}"),
        }
    }
    let fd = |id, data: &[u8]| FdFrame::new(id, data).unwrap();
    let series: Vec<u8> = (100..148).collect();
    let twelve: Vec<u8> = (0..12).collect();
    assert_eq!(
        got,
        [
            Ok(fd(Id::Standard(0x181), &twelve).with_brs(true)),
            Ok(fd(Id::Extended(0x001A_BCDE), &[0xA5; 64]).with_esi(true)),
            Ok(fd(Id::Standard(0x182), &series)
                .with_brs(true)
                .with_esi(true)),
            Ok(fd(Id::Standard(0x183), &[])),
            Err(Frame::from_array(Id::Standard(0x701), [0x05])),
        ]
    );
    assert_eq!(port.counters().snapshot().rx_invalid, 0);

    // duocan's FD frames (and a classic one) to python-can.
    let out = [
        fd(Id::Standard(0x281), &[0x11; 64]).with_brs(true),
        fd(
            Id::Extended(0x1234_5678),
            &[
                1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20,
            ],
        )
        .with_esi(true),
    ];
    for f in &out {
        port.send_fd(f).await.unwrap();
    }
    port.send(&Frame::from_array(Id::Standard(0x702), [0x7F]))
        .await
        .unwrap();
    assert_eq!(
        peer.expect("RX 281", 10).await,
        format!("RX 281 0 1 1 0 64 {}", "11".repeat(64))
    );
    assert_eq!(
        peer.expect("RX 12345678", 10).await,
        format!("RX 12345678 1 1 0 1 20 {}", hex(out[1].data()))
    );
    assert_eq!(peer.expect("RX 702", 10).await, "RX 702 0 0 0 0 1 7f");
    peer.stop().await;
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn duocan_sdo_client_against_a_python_local_node() {
    let cfg = UdpBusConfig::numbered(2);
    let m = Runtime::new(rt::master(1, &[]))
        .name("master")
        .port(UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)"))
        .spawn()
        .unwrap();
    m.boot().await.unwrap();
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["node", "0x22", "0", &g, &p]).await;
    peer.expect("STATE PRE-OPERATIONAL", 10).await;
    let py = NodeId::new(0x22).unwrap();
    let o = SdoOptions::default;

    // Expedited and segmented uploads.
    let v = m.sdo_read(py, 0x2000, 0, o()).await.unwrap();
    assert_eq!(v, 0x1234_5678u32.to_le_bytes());
    let v = m.sdo_read(py, 0x1018, 1, o()).await.unwrap();
    assert_eq!(v, 0xD0CAu32.to_le_bytes());
    let v = m.sdo_read(py, 0x2001, 0, o()).await.unwrap();
    assert_eq!(v, b"python canopen peer: a string longer than four bytes");

    // Expedited and segmented downloads: the python node reports what it stored.
    m.sdo_write(py, 0x2000, 0, 0xA5A5_0001u32.to_le_bytes().to_vec(), o())
        .await
        .unwrap();
    assert_eq!(peer.expect("WRITE 2000", 5).await, "WRITE 2000 0 0100a5a5");
    let text = b"segmented download from duocan to python".to_vec();
    m.sdo_write(
        py,
        0x2001,
        0,
        text.clone(),
        SdoOptions::mode(TransferMode::Segmented),
    )
    .await
    .unwrap();
    assert_eq!(
        peer.expect("WRITE 2001", 5).await,
        format!("WRITE 2001 0 {}", hex(&text))
    );

    // python canopen's server has no block transfer: block download falls back to segmented
    // (the server aborts with 0x05040001), block upload is answered as a plain upload.
    let blob = pattern(300, 3);
    m.sdo_write(
        py,
        0x2002,
        0,
        blob.clone(),
        SdoOptions::mode(TransferMode::Block),
    )
    .await
    .unwrap();
    assert_eq!(
        peer.expect("WRITE 2002", 5).await,
        format!("WRITE 2002 0 {}", hex(&blob))
    );
    let back = m
        .sdo_read(py, 0x2002, 0, SdoOptions::mode(TransferMode::Block))
        .await
        .unwrap();
    assert_eq!(back, blob);

    let e = sdo_error(m.sdo_read(py, 0x2100, 0, o()).await);
    assert_eq!(e.kind, SdoErrorKind::Server(AbortCode::NO_OBJECT));
    assert_eq!(m.port_counters(0).unwrap().rx_invalid, 0);
    peer.stop().await;
    m.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_sdo_client_reads_and_writes_a_duocan_node() {
    let cfg = UdpBusConfig::numbered(3);
    let d = Runtime::new(single(rt::sdo_node(0x33, false, 0, &[])))
        .name("duocan-slave")
        .port(UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)"))
        .spawn()
        .unwrap();
    d.boot().await.unwrap();
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["client", "0x33", &g, &p]).await;
    peer.send_line("go").await;
    assert_eq!(peer.expect("READ 1018", 10).await, "READ 1018 1 34120000");
    assert_eq!(
        peer.expect("READ 2001", 5).await,
        format!("READ 2001 0 {}", hex(b"duocan node over a real bus"))
    );
    peer.expect("WROTE 2000 0", 5).await;
    assert_eq!(
        d.read(0x2000, 0).await.unwrap(),
        0x1122_3344u32.to_le_bytes()
    );
    peer.expect("WROTE 2001 0", 5).await;
    assert_eq!(
        d.read(0x2001, 0).await.unwrap(),
        b"written by python canopen over segmented SDO"
    );
    // Block download and block upload, driven by python's client against duocan's server.
    peer.expect("WROTE 2002 0", 10).await;
    let blob = pattern(1000, 9);
    assert_eq!(d.read(0x2002, 0).await.unwrap(), blob);
    assert_eq!(
        peer.expect("READ 2002", 10).await,
        format!("READ 2002 0 {}", hex(&blob))
    );
    // Block transfers with `request_crc_support=False`: duocan's server sets the CRC bit, so
    // python sends a CRC on download and checks the end frame's CRC on upload; the upload fails
    // with "CRC is not OK" unless the end frame carries the real one.
    peer.send_line("go").await;
    peer.expect("WROTE-NO-CRC 2002 0", 10).await;
    let blob = pattern(700, 77);
    assert_eq!(d.read(0x2002, 0).await.unwrap(), blob);
    assert_eq!(
        peer.expect("READ-NO-CRC 2002", 10).await,
        format!("READ-NO-CRC 2002 0 {}", hex(&blob))
    );
    assert_eq!(peer.expect("ABORT", 5).await, "ABORT 2100 0 0x06020000");
    peer.expect("DONE", 5).await;
    assert_eq!(d.port_counters(0).unwrap().rx_invalid, 0);
    peer.stop().await;
    d.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_tpdo_is_consumed_by_a_duocan_rpdo() {
    use duocan::node::NodeEventKind;
    use duocan::pdo::PdoEvent;
    let cfg = UdpBusConfig::numbered(4);
    let mut n = node(1, true, 0, &[]);
    rt::add_rpdo1(&mut n, 0x180 + 0x22);
    let m = Runtime::new(single(n))
        .name("master")
        .port(UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)"))
        .spawn()
        .unwrap();
    let mut ev = m.subscribe();
    m.boot().await.unwrap();
    assert_eq!(m.nmt_state().await.unwrap(), NmtState::Operational);
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["node", "0x22", "0", &g, &p]).await;
    for value in [0x1234u16, 0xABCD] {
        peer.send_line(&format!("tpdo {value}")).await;
        peer.expect("TPDO", 5).await;
        wait_for(&mut ev, 5, "RPDO1 applied with the new value", |e| {
            matches!(
                node_event(e),
                Some(NodeEventKind::Pdo(PdoEvent::RpdoReceived { pdo: 1 }))
            )
            .then_some(())
        })
        .await;
        tokio::time::timeout(Duration::from_secs(5), async {
            loop {
                if m.read(0x2100, 0).await.unwrap() == value.to_le_bytes() {
                    return;
                }
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        })
        .await
        .unwrap_or_else(|_| panic!("0x2100 never became {value:#06x}"));
    }
    peer.stop().await;
    m.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_canopen_stores_and_restores_a_duocan_nodes_parameters() {
    use duocan::od::parameters::{MemoryStorage, StoredDictionary};
    use duocan::od::{comm, ObjectDictionary};
    use duocan::Station;
    let cfg = UdpBusConfig::numbered(5);
    let id = NodeId::must(0x34);
    let od = comm::standard_dictionary(id.raw(), comm::Identity::default());
    let mut n = duocan::Node::new(
        duocan::NodeConfig::slave(id),
        StoredDictionary::<_, _, 4096>::new(od, MemoryStorage::<4096>::new()),
    );
    // The application's configuration before boot: the power-on value of 0x1017.
    n.od_mut()
        .write_local(comm::HEARTBEAT_PRODUCER, 0, &1000u16.to_le_bytes())
        .unwrap();
    let d = Runtime::new(Station::single(n))
        .name("duocan-slave")
        .port(UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)"))
        .spawn()
        .unwrap();
    d.boot().await.unwrap();
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["storage", "0x34", &g, &p]).await;
    peer.send_line("go").await;
    assert_eq!(peer.expect("READ 1010", 5).await, "READ 1010 2 01000000");
    assert_eq!(peer.expect("ABORT", 5).await, "ABORT 1010 2 0x08000020");
    peer.expect("STORED", 5).await;
    peer.expect("BOOTED", 10).await;
    // Reset-node: the stored 300 ms, not the 1000 ms of the power-on image.
    assert_eq!(peer.expect("READ 1017", 5).await, "READ 1017 0 2c01");
    peer.expect("RESTORED", 5).await;
    assert_eq!(peer.expect("READ 1017", 5).await, "READ 1017 0 2c01");
    peer.expect("BOOTED", 10).await;
    // Reset-communication after the restore: the application's 1000 ms.
    assert_eq!(peer.expect("READ 1017", 5).await, "READ 1017 0 e803");
    peer.expect("DONE", 5).await;
    peer.stop().await;
    d.shutdown().await;
}
