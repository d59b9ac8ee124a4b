//! Listen-only: the monitor hears everything and puts nothing on the bus.

use crate::rt::{node, single};
use duocan::net::{NetError, Network};
use duocan::port::mem::MemBus;
use duocan::port::{Port, PortInput};
use duocan::runtime::Runtime;
use duocan::{NmtState, NodeId};
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_monitor_hears_states_and_sends_nothing() {
    let bus = MemBus::new("mem");
    let mut wire = bus.port();
    let net = Network::monitor(bus.port()).unwrap();
    assert!(net.is_listen_only());
    let s = Runtime::new(single(node(2, false, 50, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    // Made before the node boots, so its boot-up counts for the wait below.
    let n2 = net.node(2);
    s.boot().await.unwrap();
    n2.watch_heartbeat(Duration::from_millis(200))
        .await
        .unwrap();
    n2.wait_for_boot_up(Duration::from_secs(2)).await.unwrap();
    n2.wait_for_state(NmtState::PreOperational, Duration::from_secs(2))
        .await
        .unwrap();
    // Whatever the user asks, nothing is sent: an error, not a frame.
    let two = Some(NodeId::new(2).unwrap());
    assert_eq!(
        n2.start().await.unwrap_err(),
        NetError::ListenOnly { node: two }
    );
    assert_eq!(
        n2.sdo().read::<u32>(0x1018, 1).await.unwrap_err(),
        NetError::ListenOnly { node: two }
    );
    assert_eq!(
        net.nmt_all(duocan::NmtCommand::ResetNode)
            .await
            .unwrap_err(),
        NetError::ListenOnly { node: None }
    );
    // An NMT command from someone else does not make the monitor answer either: the node
    // obeys it, the monitor follows its state, and every frame on the wire is node 2's.
    let mut master = bus.port();
    master
        .send(&duocan::Frame::from_array(duocan::Id::Standard(0), [1, 0]))
        .await
        .unwrap();
    n2.wait_for_state(NmtState::Operational, Duration::from_secs(2))
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut ids = Vec::new();
    while let Ok(Ok(PortInput::Frame(f, _))) =
        tokio::time::timeout(Duration::from_millis(50), wire.recv()).await
    {
        ids.push(f.id());
    }
    assert!(ids.len() >= 5, "heartbeats went by: {ids:?}");
    let foreign: Vec<_> = ids
        .iter()
        .filter(|id| **id != duocan::Id::Standard(0x702) && **id != duocan::Id::Standard(0))
        .collect();
    assert!(
        foreign.is_empty(),
        "only node 2 and the NMT command: {foreign:?}"
    );
    net.close().await;
    s.shutdown().await;
}

/// A tap on the network's port: told of the frames the port receives and sends.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tap_hears_what_the_port_receives_and_sends() {
    use duocan::capture::recorder::{Tap, TapDirection, TapPoint};
    use duocan::net::NetOptions;
    use std::sync::{Arc, Mutex};

    #[derive(Default)]
    struct Seen(Mutex<Vec<(TapDirection, u16)>>);
    impl Tap for Seen {
        fn frame(&self, _: duocan::Instant, _: TapPoint, dir: TapDirection, f: &duocan::Frame) {
            if let duocan::Id::Standard(id) = f.id() {
                self.0.lock().unwrap().push((dir, id));
            }
        }
    }
    let seen = Arc::new(Seen::default());
    let net = Network::simulated(
        [5],
        NetOptions::default().with_tap(seen.clone() as Arc<dyn Tap>),
    )
    .unwrap();
    let v: u32 = net.node(5).sdo().read(0x1018, 1).await.unwrap();
    assert_eq!(v, duocan::net::SIM_VENDOR);
    let seen = seen.0.lock().unwrap().clone();
    assert!(seen.contains(&(TapDirection::Tx, 0x605)), "{seen:?}");
    assert!(seen.contains(&(TapDirection::Rx, 0x585)), "{seen:?}");
    net.close().await;
}

/// The network's observer has a node-ID of its own inside (127) but is no node on the bus: a
/// device at 127 is heard as any other (its boot-up, heartbeat states and EMCY), and
/// answers SDO.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_node_at_127_is_heard_as_any_other() {
    let bus = MemBus::new("mem");
    let net = Network::open(bus.port()).unwrap();
    let s = Runtime::new(single(node(127, false, 50, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    let n = net.node(127);
    s.boot().await.unwrap();
    let t = Duration::from_secs(2);
    n.wait_for_boot_up(t).await.expect("boot-up of 127");
    n.wait_for_state(NmtState::PreOperational, t)
        .await
        .expect("127's heartbeat");
    let vendor = n.sdo().read_bytes(0x1018, 1).await.expect("SDO to 127");
    assert_eq!(vendor, s.read(0x1018, 1).await.unwrap());
    let mut events = net.events();
    let mut raw = bus.port();
    raw.send(&duocan::Frame::from_array(
        duocan::Id::Standard(0xFF),
        [0x30, 0x81, 0x11, 0, 0, 0, 0, 0],
    ))
    .await
    .unwrap();
    let emcy = tokio::time::timeout(t, async {
        loop {
            match events.next().await {
                Some(e) => match e.emcy() {
                    Some((node, m)) if node.raw() == 127 => return m,
                    _ => {}
                },
                None => panic!("the event stream ended"),
            }
        }
    })
    .await
    .expect("127's EMCY");
    assert_eq!(emcy.code, 0x8130);
    net.close().await;
    s.shutdown().await;
}
