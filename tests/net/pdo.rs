//! PDOs through the front door on the simulated network: configuration read over SDO, a remap
//! saved in CiA 301's order and then decoded, RPDOs sent, the SYNC producer, EMCY.

use duocan::net::{sim_description, AnyValue, Events, NetError, NetOptions, Network, PdoValues};
use duocan::od::DataType;
use duocan::pdo::Dir;
use duocan::port::mem::MemBus;
use duocan::port::{Port, PortInput};
use duocan::{CobId, Id, NmtState};
use std::time::Duration;

fn quick() -> NetOptions {
    NetOptions::default().with_sdo_timeout(Duration::from_millis(300))
}

const T: Duration = Duration::from_secs(2);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_nodes_pdo_configuration_is_read_with_names() {
    let net = Network::simulated([5], quick()).unwrap();
    let node = net.add_node(5, sim_description().unwrap());
    let t1 = node.tpdo(1).read().await.unwrap();
    assert_eq!((t1.dir, t1.pdo), (Dir::Transmit, 1));
    assert_eq!(t1.cob_id, CobId(0x185));
    assert!(t1.enabled);
    assert_eq!(t1.transmission_type, 254);
    assert_eq!(
        (t1.inhibit_100us, t1.event_timer_ms, t1.sync_start),
        (Some(0), Some(0), Some(0))
    );
    let names: Vec<_> = t1.entries.iter().map(|e| e.name.as_deref()).collect();
    assert_eq!(names, [Some("Input 1"), Some("Status")]);
    assert_eq!(
        t1.entries
            .iter()
            .map(|e| (e.index, e.sub, e.bits, e.data_type))
            .collect::<Vec<_>>(),
        [
            (0x6000, 1, 16, Some(DataType::Unsigned16)),
            (0x6000, 3, 8, Some(DataType::Unsigned8))
        ]
    );
    let r1 = node.rpdo(1).read().await.unwrap();
    assert_eq!((r1.cob_id, r1.transmission_type), (CobId(0x205), 255));
    assert_eq!(
        (r1.inhibit_100us, r1.event_timer_ms, r1.sync_start),
        (None, Some(0), None),
        "an RPDO has neither inhibit time nor SYNC start"
    );
    assert_eq!(r1.entries[1].name.as_deref(), Some("Output 2"));
    let t2 = node.tpdo(2).read().await.unwrap();
    assert!(!t2.enabled && t2.entries.is_empty());
    assert_eq!(t2.cob_id, CobId(0x8000_0285));

    // All of them: the four each way the description has.
    let all = node.read_pdos(Dir::Transmit).await.unwrap();
    assert_eq!(all.iter().map(|m| m.pdo).collect::<Vec<_>>(), [1, 2, 3, 4]);
    assert_eq!(all[0], t1);
    // Without a description: up to the first the node does not have, unnamed.
    let net7 = Network::simulated([7], quick()).unwrap();
    let all = net7.node(7).read_pdos(Dir::Receive).await.unwrap();
    assert_eq!(all.len(), 4);
    assert_eq!(all[0].entries[1].name, None);
    assert_eq!(
        all[0].entries[1].entry(),
        duocan::pdo::MapEntry::new(0x6200, 2, 8)
    );
    assert!(
        net.node(6).tpdo(1).read().await.is_err(),
        "node 6 is not on this bus"
    );
    assert_eq!(net.dropped_pdos().await.unwrap(), 0);
    net7.close().await;
    for n in [0, 513] {
        let e = node.tpdo(n).read().await.unwrap_err();
        assert_eq!(
            e,
            NetError::NoSuchPdo {
                node: duocan::NodeId::must(5),
                pdo: n
            }
        );
    }
    net.close().await;
}

