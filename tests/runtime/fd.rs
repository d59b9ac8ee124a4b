//! CAN FD frames through the runtime: a device that speaks CAN FD gets them from its ports and
//! sends them; a classic device on the same bus stays classic.

use super::rig::{next, nothing_more, on_bus, received, Got, Probe};
use duocan::port::mem::MemBus;
use duocan::port::{AnyInput, Port};
use duocan::runtime::{Runtime, PORT_FD_TX_QUEUE};
use duocan::PortStatus;
use duocan::{FdFrame, Frame, Id};
use std::time::Duration;

/// Three FD frames of different lengths and flags, and a classic one between them.
fn traffic() -> (Vec<FdFrame>, Frame) {
    let fd = vec![
        FdFrame::new(Id::Standard(0x181), &[0x11; 12])
            .unwrap()
            .with_brs(true),
        FdFrame::new(Id::Extended(0x1234_5678), &(0..64).collect::<Vec<u8>>())
            .unwrap()
            .with_esi(true),
        FdFrame::new(Id::Standard(0x7FF), &[0xA5; 3])
            .unwrap()
            .with_brs(true)
            .with_esi(true),
    ];
    (fd, Frame::from_array(Id::Standard(0x205), [1, 2, 3]))
}

/// The port's counters once it counted `n` frames sent, or after a second: a frame is counted
/// once its write returned, which may be after the tester read it.
async fn tx_counted(
    h: &duocan::runtime::Handle<Probe>,
    n: u64,
) -> duocan::port::PortCountersSnapshot {
    let until = std::time::Instant::now() + std::time::Duration::from_secs(1);
    loop {
        let c = h.port_counters(0).unwrap();
        if c.tx_frames >= n || std::time::Instant::now() >= until {
            return c;
        }
        tokio::time::sleep(std::time::Duration::from_millis(1)).await;
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fd_frames_go_both_ways_and_a_classic_device_stays_classic() {
    let bus = MemBus::new("fd");
    let mut tester = bus.port();
    let fd = on_bus(&bus, Probe::new(true));
    let classic = on_bus(&bus, Probe::new(false));
    let (frames, plain) = traffic();

    // Into the devices: the FD device gets everything in order, each FD frame with its
    // flags, bytes and receive timestamp; the classic device gets the classic frame only.
    tester.send_fd(&frames[0]).await.unwrap();
    tester.send(&plain).await.unwrap();
    tester.send_fd(&frames[1]).await.unwrap();
    tester.send_fd(&frames[2]).await.unwrap();
    let got = received(&fd, 4).await;
    assert_eq!(got.len(), 4, "{got:?}");
    assert_eq!(got[1], Got::Classic(plain));
    let fd_got: Vec<_> = [&got[0], &got[2], &got[3]]
        .into_iter()
        .map(|g| match g {
            Got::Fd { frame, now, at } => {
                assert!(at <= now, "stamped before it was handled: {at} {now}");
                *frame
            }
            other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(fd_got, frames);
    assert!(fd_got[0].brs() && !fd_got[0].esi());
    assert!(fd_got[1].esi() && !fd_got[1].brs() && fd_got[1].data().len() == 64);
    assert_eq!(received(&classic, 1).await, [Got::Classic(plain)]);
    // The classic port counts what it could not hand over; the FD device's port does not.
    let invalid = |h: &duocan::runtime::Handle<Probe>| h.port_counters(0).unwrap().rx_invalid;
    assert_eq!((invalid(&fd), invalid(&classic)), (0, 3));

    // Out of the FD device: FD and classic frames, each kind in its order, flags kept.
    let (f0, f1, f2) = (frames[0], frames[1], frames[2]);
    fd.call(move |d, _| {
        d.out_fd.extend([f2, f0]);
        d.out.push_back(plain);
        d.out_fd.push_back(f1);
    })
    .await
    .unwrap();
    let mut fd_seen = vec![];
    let mut classic_seen = vec![];
    while fd_seen.len() + classic_seen.len() < 4 {
        match next(&mut tester).await {
            AnyInput::Fd(f, stamp) => {
                assert!(stamp.is_some());
                fd_seen.push(f);
            }
            AnyInput::Frame(f, _) => classic_seen.push(f),
            other => panic!("{other:?}"),
        }
    }
    assert_eq!(fd_seen, [f2, f0, f1]);
    assert_eq!(classic_seen, [plain]);
    assert_eq!(tx_counted(&fd, 4).await.tx_frames, 4);

    // A classic device is not asked for FD frames (it said it has none): its classic ones
    // go out as before, nothing else.
    classic
        .call(move |d, _| {
            d.out_fd.push_back(f0);
            d.out.push_back(plain);
        })
        .await
        .unwrap();
    assert!(matches!(next(&mut tester).await, AnyInput::Frame(f, _) if f == plain));
    nothing_more(&mut tester).await;
    fd.shutdown().await;
    classic.shutdown().await;
}

/// More FD frames at once than the port's FD queue holds: the rest are dropped and counted,
/// what was queued goes out in order.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_fd_queue_drops_and_counts() {
    let bus = MemBus::new("fd");
    let mut tester = bus.port();
    let fd = on_bus(&bus, Probe::new(true));
    let extra = 10;
    fd.call(move |d, _| {
        for i in 0..PORT_FD_TX_QUEUE + extra {
            let n = u16::try_from(i).unwrap();
            d.out_fd
                .push_back(FdFrame::new(Id::Standard(0x100), &n.to_le_bytes()).unwrap());
        }
    })
    .await
    .unwrap();
    for i in 0..PORT_FD_TX_QUEUE {
        let n = u16::try_from(i).unwrap();
        match next(&mut tester).await {
            AnyInput::Fd(f, _) => assert_eq!(f.data(), n.to_le_bytes()),
            other => panic!("{other:?}"),
        }
    }
    let c = tx_counted(&fd, PORT_FD_TX_QUEUE as u64).await;
    assert_eq!(
        (c.tx_frames, c.tx_dropped),
        (PORT_FD_TX_QUEUE as u64, extra as u64)
    );
    // Nothing else came.
    nothing_more(&mut tester).await;
    fd.shutdown().await;
}

/// FD frames the device yields just before a shutdown still go out before it returns, as
/// classic ones do.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fd_frames_queued_before_a_shutdown_go_out() {
    let bus = MemBus::new("fd");
    let mut tester = bus.port();
    let fd = on_bus(&bus, Probe::new(true));
    let (frames, _) = traffic();
    let queued = frames.clone();
    fd.call(move |d, _| d.out_fd.extend(queued)).await.unwrap();
    fd.shutdown().await;
    for f in frames {
        assert!(matches!(next(&mut tester).await, AnyInput::Fd(got, _) if got == f));
    }
}

/// A classic port under an FD device: what it hands over goes to the device as before, and
/// an FD frame it cannot send is reported as a failed send (the port stays up).
struct ClassicOnly(duocan::port::mem::MemPort);

impl Port for ClassicOnly {
    fn name(&self) -> &str {
        self.0.name()
    }
    fn counters(&self) -> duocan::port::PortCounters {
        self.0.counters()
    }
    async fn recv(&mut self) -> Result<duocan::port::PortInput, duocan::port::PortError> {
        self.0.recv().await
    }
    async fn send(&mut self, frame: &Frame) -> Result<(), duocan::port::PortError> {
        self.0.send(frame).await
    }
    async fn reopen(&mut self) -> Result<(), duocan::port::PortError> {
        self.0.reopen().await
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_fd_frame_a_classic_port_cannot_send_is_reported() {
    let bus = MemBus::new("classic");
    let mut tester = bus.port();
    let fd = Runtime::new(Probe::new(true))
        .port(ClassicOnly(bus.port()))
        .spawn()
        .unwrap();
    let mut events = fd.subscribe();
    let (frames, plain) = traffic();
    let f0 = frames[0];
    fd.call(move |d, _| {
        d.out_fd.push_back(f0);
        d.out.push_back(plain);
    })
    .await
    .unwrap();
    assert!(matches!(next(&mut tester).await, AnyInput::Frame(f, _) if f == plain));
    let failed = tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            if let duocan::runtime::RuntimeEvent::Port { status, .. } = events.recv().await.unwrap()
            {
                return status;
            }
        }
    })
    .await
    .expect("no report");
    assert!(matches!(failed, PortStatus::TxFailed(_)), "{failed:?}");
    tester.send(&plain).await.unwrap();
    assert_eq!(received(&fd, 1).await, [Got::Classic(plain)]);
    fd.shutdown().await;
}
