//! The UDP port read by a thread of its own (`Port::reader`, as the runtime reads every port
//! that offers it): the group's frames in the order sent, answers written by the reader, the
//! port's own and the reader's own datagrams never read back, the port's `recv` silent while the
//! reader has the socket and back after a re-open. Runs inside `unshare -n`
//! (`.ci/tier-python.sh`).

use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::port::{Port, PortInput, PortReader};
use duocan::{Frame, Id};
use std::time::Duration;

fn frame(id: u16, i: u16) -> Frame {
    Frame::new(Id::Standard(id), &i.to_le_bytes()).unwrap()
}

/// The next frame the reader reads (it waits at most `READER_WAIT` a call).
fn next(reader: &mut dyn PortReader) -> Option<Frame> {
    for _ in 0..20 {
        match reader.read().unwrap() {
            Some(PortInput::Frame(f, at)) => {
                assert!(at.is_some(), "a UDP frame comes with its receive timestamp");
                return Some(f);
            }
            Some(other) => panic!("not a frame: {other:?}"),
            None => {}
        }
    }
    None
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_reader_reads_in_order_answers_and_never_reads_its_own() {
    let cfg = UdpBusConfig::numbered(30);
    let open = || UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let (mut port, mut peer) = (open(), open());
    let mut reader = port.reader().expect("a UDP port reads by blocking");
    // The peer's frames, in the order sent.
    let sent: Vec<Frame> = (0..200).map(|i| frame(0x181, i)).collect();
    for f in &sent {
        peer.send(f).await.unwrap();
    }
    let got: Vec<Frame> = (0..200).map(|_| next(reader.as_mut()).unwrap()).collect();
    assert_eq!(got, sent);
    // An answer the reader writes and a frame the port's task sends both reach the peer, in
    // that order; neither comes back to the reader.
    assert!(reader.write(&frame(0x201, 1)).unwrap());
    port.send(&frame(0x202, 2)).await.unwrap();
    let heard = tokio::time::timeout(Duration::from_secs(3), async {
        let mut heard = vec![];
        while heard.len() < 2 {
            if let PortInput::Frame(f, _) = peer.recv().await.unwrap() {
                heard.push(f);
            }
        }
        heard
    })
    .await
    .expect("the peer hears both");
    assert_eq!(heard, [frame(0x201, 1), frame(0x202, 2)]);
    assert_eq!(
        next(reader.as_mut()),
        None,
        "its own frames are not read back"
    );
    let c = port.counters().snapshot();
    assert_eq!((c.rx_frames, c.tx_frames, c.rx_invalid), (200, 2, 0));
    // While the reader has the socket the port's own `recv` gets nothing.
    peer.send(&frame(0x181, 999)).await.unwrap();
    let quiet = tokio::time::timeout(Duration::from_millis(100), port.recv()).await;
    assert!(quiet.is_err(), "{quiet:?}");
    assert_eq!(next(reader.as_mut()), Some(frame(0x181, 999)));
    // Re-opened, the port reads through `recv` again.
    drop(reader);
    port.reopen().await.unwrap();
    peer.send(&frame(0x181, 1000)).await.unwrap();
    let again = tokio::time::timeout(Duration::from_secs(3), port.recv())
        .await
        .expect("the re-opened port receives")
        .unwrap();
    assert!(matches!(again, PortInput::Frame(f, Some(_)) if f == frame(0x181, 1000)));
}
