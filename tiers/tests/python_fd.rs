//! CAN FD between duocan and python-can on the udp_multicast bus: python-can as a raw peer
//! (`peer.py rawfd`) sends and receives CAN FD frames byte for byte, so that what duocan puts
//! on the wire and takes from it is checked by an implementation that is not duocan's.
//!
//! - python's FD frames of 12, 20 and 64 bytes, with and without BRS, with ESI, arrive at a
//!   duocan UDP port with exact bytes and flags; duocan's arrive at python the same way;
//! - a duocan node serving USDO (CiA 1301) answers python's hand-built USDO requests (an
//!   expedited read and an expedited write), and python sees the answer's exact bytes;
//! - duocan's front door reads and writes a duocan node over USDO across the UDP bus, and
//!   python, listening on the same bus, sees the requests and answers as CAN FD frames with
//!   BRS on the identifiers CiA 1301 gives them;
//! - the `duocan` tool, a process of its own (`--fd`), reads and writes that node over USDO.
//!
//! Needs a private network namespace with loopback multicast, `DUOCAN_PYTHON` pointing at a
//! python with `python-can`, and the tool built (`cargo build -p duocan-cli`):
//! `.ci/tier-python.sh` sees to all three. Without them the test fails.

#[path = "common/peer.rs"]
mod peer;
#[path = "../../tests/common/runtime.rs"]
mod rt;
#[path = "common/tool.rs"]
mod tool;

use duocan::machine::{SinglePort, Station};
use duocan::net::{NetOptions, Network};
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::port::{AnyInput, Port};
use duocan::runtime::{Handle, Runtime};
use duocan::{FdFrame, Id, NodeId};
use peer::{group, Peer};
use rt::{pattern, sdo_node, TestNode};
use std::time::Duration;

