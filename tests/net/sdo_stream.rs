//! Streamed SDO through a remote node (`write_from`, `read_to`): a mebibyte each way with
//! progress, and the local side failing.
//!
//! The node's SDO server collects a download whole (its dictionary takes values whole), so the
//! test node gets a 1 MiB domain and a 1 MiB transfer limit; what stays bounded is the client
//! side (its buffer is checked against the window frame by frame in `tests/sdo/stream.rs`).

use crate::rt::{pattern, sdo_node, single};
use duocan::capture::recorder::{Tap, TapDirection, TapPoint};
use duocan::net::{NetError, NetOptions, Network, TransferProgress};
use duocan::od::{Access, DataType, ObjectDef};
use duocan::port::mem::MemBus;
use duocan::runtime::{Handle, Runtime};
use duocan::sdo::{SdoErrorKind, SdoServerConfig, TransferMode};
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, ReadBuf};

const BIG: u16 = 0x2010;
const MIB: usize = 1 << 20;

async fn big_node(
    bus: &MemBus,
) -> Handle<duocan::machine::Station<duocan::machine::SinglePort, crate::rt::TestNode>> {
    let mut n = sdo_node(6, false, 0, &[]);
    n.od_mut()
        .insert(ObjectDef::bytes(BIG, 0, DataType::Domain, MIB as u32).access(Access::Rw))
        .unwrap();
    n.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(MIB));
    let s = Runtime::new(single(n)).port(bus.port()).spawn().unwrap();
    s.boot().await.unwrap();
    s
}

fn opts() -> NetOptions {
    NetOptions::default().with_sdo_timeout(Duration::from_millis(500))
}