/// (command byte, index, sub, value) of every SDO request to node 5 on the wire.
async fn sdo_requests(wire: &mut impl Port) -> Vec<(u8, u16, u8, u32)> {
    let mut out = Vec::new();
    while let Ok(Ok(PortInput::Frame(f, _))) =
        tokio::time::timeout(Duration::from_millis(100), wire.recv()).await
    {
        let d = f.data();
        if f.id() == Id::Standard(0x605) && d.len() == 8 {
            let v = u32::from_le_bytes([d[4], d[5], d[6], d[7]]);
            out.push((d[0], u16::from_le_bytes([d[1], d[2]]), d[3], v));
        }
    }
    out
}

// Paused time: the runtime's clock is tokio's, so the periods come out exact.
#[tokio::test(flavor = "current_thread", start_paused = true)]
async fn a_remap_is_saved_in_order_and_its_pdos_arrive_decoded() {
    let bus = MemBus::new("pdo");
    let mut wire = bus.port();
    let net = Network::simulated_on(&bus, [5], quick()).unwrap();
    let node = net.add_node(5, sim_description().unwrap());
    let sdo = node.sdo();
    let mut t1 = node.tpdo(1).read().await.unwrap();
    sdo_requests(&mut wire).await;
    t1.clear();
    t1.add_variable("Input 2").unwrap();
    t1.add_variable("input 1").unwrap();
    t1.add_variable("Status").unwrap();
    t1.event_timer_ms = Some(40);
    node.tpdo(1).save(&t1).await.unwrap();

    // On the wire: read the COB-ID, disable, parameters, mapping count 0, entries, count,
    // enable (expedited downloads of 1, 2 and 4 bytes: 0x2F, 0x2B, 0x23; an upload: 0x40).
    let log = sdo_requests(&mut wire).await;
    let w8 = |i, s, v| (0x2F, i, s, v);
    let w16 = |i, s, v| (0x2B, i, s, v);
    let w32 = |i, s, v| (0x23, i, s, v);
    assert_eq!(
        log,
        [
            (0x40, 0x1800, 1, 0),
            w32(0x1800, 1, 0x8000_0185),
            w8(0x1800, 2, 254),
            w16(0x1800, 3, 0),
            w16(0x1800, 5, 40),
            w8(0x1800, 6, 0),
            w8(0x1A00, 0, 0),
            w32(0x1A00, 1, 0x6000_0210),
            w32(0x1A00, 2, 0x6000_0110),
            w32(0x1A00, 3, 0x6000_0308),
            w8(0x1A00, 0, 3),
            w32(0x1800, 1, 0x185),
        ]
    );
    // The node holds it (read back over SDO).
    assert_eq!(node.tpdo(1).read().await.unwrap(), t1);
    assert_eq!(sdo.read::<u8>(0x1A00, 0).await.unwrap(), 3);

    sdo.write_value("Input 2", -5i16).await.unwrap();
    sdo.write_value("Input 1", 1000u16).await.unwrap();
    sdo.write_value("Status", 7u8).await.unwrap();
    node.start().await.unwrap();
    let v = node.wait_for_pdo(1, T).await.unwrap();
    assert_eq!(v.len(), 3);
    assert_eq!(v.get("Input 2"), Some(&AnyValue::Signed(-5)));
    assert_eq!(v.get("INPUT 1"), Some(&AnyValue::Unsigned(1000)));
    assert_eq!(v.at(0x6000, 3), Some(&AnyValue::Unsigned(7)));
    assert_eq!(v[0].name.as_deref(), Some("Input 2"), "in mapping order");

    // The same PDO on the event stream, at the event timer's period.
    let mut events = net.events();
    for (values, _) in pdos(&mut events, 5, 1, 4, Duration::from_millis(40)).await {
        assert_eq!(values, v);
    }

    // A mapping beyond 64 bits is refused before anything is sent.
    let mut long = t1.clone();
    long.add_variable("Input 2").unwrap();
    let e = long.add_variable("Input 1").unwrap_err();
    assert!(e.to_string().contains("at most 64 bits (it has 56)"), "{e}");
    assert_eq!(long.bits(), 56);
    net.close().await;
}

