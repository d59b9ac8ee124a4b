//! A SocketCAN port that disappears and comes back is re-opened and used again, under the
//! dual-bus layer (`DualBus`, default settings) and duocan's runtime, on vcan0 and vcan1:
//!
//! - the interface deleted and created again (`ip link del vcan1`, `ip link add … type vcan`,
//!   `ip link set vcan1 up`) while the network runs: the port fails, is re-opened once the
//!   interface exists again (within the runtime's back-off), and carries frames again;
//! - bus-off, as the kernel reports it (an error frame with `CAN_ERR_BUSOFF`; vcan has no
//!   controller, so the test writes the error frames a controller's driver would, with a raw
//!   socket and `CAN_ERR_FLAG`, and vcan hands them to every socket on it): the layer fails the
//!   port at once; when the driver then reports the restart (`CAN_ERR_RESTARTED`) the port is
//!   used again without a re-open, and when it does not, the layer's re-initialisation
//!   (`PortRequest::Reinit`, its first back-off 100 ms) re-opens it.
//!
//! A sender (another node) puts a counter frame on both buses every 5 ms. Runs inside duocan's
//! qemu VM (`.ci/tier-vcan.sh`), one test at a time: the interfaces are deleted and switched.

use duocan::machine::{ErrorCause, Machine, PortStatus, Station, StationEvent};
use duocan::port::socketcan::{inject_error_frame, link_state, LinkState, SocketCanPort};
use duocan::port::Port;
use duocan::runtime::{Handle, Runtime, RuntimeEvent, BACKOFF_MAX};
use duocan::{Frame, Id, Instant};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEvent, LinkEventKind, PortReason, PortState};
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Arc;
use std::time::Duration;

#[path = "common/apart.rs"]
mod apart;
use apart::Apart;

// The root crate's helpers for runtime tests (waiting on events).
#[path = "../../tests/common/runtime.rs"]
mod rt;
use rt::wait_for;

/// Counts what the layer delivers.
struct Counter(Arc<AtomicU32>);

impl Machine for Counter {
    type Event = ();
    type LinkCommand = std::convert::Infallible;
    fn handle_frame(&mut self, _: Instant, _: &Frame) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<Frame> {
        None
    }
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

type Dev = Station<DualBus, Counter>;
type Ev = RuntimeEvent<StationEvent<LinkEvent, ()>>;

/// The receiver on vcan0 and vcan1, and what it delivered so far.
async fn receiver() -> (Handle<Dev>, Arc<AtomicU32>) {
    let delivered = Arc::new(AtomicU32::new(0));
    let dev = Station::new(
        DualBus::new(DualBusConfig::default()),
        Counter(delivered.clone()),
    );
    let h = Runtime::new(dev)
        .name("receiver")
        .port(SocketCanPort::open("vcan0").unwrap())
        .port(SocketCanPort::open("vcan1").unwrap())
        .spawn()
        .unwrap();
    (h, delivered)
}

/// A counter frame on both buses every 5 ms until dropped; a bus that fails is opened again at
/// the next frame. While `quiet1` is set nothing goes on vcan1: the receiver's controller in
/// bus-off receives nothing from its bus until it is restarted, and vcan, which has no
/// controller, would go on handing it frames.
///
/// `apart` counts the frames whose two copies went out further apart than the layer's skew
/// window (see [`Apart`]): the emulated CPU holds this debug-built thread up between its two
/// writes now and then (3 of the first 21 frames in one CI run).
struct Sender {
    stop: Arc<AtomicBool>,
    quiet1: Arc<AtomicBool>,
    apart: Arc<AtomicU32>,
}

impl Sender {
    fn start() -> Self {
        let stop = Arc::new(AtomicBool::new(false));
        let quiet1 = Arc::new(AtomicBool::new(false));
        let apart = Arc::new(AtomicU32::new(0));
        let (s, q, a) = (stop.clone(), quiet1.clone(), apart.clone());
        std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap();
            rt.block_on(async move {
                // Both opened before the first frame (opening one between a frame's two writes
                // would put them apart).
                let mut buses = ["vcan0", "vcan1"].map(|n| SocketCanPort::open(n).ok());
                let mut k = 0u32;
                while !s.load(Ordering::Relaxed) {
                    let f = Frame::from_array(Id::Standard(0x281), k.to_le_bytes());
                    let first = std::time::Instant::now();
                    let mut sent = 0;
                    for (bus, name) in buses.iter_mut().zip(["vcan0", "vcan1"]) {
                        if name == "vcan1" && q.load(Ordering::SeqCst) {
                            continue;
                        }
                        if bus.is_none() {
                            *bus = SocketCanPort::open(name).ok();
                        }
                        if let Some(p) = bus {
                            if p.send(&f).await.is_err() {
                                *bus = None;
                            } else {
                                sent += 1;
                            }
                        }
                    }
                    if sent == 2 && Apart::default().note(&f, first) {
                        a.fetch_add(1, Ordering::Relaxed);
                    }
                    k += 1;
                    tokio::time::sleep(Duration::from_millis(5)).await;
                }
            });
        });
        Sender {
            stop,
            quiet1,
            apart,
        }
    }
    /// Bus 1 quiet for the receiver (its controller off the bus), or not.
    fn quiet1(&self, quiet: bool) {
        self.quiet1.store(quiet, Ordering::SeqCst);
    }
}

