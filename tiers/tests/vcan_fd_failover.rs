//! CAN FD frames through the dual-bus layer under duocan's tokio runtime on two real SocketCAN
//! interfaces opened for CAN FD (vcan0 and vcan1 at the CAN FD MTU): vcan0 is set down mid-run
//! and up again while a dual-port sender puts 64-byte FD frames (BRS) on both. Every frame is
//! delivered exactly once through the cut; the runtime reports port 0 down and up,
//! the layer marks it failed and trusts it again, and frames flow on vcan0 again afterwards.
//! The FD counterpart of `vcan_failover.rs` (classic heartbeats). Runs inside duocan's qemu VM
//! (`.ci/tier-vcan.sh`), one test at a time (`RUST_TEST_THREADS=1`: it switches vcan0 down and
//! up).
//!
//! The VM emulates its CPU (TCG): every wait is for an outcome, with a generous timeout, never
//! a count within a fixed time.

use duocan::frame::FdFrame;
use duocan::port::socketcan::SocketCanPort;
use duocan::port::Port;
use duocan::runtime::{Handle, Runtime, RuntimeEvent};
use duocan::{Duration, Id};
use duocan_redundancy::{DualBusConfig, LinkEvent, LinkEventKind, PortState};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration as StdDuration;

// The FD test device of the redundancy crate's tests: a dual-bus layer with both ports FD,
// recording the FD frames it delivers.
#[path = "../../redundancy/tests/common/fd_end.rs"]
mod fd_end;
use fd_end::FdEnd;

// The root crate's helpers for runtime tests (waiting on events).
#[path = "../../tests/common/runtime.rs"]
mod rt;
use rt::wait_for;
#[path = "common/cut.rs"]
mod cut;
use cut::{port_reported, LinkDown};

type Ev = RuntimeEvent<LinkEvent>;

/// The sender's identifier: a TPDO of node 5.
const ID: u16 = 0x185;

/// Frame `k`: 64 bytes, its number in the first four, the rest a pattern of it (so that a
/// frame garbled anywhere is not taken for another).
fn frame(k: u32) -> FdFrame {
    let mut data = [0u8; 64];
    data[..4].copy_from_slice(&k.to_le_bytes());
    for (i, b) in data.iter_mut().enumerate().skip(4) {
        *b = (k as u8).wrapping_mul(31).wrapping_add(i as u8);
    }
    FdFrame::new(Id::Standard(ID), &data)
        .unwrap()
        .with_brs(true)
}

/// A dual-port node without a layer: each frame written on vcan0, then on vcan1, from one task
/// (so the copies are as close as the kernel makes them), every 10 ms until `stop`. A write to
/// vcan0 while it is down fails and is not retried: that copy is lost, as on a cut bus; the
/// port, which lets its socket go when the interface is gone, is opened again for the next
/// frame (as the runtime re-initialises a port). Returns what it sent, and the numbers of the
/// frames whose two writes were further apart than `window` (the emulated CPU holding the
/// sender up between them): two occurrences to the layer by its documented rule (see
/// `duocan_redundancy::link::merge`), delivered once or twice.
fn sender(
    stop: Arc<AtomicBool>,
    window: StdDuration,
) -> tokio::task::JoinHandle<(Vec<FdFrame>, Vec<u32>)> {
    let mut ports = [
        SocketCanPort::open_fd("vcan0").expect("open vcan0 for CAN FD"),
        SocketCanPort::open_fd("vcan1").expect("open vcan1 for CAN FD"),
    ];
    tokio::spawn(async move {
        let (mut sent, mut apart) = (vec![], vec![]);
        let mut k = 0u32;
        while !stop.load(Ordering::Relaxed) {
            let f = frame(k);
            let mut any = false;
            let before = std::time::Instant::now();
            for p in &mut ports {
                if p.send_fd(&f).await.is_ok() {
                    any = true;
                } else {
                    // Fails again while the interface is down; works once it is up.
                    let _ = p.reopen().await;
                }
            }
            if before.elapsed() > window {
                apart.push(k);
            }
            // vcan1 never goes down: every frame is on at least one bus.
            assert!(any, "frame {k} written on neither interface");
            sent.push(f);
            k += 1;
            tokio::time::sleep(StdDuration::from_millis(10)).await;
        }
        (sent, apart)
    })
}

fn link_port(e: &Ev) -> Option<(u8, PortState)> {
    match e {
        RuntimeEvent::Device(LinkEvent {
            kind: LinkEventKind::Port { port, to, .. },
            ..
        }) => Some((*port, *to)),
        _ => None,
    }
}

