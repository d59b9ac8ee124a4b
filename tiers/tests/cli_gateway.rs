//! `duocan gateway --listen` over TCP, with python `canopen` as the node read and written:
//! a client speaks CiA 309-3 to the tool, the tool speaks CANopen on python-can's UDP bus to a
//! python `LocalNode`, which reports every write it takes and every NMT state it enters.
//! Runs inside `unshare -n` with the tool built first (`.ci/tier-python.sh` does both).

#[path = "../../cli/tests/common/base64.rs"]
mod base64;
#[path = "common/peer.rs"]
mod peer;

#[path = "common/tool.rs"]
mod tool;
use base64::b64;
use duocan::port::udp::UdpBusConfig;
use peer::{group, Peer};
use std::process::Stdio;
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, AsyncWriteExt, BufReader, Lines};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::TcpStream;
use tokio::process::{Child, Command};
use tool::tool;

/// `duocan --bus <bus> gateway --listen 127.0.0.1:0`, and the port it says it serves on.
async fn gateway(bus: &str) -> (Child, u16) {
    let mut child = Command::new(tool())
        .args(["--bus", bus, "gateway", "--listen", "127.0.0.1:0"])
        .env_remove("DUOCAN_BUS")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .expect("run duocan");
    let mut err = BufReader::new(child.stderr.take().expect("stderr piped")).lines();
    let line = tokio::time::timeout(Duration::from_secs(20), err.next_line())
        .await
        .expect("the gateway says where it listens in time")
        .expect("its stderr")
        .expect("a line");
    let port = line
        .strip_prefix("duocan gateway: listening on 127.0.0.1:")
        .and_then(|p| p.parse().ok())
        .unwrap_or_else(|| panic!("not the bound address: {line:?}"));
    (child, port)
}

/// A 309-3 client on one TCP connection.
struct Client {
    r: Lines<BufReader<OwnedReadHalf>>,
    w: OwnedWriteHalf,
}

impl Client {
    async fn connect(port: u16) -> Client {
        let (r, w) = TcpStream::connect(("127.0.0.1", port))
            .await
            .expect("connect to the gateway")
            .into_split();
        Client {
            r: BufReader::new(r).lines(),
            w,
        }
    }

    /// Sends a request; returns its response line.
    async fn ask(&mut self, line: &str) -> String {
        self.w
            .write_all(format!("{line}\r\n").as_bytes())
            .await
            .unwrap();
        let resp = tokio::time::timeout(Duration::from_secs(10), self.r.next_line())
            .await
            .unwrap_or_else(|_| panic!("no response to {line:?} in time"))
            .expect("the connection")
            .unwrap_or_else(|| panic!("the gateway closed the connection at {line:?}"));
        resp.trim_end_matches('\r').to_string()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_309_3_script_over_tcp_reads_writes_and_drives_a_python_node() {
    let cfg = UdpBusConfig::numbered(9);
    let (g, p) = group(&cfg);
    let mut py = Peer::spawn(&["node", "0x22", "100", &g, &p]).await;
    py.expect("STATE PRE-OPERATIONAL", 10).await;
    let (mut tool, port) = gateway("udp:9").await;
    let mut a = Client::connect(port).await;

    // Reads: expedited, with the node given and then by default; segmented.
    assert_eq!(a.ask("[1] 34 r 0x1018 1 u32").await, "[1] 53450");
    assert_eq!(a.ask("[2] set node 0x22").await, "[2] OK");
    assert_eq!(a.ask("[3] read 0x1000 0 x32").await, "[3] 0x00020192");
    assert_eq!(
        a.ask("[4] r 0x2001 0 vs").await,
        "[4] \"python canopen peer: a string longer than four bytes\""
    );
    assert_eq!(a.ask("[5] r 0x1017 0 u16").await, "[5] 100");

    // Writes, seen by the python node.
    assert_eq!(a.ask("[6] w 0x2000 0 u32 0x11223344").await, "[6] OK");
    assert_eq!(py.expect("WRITE", 5).await, "WRITE 2000 0 44332211");
    assert_eq!(a.ask("[7] r 0x2000 0 x32").await, "[7] 0x11223344");
    let text = "written by a \"309-3\" script";
    assert_eq!(
        a.ask(r#"[8] w 0x2001 0 vs "written by a ""309-3"" script""#)
            .await,
        "[8] OK"
    );
    let hex: String = text.bytes().map(|b| format!("{b:02x}")).collect();
    assert_eq!(py.expect("WRITE", 5).await, format!("WRITE 2001 0 {hex}"));
    let blob: Vec<u8> = (0..300u32).map(|i| (i * 31 + 9) as u8).collect();
    let coded = b64(&blob);
    assert_eq!(a.ask(&format!("[9] w 0x2002 0 d {coded}")).await, "[9] OK");
    let hex: String = blob.iter().map(|b| format!("{b:02x}")).collect();
    assert_eq!(py.expect("WRITE", 5).await, format!("WRITE 2002 0 {hex}"));
    assert_eq!(a.ask("[10] r 0x2002 0 d").await, format!("[10] {coded}"));

    // The node's aborts, as the node gave them.
    assert_eq!(
        a.ask("[11] r 0x2fff 0 u8").await,
        "[11] ERROR:0x06020000 #object does not exist in the object dictionary"
    );
    // python's server has no block transfer: it aborts a block download (command specifier
    // unknown) and answers a block upload with a plain one; duocan's client falls back to
    // the plain transfer both ways, so `set sdo_block 1` still works with it.
    assert_eq!(a.ask("[12] set sdo_block 1").await, "[12] OK");
    assert_eq!(a.ask("[13] w 0x2000 0 u32 1").await, "[13] OK");
    assert_eq!(py.expect("WRITE", 5).await, "WRITE 2000 0 01000000");
    assert_eq!(
        a.ask("[14] r 0x2001 0 vs").await,
        format!("[14] \"{}\"", text.replace('"', "\"\""))
    );
    assert_eq!(a.ask("[15] set sdo_block 0").await, "[15] OK");

    // A second client at once, with its own defaults.
    let mut b = Client::connect(port).await;
    assert_eq!(
        b.ask("[1] r 0x1000 0 u32").await,
        "[1] ERROR:105 #no default node set"
    );
    assert_eq!(b.ask("[2] set sdo_timeout 300").await, "[2] OK");
    assert_eq!(
        b.ask("[3] 0x23 r 0x1000 0 u32").await,
        "[3] ERROR:0x05040000 #SDO protocol timed out"
    );
    assert_eq!(b.ask("[4] 34 r 0x1017 0 u16").await, "[4] 100");
    let (ra, rb) = tokio::join!(a.ask("[16] r 0x2000 0 u32"), b.ask("[5] 34 r 0x1018 1 x32"));
    assert_eq!((ra.as_str(), rb.as_str()), ("[16] 1", "[5] 0x0000D0CA"));

    // NMT: the python node enters each state.
    for (req, state) in [
        ("[17] start", "STATE OPERATIONAL"),
        ("[18] stop", "STATE STOPPED"),
        ("[19] preoperational", "STATE PRE-OPERATIONAL"),
        ("[20] 0 start", "STATE OPERATIONAL"),
    ] {
        let n = &req[1..req.find(']').unwrap()];
        assert_eq!(a.ask(req).await, format!("[{n}] OK"));
        py.expect(state, 5).await;
    }
    assert_eq!(
        a.ask("[21] enable guarding 100 3").await,
        "[21] ERROR:100 #request not supported: node guarding: not carried out by this gateway"
    );

    let _ = tool.kill().await;
    py.stop().await;
}