/// The next `n` TPDOs `pdo` of node `node` on the stream, asserting they came exactly
/// `period` apart (paused time).
async fn pdos(
    events: &mut Events,
    node: u8,
    pdo: u16,
    n: usize,
    period: Duration,
) -> Vec<(PdoValues, duocan::Instant)> {
    let mut got: Vec<(PdoValues, duocan::Instant)> = Vec::new();
    while got.len() < n {
        let e = tokio::time::timeout(T, events.next()).await.unwrap();
        let e = e.expect("the stream goes on");
        if let (Some((id, k, values)), Some(at)) = (e.pdo(), e.at()) {
            if (id.raw(), k) == (node, pdo) {
                if let Some((_, last)) = got.last() {
                    let gap = at.saturating_since(*last).as_micros();
                    assert_eq!(u128::from(gap), period.as_micros(), "PDO {pdo} period");
                }
                got.push((values.clone(), at));
            }
        }
    }
    got
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_rpdo_sent_changes_the_nodes_dictionary() {
    let net = Network::simulated([5], quick()).unwrap();
    let node = net.add_node(5, sim_description().unwrap());
    let r1 = node.rpdo(1);
    // A mapping not known yet is read from the node, then the RPDO goes out (a
    // pre-operational node does not apply it).
    r1.send(&[1u16.into(), 2i8.into()]).await.unwrap();
    assert_eq!(node.sdo().read::<u16>(0x6200, 1).await.unwrap(), 0);
    // A disabled RPDO is read too, and stays unknown: the error says why.
    let e = node.rpdo(2).send(&[]).await.unwrap_err();
    assert!(e.to_string().contains("disabled on the node"), "{e}");
    node.start().await.unwrap();
    node.wait_for_state(NmtState::Operational, T).await.unwrap();
    r1.send(&[1234u16.into(), (-3i8).into()]).await.unwrap();
    assert_eq!(node.sdo().read::<u16>(0x6200, 1).await.unwrap(), 1234);
    assert_eq!(
        node.sdo().read_value("Output 2").await.unwrap(),
        AnyValue::Signed(-3)
    );

    let e = r1.send(&[1u16.into()]).await.unwrap_err();
    assert!(
        matches!(e, NetError::BadValue { .. }) && e.to_string().contains("2 value(s)"),
        "{e}"
    );
    let e = r1.send(&[70000u32.into(), 0i8.into()]).await.unwrap_err();
    assert!(e.to_string().contains("\"Output 1\""), "{e}");
    let e = node.tpdo(1).send(&[]).await.unwrap_err();
    assert!(e.to_string().contains("use node.rpdo(n)"), "{e}");
    assert_eq!(
        node.sdo().read::<u16>(0x6200, 1).await.unwrap(),
        1234,
        "nothing else arrived"
    );

    // By name: the others keep the value last sent (python's `rpdo[1]["Output 2"].raw = 5`).
    r1.send_named(&[("output 2", 5i8.into())]).await.unwrap();
    assert_eq!(node.sdo().read::<u16>(0x6200, 1).await.unwrap(), 1234);
    assert_eq!(node.sdo().read::<i8>(0x6200, 2).await.unwrap(), 5);
    let e = r1
        .send_named(&[("Output 3", 1u8.into())])
        .await
        .unwrap_err();
    assert!(e.to_string().contains("\"Output 1\", \"Output 2\""), "{e}");

    // A mapping given rather than read: RPDO 2 remapped onto Output 1 alone.
    let r2 = node.rpdo(2);
    let mut m = r2.read().await.unwrap();
    m.enabled = true;
    m.clear().add_variable("Output 1").unwrap();
    r2.save(&m).await.unwrap();
    r2.send(&[4321u16.into()]).await.unwrap();
    assert_eq!(node.sdo().read::<u16>(0x6200, 1).await.unwrap(), 4321);

    // Enabled without a COB-ID of its own, a PDO would sit on 0x000 (NMT): refused.
    let mut blank = node.rpdo(3).blank().unwrap();
    blank.enabled = true;
    let e = node.rpdo(3).save(&blank).await.unwrap_err();
    assert!(e.to_string().contains("reserved for other services"), "{e}");
    let e = node.rpdo(3).learn(&blank).await.unwrap_err();
    assert!(matches!(e, NetError::Pdo { .. }), "{e:?}");
    // A map saved on another PDO than its own is refused.
    let e = node.rpdo(3).save(&m).await.unwrap_err();
    assert!(matches!(e, NetError::Argument(_)), "{e:?}");
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_monitor_sends_neither_sync_nor_rpdos() {
    let bus = MemBus::new("mon");
    let net = Network::monitor(bus.port()).unwrap();
    let e = net.start_sync(Duration::from_millis(10)).await.unwrap_err();
    assert_eq!(e, NetError::ListenOnly { node: None });
    let r1 = net.node(5).rpdo(1);
    let mut m = r1.blank().unwrap();
    m.cob_id = CobId(0x205);
    m.enabled = true;
    m.add(0x6200, 1, 16).unwrap();
    r1.learn(&m).await.unwrap();
    let e = r1.send(&[1u16.into()]).await.unwrap_err();
    assert!(matches!(e, NetError::ListenOnly { .. }), "{e:?}");
    net.close().await;
}

#[tokio::test(flavor = "current_thread", start_paused = true)]
async fn sync_producer_drives_synchronous_tpdos() {
    let net = Network::simulated([5], quick()).unwrap();
    let node = net.add_node(5, sim_description().unwrap());
    let t2 = node.tpdo(2);
    let mut m = t2.read().await.unwrap();
    m.enabled = true;
    m.transmission_type = 1; // every SYNC
    m.clear().add_variable("Status").unwrap();
    t2.save(&m).await.unwrap();
    node.sdo().write_named("Status", 9u8).await.unwrap();
    node.start().await.unwrap();
    node.wait_for_state(NmtState::Operational, T).await.unwrap();
    let e = t2.wait(Duration::from_millis(200)).await.unwrap_err();
    assert!(
        matches!(e, NetError::Timeout { .. }),
        "no SYNC, no TPDO 2: {e:?}"
    );
    assert!(e.to_string().contains("SYNC producer"), "{e}");

    let mut events = net.events();
    net.start_sync(Duration::from_millis(50)).await.unwrap();
    for (values, _) in pdos(&mut events, 5, 2, 5, Duration::from_millis(50)).await {
        assert_eq!(values.get("Status"), Some(&AnyValue::Unsigned(9)));
    }
    net.stop_sync().await.unwrap();
    tokio::time::sleep(Duration::from_millis(60)).await;
    assert!(
        t2.wait(Duration::from_millis(200)).await.is_err(),
        "SYNC stopped"
    );
    let e = net.start_sync(Duration::ZERO).await.unwrap_err();
    assert!(matches!(e, NetError::Argument(_)), "{e:?}");
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_rpdo_timeout_arrives_as_an_emcy_event() {
    let net = Network::simulated([5], quick()).unwrap();
    let node = net.add_node(5, sim_description().unwrap());
    let r1 = node.rpdo(1);
    let mut m = r1.read().await.unwrap();
    m.event_timer_ms = Some(100); // reception timeout
    r1.save(&m).await.unwrap();
    node.start().await.unwrap();
    node.wait_for_state(NmtState::Operational, T).await.unwrap();
    let mut events = net.events();
    r1.send(&[1u16.into(), 1i8.into()]).await.unwrap();
    let m = node.wait_for_emcy(T).await.unwrap();
    assert_eq!(m.code, duocan::emcy::code::RPDO_TIMEOUT);
    assert_eq!(m.text(), "RPDO timeout");
    assert_ne!(m.register & duocan::emcy::register::COMMUNICATION, 0);
    // The same message on the event stream, easy to match.
    loop {
        let e = tokio::time::timeout(T, events.next())
            .await
            .unwrap()
            .unwrap();
        if let Some((n, msg)) = e.emcy() {
            assert_eq!((n.raw(), msg), (5, m));
            break;
        }
    }
    net.close().await;
}