/// Waits (up to `secs`) until the receiver has delivered `n` FD frames.
async fn delivered_at_least(rx: &Handle<FdEnd>, n: usize, secs: u64, what: &str) {
    let until = tokio::time::Instant::now() + StdDuration::from_secs(secs);
    loop {
        let got = rx.call(|d, _| d.got.len()).await.unwrap();
        if got >= n {
            return;
        }
        assert!(
            tokio::time::Instant::now() < until,
            "{what}: {got} of {n} FD frames delivered in {secs} s"
        );
        tokio::time::sleep(StdDuration::from_millis(50)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fd_frames_arrive_once_while_vcan0_is_down_and_after_it_recovers() {
    // A skew window of 40 ms (default 5 ms): in the emulated VM the sender's two writes of a
    // frame may be that far apart, and the frames are all different (numbered), so a wide
    // window cannot take one for another's twin.
    let window = Duration::from_millis(40);
    let cfg = DualBusConfig::default()
        .with_skew_window(window)
        .with_max_skew_window(Duration::from_millis(80));
    let rx = Runtime::new(FdEnd::with_config(cfg))
        .name("fd receiver")
        .port(SocketCanPort::open_fd("vcan0").expect("open vcan0 for CAN FD"))
        .port(SocketCanPort::open_fd("vcan1").expect("open vcan1 for CAN FD"))
        .spawn()
        .unwrap();
    let mut ev = rx.subscribe();
    let stop = Arc::new(AtomicBool::new(false));
    let tx = sender(stop.clone(), StdDuration::from_micros(window.as_micros()));

    // Both buses carry the frames: the twins are merged.
    delivered_at_least(&rx, 20, 60, "before the cut").await;
    for p in [0, 1] {
        assert!(rx.port_counters(p).unwrap().rx_frames > 0, "port {p}");
    }

    let down = LinkDown::new("vcan0");
    port_reported(&mut ev, 0, false, 60).await;
    wait_for(&mut ev, 60, "layer marks port 0 failed", |e| {
        (link_port(e) == Some((0, PortState::Failed))).then_some(())
    })
    .await;
    // Frames keep coming through vcan1 alone.
    let at_cut = rx.call(|d, _| d.got.len()).await.unwrap();
    delivered_at_least(&rx, at_cut + 30, 60, "while vcan0 is down").await;

    drop(down);
    port_reported(&mut ev, 0, true, 60).await;
    // Frames on vcan0 again.
    let p0 = rx.port_counters(0).unwrap();
    let until = tokio::time::Instant::now() + StdDuration::from_secs(60);
    while rx.port_counters(0).unwrap().rx_frames < p0.rx_frames + 20 {
        assert!(
            tokio::time::Instant::now() < until,
            "no frames on vcan0 after it came back: {p0:?} then {:?}",
            rx.port_counters(0).unwrap()
        );
        tokio::time::sleep(StdDuration::from_millis(50)).await;
    }
    // The layer trusts it again (after its back-off, up to 10 s, and probation); the port's
    // state changes on the way are shown if it does not.
    let mut seen = vec![];
    let ok = tokio::time::timeout(StdDuration::from_secs(60), async {
        loop {
            if let Ok(RuntimeEvent::Device(LinkEvent {
                kind:
                    LinkEventKind::Port {
                        port: 0,
                        to,
                        reason,
                        ..
                    },
                ..
            })) = ev.recv().await
            {
                seen.push((to, reason));
                if to == PortState::Ok {
                    return;
                }
            }
        }
    })
    .await;
    assert!(
        ok.is_ok(),
        "layer never trusted port 0 again: {seen:?}, now {:?}, port {:?}",
        rx.call(|d, _| d.link.port_state(0)).await.unwrap(),
        rx.port_counters(0).unwrap()
    );
    // Twins merged again from here on.
    let dups = rx
        .call(|d, _| d.link.merger().stats().duplicates)
        .await
        .unwrap();
    delivered_at_least(
        &rx,
        rx.call(|d, _| d.got.len()).await.unwrap() + 20,
        60,
        "after",
    )
    .await;

    stop.store(true, Ordering::Relaxed);
    let (sent, apart) = tx.await.unwrap();
    delivered_at_least(&rx, sent.len(), 60, "after the sender stopped").await;
    // Twins still in flight, and anything delivered twice, have time to show.
    tokio::time::sleep(StdDuration::from_millis(500)).await;
    let (got, stats, dups_after) = rx
        .call(|d, _| {
            (
                d.got.clone(),
                d.link.stats(),
                d.link.merger().stats().duplicates,
            )
        })
        .await
        .unwrap();
    let numbers = |v: &[FdFrame]| -> Vec<u32> {
        v.iter()
            .map(|f| u32::from_le_bytes(f.data()[..4].try_into().unwrap()))
            .collect()
    };
    // Every frame delivered, none foreign; a second delivery only of a frame written beyond
    // the window. Not in order across the buses: a frame one bus missed (written while vcan0
    // was down or being opened again) is handed over by the other port's reader, which may run
    // behind the first one's with the next frame; the layer delivers each at its arrival.
    let (mut first, mut again) = (vec![], vec![]);
    for f in &got {
        if first.contains(f) {
            again.push(*f);
        } else {
            first.push(*f);
        }
    }
    let (mut got_k, sent_k) = (numbers(&first), numbers(&sent));
    let out_of_order = got_k.windows(2).filter(|w| w[0] > w[1]).count();
    got_k.sort_unstable();
    let missing: Vec<_> = sent_k.iter().filter(|k| !got_k.contains(k)).collect();
    assert_eq!(
        got_k, sent_k,
        "each FD frame once through the cut: missing {missing:?}, {out_of_order} out of order"
    );
    first.sort_by_key(|f| numbers(&[*f])[0]);
    assert_eq!(first, sent, "bytes and flags as sent");
    assert!(
        numbers(&again).iter().all(|k| apart.contains(k)),
        "delivered twice: {:?}; written more than the window apart: {apart:?}",
        numbers(&again)
    );
    assert!(
        dups_after > dups,
        "twins from vcan0 merged after it came back"
    );
    println!(
        "{} FD frames sent, {} delivered ({} written apart, {out_of_order} out of order); layer: \
         {stats:?}; ports rx {} / {}",
        sent.len(),
        got.len(),
        apart.len(),
        rx.port_counters(0).unwrap().rx_frames,
        rx.port_counters(1).unwrap().rx_frames
    );
    // The cut cost vcan0 frames the receiver heard on vcan1 only.
    assert!(rx.port_counters(0).unwrap().rx_frames < rx.port_counters(1).unwrap().rx_frames);
    rx.shutdown().await;
}