fn hex(b: &[u8]) -> String {
    if b.is_empty() {
        return "-".into();
    }
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// The line `peer.py` prints for a CAN FD frame it received.
fn rx_line(f: &FdFrame) -> String {
    let (raw, ext) = match f.id() {
        Id::Standard(r) => (u32::from(r), 0),
        Id::Extended(r) => (r, 1),
    };
    format!(
        "RX {raw:x} {ext} 1 {} {} {} {}",
        u8::from(f.brs()),
        u8::from(f.esi()),
        f.len(),
        hex(f.data())
    )
}

/// The command that makes `peer.py rawfd` send `f`.
fn send_line(f: &FdFrame) -> String {
    let (raw, ext) = match f.id() {
        Id::Standard(r) => (u32::from(r), 0),
        Id::Extended(r) => (r, 1),
    };
    format!(
        "send {raw:x} {ext} {} {} {}",
        u8::from(f.brs()),
        u8::from(f.esi()),
        hex(f.data())
    )
}

/// The next CAN FD frame on `port` with identifier `id` (others are skipped).
async fn next_fd(port: &mut UdpPort, id: Id) -> FdFrame {
    tokio::time::timeout(Duration::from_secs(5), async {
        loop {
            match port.recv_any().await.expect("the UDP port reads") {
                AnyInput::Fd(f, _) if f.id() == id => return f,
                _ => {}
            }
        }
    })
    .await
    .unwrap_or_else(|_| panic!("no CAN FD frame on {id:?} within 5 s"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fd_frames_of_every_kind_both_ways_with_exact_bytes_and_flags() {
    let cfg = UdpBusConfig::numbered(43).with_fd();
    let mut port = UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["rawfd", &g, &p]).await;
    let fd = |id, data: &[u8]| FdFrame::new(id, data).unwrap();
    let from_python = [
        fd(Id::Standard(0x181), &pattern(12, 1)).with_brs(true),
        fd(Id::Standard(0x182), &pattern(12, 2)),
        fd(Id::Standard(0x183), &pattern(20, 3)).with_brs(true),
        fd(Id::Standard(0x184), &pattern(20, 4)).with_esi(true),
        fd(Id::Standard(0x185), &pattern(64, 5))
            .with_brs(true)
            .with_esi(true),
        fd(Id::Extended(0x1ABC_DE01), &pattern(64, 6)),
    ];
    for f in &from_python {
        peer.send_line(&send_line(f)).await;
        peer.expect("SENT", 5).await;
        let got = next_fd(&mut port, f.id()).await;
        assert_eq!(got, *f, "python's frame arrived with its bytes and flags");
        assert_eq!(
            (got.len(), got.brs(), got.esi()),
            (f.len(), f.brs(), f.esi())
        );
    }

    let from_duocan = [
        fd(Id::Standard(0x281), &pattern(12, 7)).with_brs(true),
        fd(Id::Standard(0x282), &pattern(20, 8)).with_esi(true),
        fd(Id::Standard(0x283), &pattern(64, 9))
            .with_brs(true)
            .with_esi(true),
        fd(Id::Standard(0x284), &pattern(64, 10)),
        fd(Id::Extended(0x1ABC_DE02), &pattern(20, 11)).with_brs(true),
    ];
    for f in &from_duocan {
        port.send_fd(f).await.unwrap();
        let prefix = rx_line(f);
        let prefix = prefix.split(' ').take(2).collect::<Vec<_>>().join(" ");
        assert_eq!(
            peer.expect(&prefix, 5).await,
            rx_line(f),
            "duocan's frame as python-can received it"
        );
    }
    assert_eq!(port.counters().snapshot().rx_invalid, 0);
    peer.stop().await;
}

type FdStation = Station<SinglePort, TestNode>;

/// Node `id` with the SDO test entries, configured for FD, on its own FD UDP port, booted.
async fn fd_node(cfg: &UdpBusConfig, id: u8) -> Handle<FdStation> {
    let mut classic = sdo_node(id, false, 0, &[]);
    let od = std::mem::replace(classic.od_mut(), duocan::od::DynamicDictionary::new(id));
    let n = TestNode::new(
        duocan::NodeConfig::slave(NodeId::must(id)).with_fd(true),
        od,
    );
    let s = Runtime::new(Station::new(SinglePort::fd(), n))
        .name("fd node")
        .port(UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)"))
        .spawn()
        .unwrap();
    s.boot().await.unwrap();
    s
}

/// python, as a raw USDO client of node-ID 0x10, reads and writes a duocan node's dictionary
/// with requests it builds byte by byte; the answers are checked byte by byte.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_duocan_node_answers_python_usdo_requests() {
    let cfg = UdpBusConfig::numbered(44).with_fd();
    let node = fd_node(&cfg, 5).await;
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["rawfd", &g, &p]).await;
    // Each answer is awaited by its identifier alone: python's listener may print it before
    // the sender's "SENT" line, which `expect` would then have skipped past.

    // Expedited read of 0x1018:01 (vendor-ID 0x1234), session 7: destination 5, command 0x04,
    // session, index, sub, type and length unused.
    peer.send_line("send 610 0 1 0 0504071810010000").await;
    // The answer on 0x585 to client 0x10: command 0x44, the same session, index and sub,
    // UNSIGNED32 (7), 4 bytes; 12 bytes in all, BRS on.
    assert_eq!(
        peer.expect("RX 585", 5).await,
        "RX 585 0 1 1 0 12 104407181001070434120000"
    );

    // Expedited write of 250 to 0x1017:00 (UNSIGNED16, 6), session 8, padded with 0xCC to the
    // 12-byte FD length.
    peer.send_line("send 610 0 1 0 0501081710000602fa00cccc")
        .await;
    assert_eq!(
        peer.expect("RX 585", 5).await,
        "RX 585 0 1 1 0 8 1041081710000000"
    );
    assert_eq!(node.read(0x1017, 0).await.unwrap(), 250u16.to_le_bytes());

    // A read of an entry the node does not have: an abort in the same session (9).
    peer.send_line("send 610 0 1 0 0504093412000000").await;
    let abort = peer.expect("RX 585", 5).await;
    assert!(
        abort.starts_with("RX 585 0 1 1 0 8 1080093412"),
        "an abort of session 9 for 0x1234:00, got {abort}"
    );
    peer.stop().await;
    node.shutdown().await;
}

/// duocan's front door on its own UDP port reads and writes a duocan node over USDO; python
/// sees the exchange on the bus.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_door_reads_a_duocan_node_over_usdo_and_python_sees_fd_frames() {
    let cfg = UdpBusConfig::numbered(45).with_fd();
    let node = fd_node(&cfg, 5).await;
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["rawfd", &g, &p]).await;
    let opts = NetOptions::default()
        .with_sdo_timeout(Duration::from_millis(500))
        .with_fd(NodeId::must(127));
    let door = UdpPort::open(cfg.clone()).expect("open the UDP bus (inside unshare -n?)");
    let net = Network::open_with(door, opts).unwrap();
    let n5 = net.node(5);

    assert_eq!(n5.sdo().read::<u32>(0x1018, 1).await.unwrap(), 0x1234);
    // The request on 0x600 + 127 to server 5, its answer on 0x585 to client 127: CAN FD, BRS.
    let req = peer.expect("RX 67f", 5).await;
    assert!(req.starts_with("RX 67f 0 1 1 0 8 0504"), "request {req}");
    let ans = peer.expect("RX 585", 5).await;
    assert!(
        ans.starts_with("RX 585 0 1 1 0 12 7f44") && ans.ends_with("181001070434120000"),
        "answer {ans}"
    );

    // A segmented write and read back of 300 bytes (five 60-byte segments each way).
    let blob = pattern(300, 3);
    n5.sdo().write_bytes(0x2002, 0, blob.clone()).await.unwrap();
    assert_eq!(node.read(0x2002, 0).await.unwrap(), blob);
    assert_eq!(n5.sdo().read_bytes(0x2002, 0).await.unwrap(), blob);
    // python saw the ten segments (five each way) as 64-byte CAN FD frames with BRS.
    let mut full = 0;
    while full < 10 {
        let l = peer.expect("RX", 5).await;
        if l.contains(" 1 1 0 64 ") {
            full += 1;
        }
    }
    peer.stop().await;
    node.shutdown().await;
}

