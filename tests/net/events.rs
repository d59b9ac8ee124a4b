//! The event stream: flat events, lag as an item with its exact count, the end on close.

use duocan::net::{NetEvent, Network};
use duocan::port::mem::MemBus;
use duocan::port::Port;
use duocan::runtime::EVENT_QUEUE;
use duocan::{Frame, Id};
use std::time::Duration;

fn emcy(node: u16, code: u16) -> Frame {
    let c = code.to_le_bytes();
    Frame::from_array(Id::Standard(0x80 + node), [c[0], c[1], 0x11, 1, 2, 3, 4, 5])
}

// One thread: the sender paces itself so the network never holds more than a few frames at
// once, and every EMCY becomes exactly one event.
#[tokio::test(flavor = "current_thread")]
async fn a_lagging_reader_gets_lagged_n_and_carries_on() {
    let bus = MemBus::new("mem");
    let net = Network::open(bus.port()).unwrap();
    let mut raw = bus.port();
    tokio::time::sleep(Duration::from_millis(20)).await;
    let mut events = net.events();
    let n9 = net.node(9);
    let sent = EVENT_QUEUE + 77;
    for i in 0..sent {
        raw.send(&emcy(5, i as u16)).await.unwrap();
        if i % 8 == 7 {
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    }
    raw.send(&Frame::from_array(Id::Standard(0x709), [0]))
        .await
        .unwrap();
    // Once the boot-up is through, so is every EMCY before it (one port, in order).
    n9.wait_for_boot_up(Duration::from_secs(5)).await.unwrap();

    // 1102 events into a queue of 1024: this reader missed the first 78, is told so, and reads
    // on from the oldest kept.
    assert_eq!(events.next().await, Some(NetEvent::Lagged(78)));
    for i in 78..sent {
        match events.next().await {
            Some(NetEvent::Emcy { node, msg, .. }) => {
                assert_eq!((node.raw(), msg.code), (5, i as u16));
                assert_eq!(msg.register, 0x11);
            }
            other => panic!("event {i}: {other:?}"),
        }
    }
    let boot = events.next().await.unwrap();
    assert_eq!(boot.node().map(|n| n.raw()), Some(9));
    assert_eq!(boot.state(), Some(duocan::NmtState::Initialising));
    assert!(matches!(boot, NetEvent::BootUp { .. }));
    net.close().await;
    assert_eq!(
        events.next().await,
        None,
        "the stream ends when the network closes"
    );
}
