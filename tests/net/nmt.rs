//! NMT through a remote node: commands, states from heartbeats, the waits and their rule.

use crate::rt::{node, single};
use duocan::net::{Awaited, NetError, NetEvent, NetOptions, Network};
use duocan::port::mem::MemBus;
use duocan::runtime::Runtime;
use duocan::{NmtState, NodeId};
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn commands_move_the_node_and_its_state_follows() {
    let net = Network::simulated([4, 5], NetOptions::default()).unwrap();
    let n5 = net.node(5);
    for id in [4, 5] {
        net.node(id)
            .wait_for_state(NmtState::PreOperational, Duration::from_secs(2))
            .await
            .unwrap();
    }
    assert_eq!(n5.state().await.unwrap(), Some(NmtState::PreOperational));
    assert_eq!(net.node(9).state().await.unwrap(), None, "never heard");
    n5.start().await.unwrap();
    n5.wait_for_state(NmtState::Operational, Duration::from_secs(2))
        .await
        .unwrap();
    assert_eq!(n5.state().await.unwrap(), Some(NmtState::Operational));
    // Already there: the wait returns at once. (Heartbeats that repeat a state are no news,
    // so a wait that only watched for changes would run into its 2 s timeout.)
    let t = std::time::Instant::now();
    n5.wait_for_state(NmtState::Operational, Duration::from_secs(2))
        .await
        .unwrap();
    assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
    // Node 4 was not addressed.
    assert_eq!(
        net.node(4).state().await.unwrap(),
        Some(NmtState::PreOperational)
    );
    n5.stop().await.unwrap();
    n5.wait_for_state(NmtState::Stopped, Duration::from_secs(2))
        .await
        .unwrap();
    // A state that does not come is a timeout naming node, state and time.
    let e = n5
        .wait_for_state(NmtState::Operational, Duration::from_millis(300))
        .await
        .unwrap_err();
    assert_eq!(
        e,
        NetError::Timeout {
            node: NodeId::new(5).unwrap(),
            awaited: Awaited::State(NmtState::Operational),
            after: Duration::from_millis(300)
        }
    );
    net.nmt_all(duocan::NmtCommand::Start).await.unwrap();
    for id in [4, 5] {
        net.node(id)
            .wait_for_state(NmtState::Operational, Duration::from_secs(2))
            .await
            .unwrap();
    }
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_boot_up_before_the_wait_counts_from_when_the_node_object_was_made() {
    let net = Network::simulated([5], NetOptions::default()).unwrap();
    let n5 = net.node(5);
    let made = net.now();
    n5.reset().await.unwrap();
    // The boot-up arrives while the caller is busy elsewhere: python's race.
    tokio::time::sleep(Duration::from_millis(300)).await;
    let at = n5
        .wait_for_boot_up(Duration::from_millis(10))
        .await
        .expect("the boot-up that came before the wait counts");
    assert!(at >= made && at <= net.now(), "{at:?} {made:?}");
    assert_eq!(n5.last_boot_up().await.unwrap(), Some(at));
    // From a later instant, that boot-up does not count: the wait times out.
    let later = net.now();
    let e = n5
        .wait_for_boot_up_since(later, Duration::from_millis(200))
        .await
        .unwrap_err();
    assert_eq!(
        e,
        NetError::Timeout {
            node: NodeId::new(5).unwrap(),
            awaited: Awaited::BootUp,
            after: Duration::from_millis(200)
        }
    );
    // A node object made after the boot-up does not see it either.
    let fresh = net.node(5);
    assert!(fresh
        .wait_for_boot_up(Duration::from_millis(100))
        .await
        .is_err());
    // And a boot-up after the wait started is seen.
    let since = net.now();
    let (r, sent) = tokio::join!(
        n5.wait_for_boot_up_since(since, Duration::from_secs(2)),
        n5.reset_communication()
    );
    sent.unwrap();
    assert!(r.unwrap() >= since);
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_watched_heartbeat_lost_is_reported_at_its_timeout() {
    let bus = MemBus::new("mem");
    let net = Network::open(bus.port()).unwrap();
    let mut events = net.events();
    let s = Runtime::new(single(node(3, false, 50, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    s.boot().await.unwrap();
    net.node(3)
        .watch_heartbeat(Duration::from_millis(300))
        .await
        .unwrap();
    net.node(3)
        .wait_for_state(NmtState::PreOperational, Duration::from_secs(2))
        .await
        .unwrap();
    s.shutdown().await;
    let lost = tokio::time::timeout(Duration::from_secs(3), async {
        loop {
            match events.next().await {
                Some(NetEvent::HeartbeatLost { node, last, at }) => return (node, last, at),
                Some(_) => {}
                None => panic!("network closed"),
            }
        }
    })
    .await
    .expect("the loss is reported");
    assert_eq!(lost.0.raw(), 3);
    // Declared at the last heartbeat plus the watch time, never earlier (the margin above is
    // the scheduler's on a loaded machine, not the stack's).
    let after = lost.2 - lost.1;
    assert!(
        after >= duocan::Duration::from_millis(300) && after < duocan::Duration::from_millis(800),
        "{after:?}"
    );
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_watched_node_never_heard_is_reported_once_at_its_timeout() {
    // Node 3 beats every 50 ms; node 9 is not there at all. CiA 301 monitoring starts at the
    // first heartbeat, so without this event node 9 would never be reported.
    let bus = MemBus::new("mem");
    let net = Network::open(bus.port()).unwrap();
    let mut events = net.events();
    let s = Runtime::new(single(node(3, false, 50, &[])))
        .port(bus.port())
        .spawn()
        .unwrap();
    s.boot().await.unwrap();
    for id in [3, 9] {
        net.node(id)
            .watch_heartbeat(Duration::from_millis(200))
            .await
            .unwrap();
    }
    let mut not_heard = vec![];
    let _ = tokio::time::timeout(Duration::from_millis(900), async {
        while let Some(e) = events.next().await {
            if let NetEvent::NotHeard { node, since, at } = e {
                not_heard.push((node.raw(), since, at, e.to_string()));
            }
        }
    })
    .await;
    assert_eq!(not_heard.len(), 1, "{not_heard:?}");
    let (node, since, at, line) = &not_heard[0];
    assert_eq!(*node, 9);
    // Exactly the watch's timeout after it began (the network's clock).
    assert_eq!(*at - *since, duocan::Duration::from_millis(200));
    assert_eq!(line, "node 0x09: not heard for 200 ms");
    s.shutdown().await;
    net.close().await;
}