impl Drop for Sender {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
    }
}

/// Creates vcan1 and raises it (busybox's `ip link add` creates the link and may still report
/// EEXIST: sysfs says whether it is there).
fn create_vcan1() {
    let _ = Command::new("ip")
        .args(["link", "add", "dev", "vcan1", "type", "vcan"])
        .status();
    assert_ne!(link_state("vcan1"), LinkState::Missing, "vcan1 created");
    let st = Command::new("ip")
        .args(["link", "set", "vcan1", "up"])
        .status();
    assert!(st.is_ok_and(|s| s.success()), "ip link set vcan1 up");
    assert_eq!(link_state("vcan1"), LinkState::Up);
}

/// vcan1 is there and up again when dropped (also when a test fails).
struct Vcan1Back;

impl Drop for Vcan1Back {
    fn drop(&mut self) {
        if link_state("vcan1") == LinkState::Missing {
            let _ = Command::new("ip")
                .args(["link", "add", "dev", "vcan1", "type", "vcan"])
                .status();
        }
        let _ = Command::new("ip")
            .args(["link", "set", "vcan1", "up"])
            .status();
    }
}

/// The layer's state changes of port 1.
fn port1(e: &Ev) -> Option<(PortState, PortReason, duocan::Instant)> {
    match e {
        RuntimeEvent::Device(StationEvent::Link(LinkEvent {
            at,
            kind:
                LinkEventKind::Port {
                    port: 1,
                    to,
                    reason,
                    ..
                },
        })) => Some((*to, *reason, *at)),
        _ => None,
    }
}

