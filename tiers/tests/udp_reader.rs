//! The UDP port read by a thread of its own (`Port::reader`, as the runtime reads every port
//! that offers it): the group's frames in the order sent, answers written by the reader, the
//! port's own and the reader's own datagrams never read back, the port's `recv` silent while the
//! reader has the socket and back after a re-open. Receive timestamps: a frame read late keeps
//! the time its datagram arrived, by the reader, by the port's own `recv`, and through the
//! runtime to the device while the reader thread is held up. Runs inside `unshare -n`
//! (`.ci/tier-python.sh`).

use duocan::machine::{Device, PortStatus};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::port::{Port, PortInput, PortReader};
use duocan::runtime::Runtime;
use duocan::{Frame, Id, Instant};
use std::sync::{Arc, Mutex};
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

/// How far a stamp may be from the instants around the send (the kernel stamps the datagram
/// as the sender's `sendto` hands it to loopback; the conversion reads two clocks back to back).
const SLACK: Duration = Duration::from_millis(3);

/// Sends `f` from `peer`: the instants just before and just after.
async fn send_timed(peer: &mut UdpPort, f: &Frame) -> (std::time::Instant, std::time::Instant) {
    let before = std::time::Instant::now();
    peer.send(f).await.unwrap();
    (before, std::time::Instant::now())
}

/// Asserts `at` lies within `sent` (give or take [`SLACK`]).
fn arrived_when_sent(
    at: std::time::Instant,
    (before, after): (std::time::Instant, std::time::Instant),
) {
    assert!(
        at + SLACK >= before && at <= after + SLACK,
        "stamped {:?} from the send's start, which took {:?}",
        at.checked_duration_since(before),
        after - before
    );
}

/// Makes sure the kernel stamps datagrams as they arrive. It does once some socket has asked
/// for stamps, but the first request of all only schedules the switch (a deferred work item):
/// until it has run, a datagram is stamped when it is read. A port kept open for the whole run
/// keeps the switch on, and probes show when it is: a datagram read 20 ms after it was sent
/// carries a stamp at least 15 ms before its read.
async fn kernel_stamps_on_arrival() {
    static KEEPER: tokio::sync::OnceCell<Mutex<(UdpPort, Box<dyn PortReader>)>> =
        tokio::sync::OnceCell::const_new();
    KEEPER
        .get_or_init(|| async {
            let cfg = UdpBusConfig::numbered(33);
            let mut keeper = UdpPort::open(cfg.clone()).expect("open the UDP bus");
            let mut reader = keeper.reader().expect("a UDP port reads by blocking");
            let mut probe = UdpPort::open(cfg).unwrap();
            for i in 0..100u16 {
                probe.send(&frame(0x7FF, i)).await.unwrap();
                std::thread::sleep(Duration::from_millis(20));
                while let Some(PortInput::Frame(_, Some(at))) = reader.read().unwrap() {
                    if at.elapsed() >= Duration::from_millis(15) {
                        return Mutex::new((keeper, reader));
                    }
                }
            }
            panic!("the kernel never stamped a datagram on arrival");
        })
        .await;
}

/// A reader held up 150 ms after three frames arrived reads them with their arrival times, not
/// its read time; so does the port's own `recv` (the async path) after a re-open.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_frame_read_late_keeps_the_time_it_arrived() {
    kernel_stamps_on_arrival().await;
    let cfg = UdpBusConfig::numbered(31);
    let open = || UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let (mut port, mut peer) = (open(), open());
    let mut reader = port.reader().expect("a UDP port reads by blocking");
    let mut sent = vec![];
    for i in 0..3 {
        sent.push(send_timed(&mut peer, &frame(0x181, i)).await);
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    std::thread::sleep(Duration::from_millis(150));
    for (i, when) in sent.iter().enumerate() {
        let Some(PortInput::Frame(f, Some(at))) = reader.read().unwrap() else {
            panic!("a stamped frame")
        };
        let read = std::time::Instant::now();
        assert_eq!(f, frame(0x181, i as u16));
        arrived_when_sent(at, *when);
        assert!(
            read - at >= Duration::from_millis(150),
            "read {:?} after it arrived",
            read - at
        );
    }
    drop(reader);
    port.reopen().await.unwrap();
    let when = send_timed(&mut peer, &frame(0x181, 7)).await;
    tokio::time::sleep(Duration::from_millis(100)).await;
    let got = tokio::time::timeout(Duration::from_secs(3), port.recv())
        .await
        .expect("the re-opened port receives")
        .unwrap();
    let read = std::time::Instant::now();
    let PortInput::Frame(f, Some(at)) = got else {
        panic!("a stamped frame, not {got:?}")
    };
    assert_eq!(f, frame(0x181, 7));
    arrived_when_sent(at, when);
    assert!(
        read - at >= Duration::from_millis(100),
        "read {:?} after it arrived",
        read - at
    );
}

/// What the device saw of each frame: the instant it was handled at and its stamp.
type Seen = Arc<Mutex<Vec<(Frame, Instant, Option<Instant>)>>>;

