//! A CAN FD frame through the dual-bus layer under the tokio runtime: sent once by one
//! device's layer over two in-memory buses, it reaches the other device's layer on both and
//! is delivered once, as sent.

use super::fd_end::FdEnd;
use duocan::frame::FdFrame;
use duocan::port::mem::MemBus;
use duocan::runtime::{Handle, Runtime};
use duocan::Id;
use std::time::Duration;

fn start(buses: &[MemBus; 2]) -> Handle<FdEnd> {
    Runtime::new(FdEnd::new())
        .port(buses[0].port())
        .port(buses[1].port())
        .spawn()
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_fd_frame_crosses_two_buses_and_arrives_once() {
    let buses = [MemBus::new("canfd0"), MemBus::new("canfd1")];
    let (a, b) = (start(&buses), start(&buses));
    let frames = [
        FdFrame::new(Id::Standard(0x185), &[0xA5; 64])
            .unwrap()
            .with_brs(true),
        FdFrame::new(
            Id::Standard(0x186),
            &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12],
        )
        .unwrap()
        .with_esi(true),
    ];
    for f in frames {
        a.call(move |d, now| d.link.send_fd(now, &f))
            .await
            .unwrap()
            .expect("both ports speak FD");
    }
    let got = tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            let got = b.call(|d, _| d.got.clone()).await.unwrap();
            if got.len() >= frames.len() {
                return got;
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await
    .expect("the frames did not arrive");
    assert_eq!(got, frames, "once each, in order, bytes and flags as sent");
    // Each went out on both buses; the twins reach `b` and are dropped there.
    for (i, bus) in ["canfd0", "canfd1"].into_iter().enumerate() {
        let sent = a.port_counters(i).unwrap().tx_frames;
        assert_eq!(sent, 2, "{bus}");
    }
    let dropped = tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            let d = b
                .call(|d, _| d.link.merger().stats().duplicates)
                .await
                .unwrap();
            if d >= 2 {
                return d;
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
    })
    .await
    .expect("the twins did not arrive");
    assert_eq!(dropped, 2);
    assert_eq!(b.call(|d, _| d.got.len()).await.unwrap(), 2, "still once");
    a.shutdown().await;
    b.shutdown().await;
}
