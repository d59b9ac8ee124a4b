//! Confirmed transmissions on real SocketCAN: with vcan loaded with `echo=1` its driver echoes
//! frames (`IFF_ECHO`), as a CAN controller's driver does once a frame was on the bus, and a
//! port asked to confirm its transmissions hands each of its frames back as a `TxOk` status,
//! in order, never as a received frame, through `recv` and through its reader thread; other
//! sockets still receive the frames. Runs inside the qemu VM of `.ci/vcanvm`, booted with
//! `VCANVM_ECHO=1` (`.ci/tier-vcan.sh`). Without `echo=1` a port cannot confirm: `vcan.rs`.

use duocan::port::socketcan::SocketCanPort;
use duocan::port::{Port, PortInput};
use duocan::{Frame, Id, PortStatus};
use std::time::Duration;

fn frame(i: u8) -> Frame {
    Frame::new(Id::Standard(0x180 + u16::from(i)), &[i; 3]).unwrap()
}

async fn next(p: &mut SocketCanPort) -> PortInput {
    tokio::time::timeout(Duration::from_secs(2), p.recv())
        .await
        .expect("input within 2 s")
        .expect("port works")
}

#[tokio::test]
async fn own_frames_come_back_as_confirmations_through_recv() {
    let mut tx = SocketCanPort::open("vcan0").unwrap();
    let mut rx = SocketCanPort::open("vcan0").unwrap();
    assert!(
        tx.confirm_transmissions(),
        "vcan with echo=1 echoes in its driver: the port can confirm"
    );
    for i in 0..3 {
        tx.send(&frame(i)).await.unwrap();
    }
    for _ in 0..3 {
        let x = next(&mut tx).await;
        assert!(
            matches!(x, PortInput::Status(PortStatus::TxOk)),
            "a confirmation, not the frame: {x:?}"
        );
    }
    for i in 0..3 {
        match next(&mut rx).await {
            PortInput::Frame(f, at) => {
                assert_eq!(f, frame(i));
                assert!(at.is_some(), "stamped");
            }
            x => panic!("the other socket receives the frame: {x:?}"),
        }
    }
    // A frame from elsewhere is a frame to the confirming port.
    rx.send(&frame(7)).await.unwrap();
    match next(&mut tx).await {
        PortInput::Frame(f, _) => assert_eq!(f, frame(7)),
        x => panic!("a frame from another socket: {x:?}"),
    }
    // Kept across a re-opening.
    tx.reopen().await.unwrap();
    tx.send(&frame(4)).await.unwrap();
    assert!(matches!(
        next(&mut tx).await,
        PortInput::Status(PortStatus::TxOk)
    ));
}

#[tokio::test]
async fn the_reader_thread_confirms_too() {
    let mut tx = SocketCanPort::open("vcan1").unwrap();
    let mut rx = SocketCanPort::open("vcan1").unwrap();
    assert!(tx.confirm_transmissions());
    let mut reader = tx
        .reader()
        .expect("a classic SocketCAN port reads by blocking");
    rx.send(&frame(1)).await.unwrap();
    for i in 2..4 {
        assert!(reader.write(&frame(i)).unwrap());
    }
    assert!(reader.flush().unwrap());
    let mut got = vec![];
    while got.len() < 3 {
        match reader.read().unwrap() {
            Some(x) => got.push(x),
            None => panic!("nothing within the reader's wait; got {got:?}"),
        }
    }
    let frames = got
        .iter()
        .filter_map(|x| x.frame().copied())
        .collect::<Vec<_>>();
    let confirmed = got
        .iter()
        .filter(|x| matches!(x, PortInput::Status(PortStatus::TxOk)))
        .count();
    assert_eq!(
        frames,
        [frame(1)],
        "only the other socket's frame is a frame: {got:?}"
    );
    assert_eq!(confirmed, 2, "both own frames confirmed: {got:?}");
}