/// Waits until port 1 has read `more` frames beyond `from` (at most `secs`).
async fn port1_reads(h: &Handle<Dev>, from: u64, more: u64, secs: u64, what: &str) -> u64 {
    let until = tokio::time::Instant::now() + Duration::from_secs(secs);
    loop {
        let n = h.port_counters(1).unwrap().rx_frames;
        if n >= from + more {
            return n;
        }
        assert!(
            tokio::time::Instant::now() < until,
            "{what}: port 1 read {} of {more} frames in {secs} s",
            n - from
        );
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// Both ports carry the sender's frames, and the layer delivers them once (a frame whose copies
/// the sender put further apart than the skew window once or twice): before a fault.
async fn both_buses_carry(h: &Handle<Dev>, delivered: &AtomicU32, sender: &Sender) {
    for p in [0, 1] {
        let until = tokio::time::Instant::now() + Duration::from_secs(10);
        while h.port_counters(p).unwrap().rx_frames < 20 {
            assert!(tokio::time::Instant::now() < until, "no frames on port {p}");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
    let d = u64::from(delivered.load(Ordering::Relaxed));
    let (a, b) = (
        h.port_counters(0).unwrap().rx_frames,
        h.port_counters(1).unwrap().rx_frames,
    );
    let apart = u64::from(sender.apart.load(Ordering::Relaxed));
    println!("{d} delivered of {a} + {b} received, {apart} sent further apart than the window");
    assert!(
        d <= a.max(b) + 2 + apart,
        "{d} delivered of {a} + {b} received ({apart} sent further apart than the window)"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_deleted_interface_created_again_is_reopened_and_carries_frames() {
    let sender = Sender::start();
    let (h, delivered) = receiver().await;
    let mut ev = h.subscribe();
    both_buses_carry(&h, &delivered, &sender).await;

    let back = Vcan1Back;
    let st = Command::new("ip").args(["link", "del", "vcan1"]).status();
    assert!(st.is_ok_and(|s| s.success()), "ip link del vcan1");
    assert_eq!(link_state("vcan1"), LinkState::Missing);
    let cause = wait_for(&mut ev, 5, "the runtime reports port 1 down", |e| match e {
        RuntimeEvent::Port {
            port: 1,
            status: PortStatus::Down(c),
            ..
        } => Some(*c),
        _ => None,
    })
    .await;
    assert_eq!(cause, ErrorCause::InterfaceDown);
    wait_for(&mut ev, 5, "the layer fails port 1", |e| {
        port1(e).filter(|(to, _, _)| *to == PortState::Failed)
    })
    .await;
    // Gone for long enough that the re-opens back off to their longest wait.
    tokio::time::sleep(BACKOFF_MAX * 3).await;
    let reopened = h.port_counters(1).unwrap().reopened;
    let missed = h.port_counters(1).unwrap().rx_frames;
    // Port 0 carried the traffic meanwhile.
    let d = delivered.load(Ordering::Relaxed);
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert!(
        delivered.load(Ordering::Relaxed) > d + 10,
        "port 0 delivers"
    );

    create_vcan1();
    let created = tokio::time::Instant::now();
    wait_for(&mut ev, 10, "the runtime reports port 1 up", |e| match e {
        RuntimeEvent::Port {
            port: 1,
            status: PortStatus::Up,
            ..
        } => Some(()),
        _ => None,
    })
    .await;
    let took = created.elapsed();
    println!("port 1 re-opened {took:?} after vcan1 was created again");
    // The next re-open after the interface is back: at most the longest back-off later (and
    // a little for the emulated VM).
    assert!(
        took <= BACKOFF_MAX + Duration::from_millis(300),
        "re-opened {took:?} after vcan1 was created again"
    );
    assert_eq!(h.port_counters(1).unwrap().reopened, reopened + 1);
    // The sender re-opened its side too: frames flow on port 1 again, and the layer takes the
    // port back.
    port1_reads(&h, missed, 20, 10, "after vcan1 came back").await;
    wait_for(&mut ev, 10, "the layer has port 1 ok again", |e| {
        port1(e).filter(|(to, _, _)| *to == PortState::Ok)
    })
    .await;
    drop(back);
    h.shutdown().await;
}

/// Writes a controller's error frame on vcan1 (`bits` of `linux/can/error.h`).
fn controller_reports(bits: u32) {
    inject_error_frame("vcan1", bits, &[0; 8]).expect("write an error frame on vcan1");
}

const CAN_ERR_BUSOFF: u32 = 0x040;
const CAN_ERR_RESTARTED: u32 = 0x100;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bus_off_then_restart_the_port_is_used_again_without_a_reopen() {
    let sender = Sender::start();
    let (h, delivered) = receiver().await;
    let mut ev = h.subscribe();
    both_buses_carry(&h, &delivered, &sender).await;
    let reopened = h.port_counters(1).unwrap().reopened;

    sender.quiet1(true);
    controller_reports(CAN_ERR_BUSOFF);
    let (_, reason, _) = wait_for(&mut ev, 5, "the layer fails port 1 at bus-off", |e| {
        port1(e).filter(|(to, _, _)| *to == PortState::Failed)
    })
    .await;
    assert_eq!(reason, PortReason::Down(ErrorCause::BusOff));
    // The driver restarts the controller (before the layer's first re-initialisation), and
    // it is on the bus again.
    controller_reports(CAN_ERR_RESTARTED);
    sender.quiet1(false);
    let (_, reason, _) = wait_for(&mut ev, 5, "port 1 recovering after the restart", |e| {
        port1(e).filter(|(to, _, _)| *to == PortState::Recovering)
    })
    .await;
    assert_eq!(
        reason,
        PortReason::Up,
        "back by the restart, not a re-initialisation"
    );
    let from = h.port_counters(1).unwrap().rx_frames;
    port1_reads(&h, from, 20, 10, "after the restart").await;
    wait_for(&mut ev, 10, "the layer has port 1 ok again", |e| {
        port1(e).filter(|(to, _, _)| *to == PortState::Ok)
    })
    .await;
    assert_eq!(h.port_counters(1).unwrap().reopened, reopened, "no re-open");
    h.shutdown().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bus_off_without_a_restart_the_layer_reinitialises_the_port() {
    let sender = Sender::start();
    let (h, delivered) = receiver().await;
    let mut ev = h.subscribe();
    both_buses_carry(&h, &delivered, &sender).await;
    let reopened = h.port_counters(1).unwrap().reopened;

    sender.quiet1(true);
    controller_reports(CAN_ERR_BUSOFF);
    let (_, reason, failed) = wait_for(&mut ev, 5, "the layer fails port 1 at bus-off", |e| {
        port1(e).filter(|(to, _, _)| *to == PortState::Failed)
    })
    .await;
    assert_eq!(reason, PortReason::Down(ErrorCause::BusOff));
    // No restart reported: the layer re-initialises the port after its first back-off, and
    // the runtime re-opens the socket.
    let (_, reason, reinit) = wait_for(&mut ev, 5, "the layer re-initialises port 1", |e| {
        port1(e).filter(|(to, _, _)| *to == PortState::Recovering)
    })
    .await;
    assert_eq!(reason, PortReason::Reinit { attempt: 1 });
    let first = DualBusConfig::default().health.reinit_first;
    assert_eq!(
        reinit - failed,
        first,
        "re-initialised after the first back-off"
    );
    wait_for(&mut ev, 5, "the runtime reports port 1 up", |e| match e {
        RuntimeEvent::Port {
            port: 1,
            status: PortStatus::Up,
            ..
        } => Some(()),
        _ => None,
    })
    .await;
    assert_eq!(
        h.port_counters(1).unwrap().reopened,
        reopened + 1,
        "re-opened once"
    );
    // The re-opened controller is on the bus again.
    sender.quiet1(false);
    let from = h.port_counters(1).unwrap().rx_frames;
    port1_reads(&h, from, 20, 10, "after the re-initialisation").await;
    wait_for(&mut ev, 10, "the layer has port 1 ok again", |e| {
        port1(e).filter(|(to, _, _)| *to == PortState::Ok)
    })
    .await;
    h.shutdown().await;
}