/// `duocan --bus <bus> --fd 126 <args>`: the tool as a USDO client of node-ID 126.
async fn tool_fd(bus: &str, args: &[&str]) -> (i32, String, String) {
    let mut all = vec!["--fd", "126"];
    all.extend_from_slice(args);
    tool::duocan(bus, &all).await
}

/// The `duocan` tool, in a process of its own, reads and writes a duocan node over USDO
/// (`--fd`); python sees the tool's requests as CAN FD frames on 0x600 + the tool's node-ID.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tool_in_its_own_process_reads_and_writes_a_duocan_node_over_usdo() {
    let cfg = UdpBusConfig::numbered(46).with_fd();
    let node = fd_node(&cfg, 5).await;
    let (g, p) = group(&cfg);
    let mut peer = Peer::spawn(&["rawfd", &g, &p]).await;
    let bus = "udp:46";
    let (code, out, err) = tool_fd(bus, &["sdo", "read", "5", "0x1018", "1"]).await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.trim(), "[34 12 00 00] = 4660 (0x00001234)");
    let req = peer.expect("RX 67e", 5).await;
    assert!(req.starts_with("RX 67e 0 1 1 0 8 0504"), "request {req}");

    // 130 bytes: segmented both ways (60 bytes a segment).
    let blob: String = pattern(130, 9)
        .iter()
        .map(|b| format!("{b:02x} "))
        .collect();
    let (code, _, err) = tool_fd(
        bus,
        &["sdo", "write", "5", "0x2002", "0", "hex", blob.trim()],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(node.read(0x2002, 0).await.unwrap(), pattern(130, 9));
    let (code, out, err) = tool_fd(bus, &["sdo", "read", "5", "0x2002", "0", "hex"]).await;
    assert_eq!(code, 0, "{err}");
    let want: Vec<String> = pattern(130, 9).iter().map(|b| format!("{b:02x}")).collect();
    let got: Vec<String> = out.split_whitespace().map(str::to_lowercase).collect();
    assert_eq!(got, want, "the tool read {out:?}");

    // An entry the node does not have: the tool says so and exits non-zero.
    let (code, _, err) = tool_fd(bus, &["sdo", "read", "5", "0x2fff", "0"]).await;
    assert_eq!(code, 1);
    assert!(err.contains("object 0x2fff sub 0"), "{err}");
    peer.stop().await;
    node.shutdown().await;
}