/// A device that takes 100 ms to handle the first frame (the reader thread that hands it over
/// is held up meanwhile, as a stalled reader is) and records every frame.
struct Slow(Seen);

impl Device for Slow {
    type Event = ();
    fn port_count(&self) -> usize {
        1
    }
    fn handle_rx(&mut self, now: Instant, _: usize, f: &Frame) {
        self.0.lock().unwrap().push((*f, now, None));
    }
    fn handle_rx_at(&mut self, now: Instant, _: usize, f: &Frame, at: Instant) {
        let first = self.0.lock().unwrap().is_empty();
        self.0.lock().unwrap().push((*f, now, Some(at)));
        if first {
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        None
    }
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

/// Through the runtime: the reader thread is held up 100 ms by the first frame; the two sent
/// 20 ms and 40 ms after it are handed over late, but reach the device with their arrival
/// times, as far apart as they were sent. Handed over without stamps they would have been
/// stamped at the hand-over, a few microseconds apart.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn through_the_runtime_a_held_up_reader_hands_frames_over_with_their_arrival_times() {
    kernel_stamps_on_arrival().await;
    let cfg = UdpBusConfig::numbered(32);
    let open = || UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let seen: Seen = Arc::default();
    let rt = Runtime::new(Slow(seen.clone()))
        .port(open())
        .spawn()
        .unwrap();
    let mut peer = open();
    tokio::time::sleep(Duration::from_millis(50)).await;
    let mut sent = vec![];
    for i in 0..3 {
        sent.push(send_timed(&mut peer, &frame(0x181, i)).await.0);
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let until = std::time::Instant::now() + Duration::from_secs(5);
    while seen.lock().unwrap().len() < 3 {
        assert!(
            std::time::Instant::now() < until,
            "three frames reach the device"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let seen = seen.lock().unwrap().clone();
    let frames: Vec<Frame> = seen.iter().map(|s| s.0).collect();
    assert_eq!(frames, [frame(0x181, 0), frame(0x181, 1), frame(0x181, 2)]);
    let at: Vec<Instant> = seen
        .iter()
        .map(|s| s.2.expect("handed over with its stamp"))
        .collect();
    let us = |d: Duration| d.as_micros() as i64;
    for i in 1..3 {
        // Stamps as far apart as the sends (µs), however late each was handed over.
        let stamped = (at[i] - at[i - 1]).as_micros() as i64;
        let apart = us(sent[i] - sent[i - 1]);
        assert!(
            (stamped - apart).abs() <= us(SLACK),
            "frame {i}: stamped {stamped} µs after the previous one, sent {apart} µs after"
        );
    }
    // Frame 1 arrived 20 ms after frame 0, while the reader was held up 100 ms: handed over
    // at least 60 ms after it arrived.
    let late = seen[1].1 - at[1];
    assert!(
        late >= duocan::Duration::from_millis(60),
        "handed over {late} after it arrived"
    );
    rt.shutdown().await;
}

/// A port whose reader falls behind a flood loses what its socket's queue cannot hold, and
/// counts every frame lost: what it reads and what it counts as overrun add up to what was
/// sent (the kernel tells the count with the next frame queued after the loss). The queue holds
/// the first few thousand frames (a reader held up by the scheduler finds them still there);
/// the kernel's default queue held about 250.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reader_behind_a_flood_counts_every_frame_it_lost() {
    const SENT: u16 = 40_000;
    let cfg = UdpBusConfig::numbered(34);
    let open = || UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let (mut port, mut peer) = (open(), open());
    for i in 0..SENT {
        peer.send(&frame(0x181, i)).await.unwrap();
        if i % 200 == 199 {
            // Paced, so that loopback's own backlog (1,000 packets) never overflows: every
            // loss is the receiving socket's.
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    }
    let mut read = 0u64;
    let mut last = None;
    while let Ok(Ok(x)) = tokio::time::timeout(Duration::from_millis(200), port.recv()).await {
        let f = *x.frame().expect("only frames");
        // In the order sent, with gaps where frames were lost.
        let i = u16::from_le_bytes([f.data()[0], f.data()[1]]);
        assert!(last.is_none_or(|l| i > l), "{i} after {last:?}");
        last = Some(i);
        read += 1;
    }
    // The kernel tells a socket's losses with the next frame it queues after them.
    peer.send(&frame(0x181, SENT)).await.unwrap();
    let after = tokio::time::timeout(Duration::from_secs(3), port.recv()).await;
    assert_eq!(after.unwrap().unwrap().frame(), Some(&frame(0x181, SENT)));
    let c = port.counters().snapshot();
    assert_eq!(c.rx_frames, read + 1);
    assert!(
        c.rx_overrun > 0 && read >= 2_000,
        "the queue held {read} frames, {} overrun",
        c.rx_overrun
    );
    assert_eq!(read + c.rx_overrun, u64::from(SENT), "{c:?}");
}