/// Checks a run of progress reports: never falling, never above the total, ending at it.
fn rising(reports: &[TransferProgress], total: u64) {
    assert!(!reports.is_empty());
    for w in reports.windows(2) {
        assert!(w[0].done <= w[1].done, "{w:?}");
    }
    assert!(reports.iter().all(|p| p.done <= total));
    assert_eq!(reports.last().unwrap().done, total);
    assert!(
        reports.len() > 3,
        "reported along the way: {}",
        reports.len()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_mebibyte_streams_both_ways_with_progress() {
    let bus = MemBus::new("mem");
    let net = Network::open_with(bus.port(), opts()).unwrap();
    let s = big_node(&bus).await;
    for (mode, len, seed, sized) in [
        (TransferMode::Block, MIB, 1, true),
        (TransferMode::Segmented, MIB / 4, 2, false),
        (TransferMode::Block, MIB - 5, 3, false),
    ] {
        let sdo = net.node(6).sdo().with_mode(mode);
        let blob = pattern(len, seed);
        let mut seen = Vec::new();
        let n = sdo
            .write_from(BIG, 0, &blob[..], sized.then_some(len as u64), |p| {
                seen.push(p)
            })
            .await
            .unwrap();
        assert_eq!(n, len as u64);
        rising(&seen, len as u64);
        assert!(seen.iter().all(|p| p.total == sized.then_some(len as u64)));
        assert!(
            s.read(BIG, 0).await.unwrap() == blob,
            "{mode:?}: the node holds it"
        );

        let mut out = Vec::new();
        let mut seen = Vec::new();
        let n = sdo
            .read_to(BIG, 0, &mut out, |p| seen.push(p))
            .await
            .unwrap();
        assert_eq!(n, len as u64);
        assert!(out == blob, "{mode:?}: {} bytes back", out.len());
        rising(&seen, len as u64);
        assert_eq!(
            seen[0].total,
            Some(len as u64),
            "the node announced the size"
        );
    }
    net.close().await;
    s.shutdown().await;
}

/// The error of an input that ended before the size announced.
fn assert_input_ended(e: &NetError) {
    assert!(
        matches!(
            e,
            NetError::Io {
                kind: std::io::ErrorKind::UnexpectedEof,
                ..
            }
        ),
        "{e:?}"
    );
}

/// A reader that fails after `ok` bytes.
struct Failing {
    ok: usize,
}

impl AsyncRead for Failing {
    fn poll_read(
        mut self: Pin<&mut Self>,
        _: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        if self.ok == 0 {
            return Poll::Ready(Err(std::io::Error::other("disk on fire")));
        }
        let n = self.ok.min(buf.remaining());
        buf.put_slice(&vec![0x55; n]);
        self.ok -= n;
        Poll::Ready(Ok(()))
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_failing_or_short_input_is_an_error_and_the_node_is_told() {
    let bus = MemBus::new("mem");
    let net = Network::open_with(bus.port(), opts()).unwrap();
    let s = big_node(&bus).await;
    let sdo = net.node(6).sdo();
    let before = pattern(100, 9);
    sdo.write_bytes(BIG, 0, before.clone()).await.unwrap();
    let e = sdo
        .write_from(BIG, 0, Failing { ok: 10_000 }, None, |_| {})
        .await
        .unwrap_err();
    match &e {
        NetError::Io {
            index, sub, kind, ..
        } => {
            assert_eq!((*index, *sub, *kind), (BIG, 0, std::io::ErrorKind::Other));
        }
        other => panic!("{other:?}"),
    }
    assert!(e.to_string().contains("disk on fire"), "{e}");
    assert_eq!(e.node().map(|n| n.raw()), Some(6));
    // The node dropped the cut-off transfer and serves the next one.
    assert_eq!(sdo.read_bytes(BIG, 0).await.unwrap(), before);
    let e = sdo
        .write_from(BIG, 0, &[1u8; 50][..], Some(80), |_| {})
        .await
        .unwrap_err();
    assert_input_ended(&e);
    assert_eq!(sdo.read_bytes(BIG, 0).await.unwrap(), before);
    // An input longer than the size given: the size is written, the rest is not read.
    let n = sdo
        .write_from(BIG, 0, &[2u8; 500][..], Some(300), |_| {})
        .await
        .unwrap();
    assert_eq!(n, 300);
    assert_eq!(sdo.read_bytes(BIG, 0).await.unwrap(), [2; 300]);
    // A size SDO cannot announce is refused before anything is sent.
    assert!(matches!(
        sdo.write_from(BIG, 0, &[][..], Some(1 << 33), |_| {}).await,
        Err(NetError::Argument(_))
    ));
    // The node's own limit is its to enforce: an abort, as for a whole value.
    let e = sdo
        .write_from(0x2001, 0, &[3u8; 2000][..], None, |_| {})
        .await
        .unwrap_err();
    assert!(
        matches!(e, NetError::Sdo(ref x) if matches!(x.kind, SdoErrorKind::Server(_))),
        "{e:?}"
    );
    net.close().await;
    s.shutdown().await;
}

/// The first bytes (command specifiers) of every SDO request to node 6 the network sent.
#[derive(Default)]
struct Requests(std::sync::Mutex<Vec<u8>>);

impl Tap for Requests {
    fn frame(&self, _: duocan::Instant, _: TapPoint, dir: TapDirection, f: &duocan::Frame) {
        if dir == TapDirection::Tx && f.id() == duocan::Id::Standard(0x606) {
            self.0.lock().unwrap().push(f.data()[0]);
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_to_four_bytes_go_expedited_as_a_whole_value_does() {
    let bus = MemBus::new("mem");
    let sent = Arc::new(Requests::default());
    let net = Network::open_with(bus.port(), opts().with_tap(sent.clone())).unwrap();
    let s = big_node(&bus).await;
    let taken = || std::mem::take(&mut *sent.0.lock().unwrap());
    // 2 bytes announced: one expedited request (0x2B: 2 bytes), as write_bytes sends them,
    // whether the mode is left to the client or asked for.
    for mode in [TransferMode::Auto, TransferMode::Expedited] {
        let mut seen = Vec::new();
        let sdo = net.node(6).sdo().with_mode(mode);
        let n = sdo
            .write_from(BIG, 0, &[7u8, 8][..], Some(2), |p| seen.push(p))
            .await
            .unwrap();
        assert_eq!(n, 2);
        assert_eq!(taken(), [0x2B], "{mode:?}");
        assert_eq!(seen.last().map(|p| (p.done, p.total)), Some((2, Some(2))));
        assert_eq!(s.read(BIG, 0).await.unwrap(), [7, 8]);
    }
    // Segmented asked for: segmented (initiate with the size, one segment).
    let sdo = net.node(6).sdo().with_mode(TransferMode::Segmented);
    sdo.write_from(BIG, 0, &[9u8, 9][..], Some(2), |_| {})
        .await
        .unwrap();
    assert_eq!(taken(), [0x21, 0x0B]);
    // Expedited cannot carry more than 4 bytes, nor a size not announced: refused unsent.
    let sdo = net.node(6).sdo().with_mode(TransferMode::Expedited);
    for size in [Some(5), None] {
        let e = sdo
            .write_from(BIG, 0, &[1u8; 5][..], size, |_| {})
            .await
            .unwrap_err();
        assert!(
            matches!(e, NetError::Sdo(ref x) if x.kind == SdoErrorKind::TransferMode),
            "{size:?}: {e:?}"
        );
    }
    assert_eq!(taken(), []);
    // An input shorter than the few bytes announced: an error, nothing sent.
    let e = net
        .node(6)
        .sdo()
        .write_from(BIG, 0, &[1u8; 2][..], Some(3), |_| {})
        .await
        .unwrap_err();
    assert_input_ended(&e);
    assert_eq!(taken(), []);
    net.close().await;
    s.shutdown().await;
}
