//! CANopenNode as the device, duocan as the master, on real SocketCAN (vcan0 inside duocan's
//! qemu VM: `.ci/tier-vcan.sh`). `canopend` (CANopenNode's Linux device with its example
//! dictionary, built statically by `../shared/peers/canopennode/build.sh` on the host) runs as
//! node 4, a fresh process per test; duocan talks to it through its front door
//! (`duocan::net::Network`) and, for the scan, through the `duocan` tool as a user would:
//!
//! - the tool's `scan` finds it, with the identity (0x1018) its EDS describes;
//! - SDO both ways in every mode the dictionary allows, each checked on the wire (a tap on the
//!   port): expedited, segmented download, block download and block upload with CRC, and the
//!   server's aborts. Segmented upload cannot be asked for: the server picks it only for more
//!   than 4 bytes, and the example dictionary has nothing longer;
//! - NMT start, stop and pre-operational, each seen in its heartbeat; the heartbeat consumer
//!   reports the loss when the process is killed;
//! - PDOs configured by SDO (mapping, transmission type, event timer) both ways: its TPDO
//!   received decoded and named by its EDS, an RPDO sent that it writes into its dictionary;
//! - an EMCY: canopend's own heartbeat consumer, set up by SDO, times out on a node that was
//!   heard once (0x8130), and its error history (0x1003) says the same;
//! - LSS both ways: duocan's LSS master configures a canopend started without a node-ID
//!   (fastscan, node-ID, bit timing, store), and canopend's gateway, driven by `cocomm`,
//!   configures a duocan LSS slave (the tool's `device lss-slave`);
//! - the tool's `eds export` of canopend, by a scan and from its EDS, agrees with the EDS it
//!   ships entry by entry;
//! - the tool's `dump` and `monitor`, listening while canopend boots, is configured by SDO,
//!   stopped and started and sends an EMCY, decode each of those frames (boot-up, SDO,
//!   heartbeat states, NMT, EMCY with its code), and the monitor never takes its heartbeat,
//!   sent at once on each state change, for silent;
//! - the same `cocomm` requests sent to canopend's gateway and to duocan's, both talking to
//!   the same canopend device: the answers differ only as duocan's gateway documents;
//! - two canopend processes as the A/B pair of two duocan redundant masters, through the
//!   failover kit's fault bridge (the scenario `cli/scenarios/canopend/board_power_loss.toml`,
//!   on the kit's interfaces vm1a … vs2b): board A loses power, board B is started within the
//!   pair's bound and runs, one start, each frame once; and the kit's verdicts on that run's
//!   logs fail when the scenario asks for what did not happen.
//!
//! The environment names the files (the VM has them under /tests): `DUOCAN_CANOPEND` (the
//! binary), `DUOCAN_CANOPEND_EDS` (its description), `DUOCAN_COCOMM` (its gateway's client),
//! `DUOCAN_TOOL` (the `duocan` tool). A missing one fails the test, saying which: it is never
//! skipped.

#[path = "../../cli/tests/common/cocomm.rs"]
mod cocomm;
#[path = "../../cli/tests/common/eds_compare.rs"]
mod eds_compare;

use cocomm::{check_answers, cocomm_socket, script};
use duocan::capture::recorder::{Tap, TapDirection, TapPoint};
use duocan::cia305::{
    BitTiming, Inquiry, LssAddress, LssError, LssMasterConfig, LssMode, LssPlan, LssService,
};
use duocan::net::{NetError, NetEvent, NetOptions, Network, SIM_VENDOR};
use duocan::port::socketcan::SocketCanPort;
use duocan::port::Port;
use duocan::sdo::{SdoErrorKind, TransferMode};
use duocan::{Frame, Id, Instant, NmtState, NodeId};
use eds_compare::{differences, read_eds};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// canopend's node-ID.
const NODE: u8 = 4;
/// Its SDO server's request and answer identifiers.
const REQ: u32 = 0x600 + NODE as u32;
const RESP: u32 = 0x580 + NODE as u32;

/// The file an environment variable names; a panic saying what to set when it is not there.
fn file_from_env(var: &str, what: &str) -> PathBuf {
    let p = std::env::var_os(var).unwrap_or_else(|| {
        panic!("{var} is not set: give the path of {what} (.ci/tier-vcan.sh builds and sets it)")
    });
    let p = PathBuf::from(p);
    assert!(p.is_file(), "{var}={} is not a file ({what})", p.display());
    p
}

fn canopend_bin() -> PathBuf {
    file_from_env(
        "DUOCAN_CANOPEND",
        "CANopenNode's canopend (../shared/peers/canopennode/build.sh)",
    )
}

fn canopend_eds() -> PathBuf {
    file_from_env(
        "DUOCAN_CANOPEND_EDS",
        "canopend's EDS (canopend.eds, beside the binary build.sh makes)",
    )
}

fn tool_bin() -> PathBuf {
    file_from_env("DUOCAN_TOOL", "the duocan tool (cargo build -p duocan-cli)")
}

/// A program the test started (canopend, the duocan tool), with its own folder and its output
/// in a file there; killed on drop, its output shown when the test failed.
struct Proc {
    what: String,
    child: Option<Child>,
    dir: PathBuf,
}

/// canopend, a [`Proc`].
type Canopend = Proc;

impl Proc {
    /// canopend as node [`NODE`] on vcan0.
    fn start(name: &str) -> Proc {
        Proc::canopend(name, &["-i", &NODE.to_string()])
    }

    /// canopend on vcan0 with `args` after the interface (`-i` its node-ID, `-c` its
    /// gateway), with its own storage folder (so nothing one test stores reaches the next).
    fn canopend(name: &str, args: &[&str]) -> Proc {
        let dir = Proc::folder(&format!("canopend-{name}"));
        // Its two storage files, "empty" as canopend reads them (a '-' and one more byte: the
        // defaults, no error). Without them it reports a storage error (EMCY 0x5000), sets the
        // generic bit of its error register and refuses to go operational.
        for f in ["od_comm.persist", "mainline.persist"] {
            std::fs::write(dir.join(format!("od_{f}")), "-\n").expect("canopend's storage file");
        }
        let storage = dir.join("od_").display().to_string();
        let mut all = vec!["vcan0"];
        all.extend_from_slice(args);
        all.extend(["-s", &storage]);
        Proc::spawn("canopend", &canopend_bin(), &all, dir)
    }

    /// The duocan tool with `args`.
    fn tool(name: &str, args: &[&str]) -> Proc {
        let dir = Proc::folder(&format!("duocan-{name}"));
        Proc::spawn("duocan", &tool_bin(), args, dir)
    }

    /// A new empty folder.
    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(name);
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("a test folder");
        dir
    }

    fn spawn(what: &str, bin: &Path, args: &[&str], dir: PathBuf) -> Proc {
        let log = std::fs::File::create(dir.join("log")).expect("the output file");
        let child = Command::new(bin)
            .args(args)
            .current_dir(&dir)
            .env_remove("DUOCAN_BUS")
            .stdin(Stdio::null())
            .stdout(log.try_clone().expect("log"))
            .stderr(log)
            .spawn()
            .unwrap_or_else(|e| panic!("start {}: {e}", bin.display()));
        Proc {
            what: what.into(),
            child: Some(child),
            dir,
        }
    }

    /// What it printed.
    fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("log")).unwrap_or_default()
    }

    /// Waits until it has printed `text`, at most `timeout`; panics saying what it printed
    /// instead (or that it exited).
    fn wait_for_output(&mut self, text: &str, timeout: Duration) {
        let deadline = std::time::Instant::now() + timeout;
        while !self.log().contains(text) {
            self.assert_running();
            assert!(
                std::time::Instant::now() < deadline,
                "{} did not print {text:?} within {timeout:?}; it printed:\n{}",
                self.what,
                self.log()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Kills it and waits for it.
    fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    /// Panics if it has exited.
    fn assert_running(&mut self) {
        if let Some(c) = self.child.as_mut() {
            if let Ok(Some(st)) = c.try_wait() {
                panic!("{} exited ({st}):\n{}", self.what, self.log());
            }
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        self.kill();
        if std::thread::panicking() {
            eprintln!("{}'s output:\n{}", self.what, self.log());
        }
    }
}

/// Every frame on the port, in order: (sent by duocan, identifier, data).
#[derive(Default)]
struct Wire(Mutex<Vec<(bool, u32, Vec<u8>)>>);

impl Tap for Wire {
    fn frame(&self, _at: Instant, point: TapPoint, dir: TapDirection, f: &Frame) {
        if point == TapPoint::Port(0) {
            let sent = dir == TapDirection::Tx;
            self.0
                .lock()
                .unwrap()
                .push((sent, f.id().raw(), f.data().to_vec()));
        }
    }
}

impl Wire {
    /// How many frames there are so far (a mark to look from).
    fn mark(&self) -> usize {
        self.0.lock().unwrap().len()
    }

    /// The command bytes of the SDO frames since `mark`: requests to the node, answers from it.
    fn sdo_since(&self, mark: usize) -> (Vec<u8>, Vec<u8>) {
        let all = self.0.lock().unwrap();
        let mut req = vec![];
        let mut resp = vec![];
        for (sent, id, data) in &all[mark..] {
            match (*sent, *id) {
                (true, REQ) => req.push(data[0]),
                (false, RESP) => resp.push(data[0]),
                _ => {}
            }
        }
        (req, resp)
    }
}

/// The network on vcan0 with a tap, and node 4 with canopend's EDS attached.
fn open() -> (Network, Arc<Wire>) {
    open_with(NetOptions::default())
}

/// [`open`] with `options` (the SDO timeout and the tap are set here).
fn open_with(options: NetOptions) -> (Network, Arc<Wire>) {
    let wire = Arc::new(Wire::default());
    let port = SocketCanPort::open("vcan0").expect("open vcan0");
    let net = Network::open_with(
        port,
        options
            .with_sdo_timeout(Duration::from_millis(1500))
            .with_tap(wire.clone()),
    )
    .expect("open the network on vcan0");
    net.add_node_eds(NODE, canopend_eds())
        .expect("read canopend's EDS");
    (net, wire)
}

/// canopend started after the network, its boot-up awaited.
async fn boot(net: &Network, name: &str) -> Canopend {
    let node = net.node(NODE);
    let mut dev = Canopend::start(name);
    if let Err(e) = node.wait_for_boot_up(Duration::from_secs(10)).await {
        dev.assert_running();
        panic!("no boot-up from canopend: {e}\n{}", dev.log());
    }
    dev
}

/// The server's abort code of a failed transfer.
fn abort(r: Result<impl std::fmt::Debug, NetError>) -> u32 {
    match r {
        Err(NetError::Sdo(e)) => match e.kind {
            SdoErrorKind::Server(c) => c.0,
            k => panic!("not a server abort: {k:?}"),
        },
        other => panic!("not an SDO abort: {other:?}"),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tools_scan_finds_canopend_with_the_identity_its_eds_gives() {
    let tool = tool_bin();
    let eds = canopend_eds();
    // Booted (its boot-up seen) before the scan starts: found by the scan's SDO probe.
    let (net, _wire) = open();
    let _dev = boot(&net, "scan").await;
    net.close().await;
    let out = Command::new(&tool)
        .args(["--bus", "vcan0", "--json", "--eds"])
        .arg(format!("{NODE}={}", eds.display()))
        .args(["scan", "--listen", "300", "--probe-timeout", "300"])
        .env_remove("DUOCAN_BUS")
        .output()
        .expect("run duocan scan");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "duocan scan: {}\n{stdout}{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    let rows: serde_json::Value = serde_json::from_str(&stdout).expect("scan --json");
    let rows = rows.as_array().expect("an array");
    assert_eq!(rows.len(), 1, "one node on vcan0: {stdout}");
    let r = &rows[0];
    assert_eq!(r["node"], NODE, "{stdout}");
    // The example dictionary's identity and device type are all zeros, as its EDS says; the
    // description column names the EDS when the identity matches it.
    for col in ["device_type", "vendor", "product", "revision", "serial"] {
        assert_eq!(r[col], 0, "{col}: {stdout}");
    }
    assert_eq!(r["description"], "canopend.eds", "{stdout}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tools_eds_export_of_canopend_agrees_with_the_eds_it_ships() {
    let eds = canopend_eds();
    let (net, _wire) = open();
    let dev = boot(&net, "export").await;
    net.close().await;
    let shipped = read_eds(&eds);
    // Read by a scan of 0x1000-0x1FFF (canopend's example dictionary has nothing beyond), and
    // from the EDS attached: every entry the EDS lists, with its type, object type, access
    // and default as the value read. The one difference allowed: `const` where the EDS says
    // `ro` (0x1000, 0x1018, a record's sub-index 0), CiA 301's access in the scan's catalog;
    // both are read-only, and SDO cannot tell them apart.
    let attach = format!("{NODE}={}", eds.display());
    for (how, args) in [
        ("scan", vec![]),
        ("description", vec!["--eds", attach.as_str()]),
    ] {
        let file = dev.dir.join(format!("{how}.eds"));
        let node = NODE.to_string();
        let mut all = vec!["--bus", "vcan0"];
        all.extend(args);
        all.extend(["eds", "export", &node, "-o", file.to_str().unwrap()]);
        let out = Command::new(tool_bin())
            .args(&all)
            .env_remove("DUOCAN_BUS")
            .output()
            .expect("run duocan eds export");
        assert!(
            out.status.success(),
            "duocan {all:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let diff = differences(&shipped, &read_eds(&file), NODE, 0..=0xFFFF);
        assert!(
            diff.is_empty(),
            "the export ({how}) differs from canopend's EDS:\n{}",
            diff.join("\n")
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sdo_both_ways_expedited_segmented_and_block_with_crc() {
    let (net, wire) = open();
    let _dev = boot(&net, "sdo").await;
    let node = net.node(NODE);
    let sdo = node.sdo();

    // Expedited, both ways: the heartbeat period by index and by the EDS's name.
    let m = wire.mark();
    let dt: u32 = sdo.read(0x1000, 0).await.expect("read 0x1000");
    assert_eq!(dt, 0);
    sdo.clone()
        .with_mode(TransferMode::Expedited)
        .write(0x1017, 0, 250u16)
        .await
        .expect("write 0x1017");
    let hb: u16 = sdo
        .read_named("Producer heartbeat time")
        .await
        .expect("read 0x1017 by name");
    assert_eq!(hb, 250);
    let (req, resp) = wire.sdo_since(m);
    // upload initiate, expedited download of 2 bytes (0x2B), upload initiate
    assert_eq!(req, [0x40, 0x2B, 0x40], "requests {req:02x?}");
    // expedited answers: 4 bytes (0x43), download done (0x60), 2 bytes (0x4B)
    assert_eq!(resp, [0x43, 0x60, 0x4B], "answers {resp:02x?}");

    // Segmented download of a 4-byte value (the consumer heartbeat entry 0x1016:1).
    let m = wire.mark();
    let watch_5 = (5u32 << 16) | 1000;
    sdo.clone()
        .with_mode(TransferMode::Segmented)
        .write(0x1016, 1, watch_5)
        .await
        .expect("segmented write of 0x1016:1");
    let (req, resp) = wire.sdo_since(m);
    // initiate with the size (0x21), one last segment of 4 bytes (toggle 0, 3 unused, last:
    // 0x07); the server's initiate answer (0x60) and the segment's (0x20).
    assert_eq!(req, [0x21, 0x07], "requests {req:02x?}");
    assert_eq!(resp, [0x60, 0x20], "answers {resp:02x?}");
    // A read asked as segmented: the server answers 4 bytes expedited (its choice).
    let back: u32 = sdo
        .clone()
        .with_mode(TransferMode::Segmented)
        .read(0x1016, 1)
        .await
        .expect("read 0x1016:1");
    assert_eq!(back, watch_5);

    // Block download and block upload with CRC (0x1016:2).
    let watch_6 = (6u32 << 16) | 2000;
    let block = sdo.clone().with_mode(TransferMode::Block);
    let m = wire.mark();
    block
        .write(0x1016, 2, watch_6)
        .await
        .expect("block write of 0x1016:2");
    let (req, resp) = wire.sdo_since(m);
    // initiate with CRC and size (0xC6), one segment, last (0x81), end with 0 unused bytes
    // after the 4 (7 - 4 = 3 unused: 0xC1 | 3 << 2 = 0xCD).
    assert_eq!(req, [0xC6, 0x81, 0xCD], "requests {req:02x?}");
    // initiate answer with CRC (0xA4), the sub-block's acknowledgement (0xA2), end (0xA1).
    assert_eq!(resp, [0xA4, 0xA2, 0xA1], "answers {resp:02x?}");
    let m = wire.mark();
    let back: u32 = block.read(0x1016, 2).await.expect("block read of 0x1016:2");
    assert_eq!(back, watch_6);
    let (req, resp) = wire.sdo_since(m);
    // initiate with CRC (0xA4), start (0xA3), the sub-block's acknowledgement (0xA2), end (0xA1).
    assert_eq!(req, [0xA4, 0xA3, 0xA2, 0xA1], "requests {req:02x?}");
    // initiate answer with CRC and size (0xC6), the segment, last (0x81), end: 3 unused,
    // CRC (0xCD).
    assert_eq!(resp, [0xC6, 0x81, 0xCD], "answers {resp:02x?}");

    // The server's aborts: no such object, read-only, a value of the wrong length.
    assert_eq!(abort(sdo.read::<u32>(0x2000, 0).await), 0x0602_0000);
    assert_eq!(abort(sdo.write(0x1000, 0, 1u32).await), 0x0601_0002);
    assert_eq!(abort(sdo.write(0x1017, 0, 1u32).await), 0x0607_0012);
    // After them the server still answers.
    let hb: u16 = sdo.read(0x1017, 0).await.expect("read 0x1017 again");
    assert_eq!(hb, 250);
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nmt_commands_show_in_the_heartbeat_and_its_loss_is_reported() {
    let (net, _wire) = open();
    let mut dev = boot(&net, "nmt").await;
    let node = net.node(NODE);
    let t = Duration::from_secs(3);
    // canopend's example dictionary sends no heartbeat until 0x1017 is set.
    node.sdo()
        .write(0x1017, 0, 100u16)
        .await
        .expect("write 0x1017");
    // It goes operational by itself once booted (its NMT start-up setting).
    node.wait_for_state(NmtState::Operational, t)
        .await
        .expect("heartbeat: operational");
    node.watch_heartbeat(Duration::from_millis(600))
        .await
        .expect("watch the heartbeat");
    let mut events = net.events();
    for (state, cmd) in [
        (NmtState::PreOperational, "enter pre-operational"),
        (NmtState::Operational, "start"),
        (NmtState::Stopped, "stop"),
        (NmtState::PreOperational, "enter pre-operational"),
        (NmtState::Operational, "start"),
    ] {
        match cmd {
            "start" => node.start().await,
            "stop" => node.stop().await,
            _ => node.enter_pre_operational().await,
        }
        .unwrap_or_else(|e| panic!("NMT {cmd}: {e}"));
        node.wait_for_state(state, t)
            .await
            .unwrap_or_else(|e| panic!("after NMT {cmd}: {e}"));
        assert_eq!(node.state().await.unwrap(), Some(state));
    }
    // Stopped: no SDO; operational: SDO again.
    node.stop().await.unwrap();
    node.wait_for_state(NmtState::Stopped, t).await.unwrap();
    let r = node
        .sdo()
        .with_options(
            duocan::sdo::SdoOptions::default().with_timeout(duocan::Duration::from_millis(300)),
        )
        .read::<u16>(0x1017, 0)
        .await;
    assert!(r.is_err(), "a stopped node answered SDO: {r:?}");
    node.start().await.unwrap();
    node.wait_for_state(NmtState::Operational, t).await.unwrap();
    let hb: u16 = node
        .sdo()
        .read(0x1017, 0)
        .await
        .expect("SDO when operational");
    assert_eq!(hb, 100);

    // Killed: the loss is reported, and it is the first (the stream has every event since the
    // watch began, so a loss during the NMT commands would come first, before the kill).
    let killed_at = net.now();
    dev.kill();
    let lost = tokio::time::timeout(Duration::from_secs(5), async {
        while let Some(e) = events.next().await {
            match e {
                NetEvent::HeartbeatLost { node: n, last, at } if n.raw() == NODE => {
                    return (last, at)
                }
                NetEvent::HeartbeatLost { .. } | NetEvent::NotHeard { .. } => {
                    panic!("unexpected {e:?}")
                }
                _ => {}
            }
        }
        panic!("the event stream ended")
    })
    .await
    .expect("HeartbeatLost within 5 s of the kill");
    let (last, at) = lost;
    assert!(
        at >= killed_at,
        "heartbeat reported lost at {at:?}, before the kill at {killed_at:?}"
    );
    // Declared at the watch's timeout after the last heartbeat (a few ms later in the VM,
    // whose emulated CPU runs the timer late).
    let after = at - last;
    assert!(
        after >= duocan::Duration::from_millis(600) && after < duocan::Duration::from_millis(1000),
        "loss declared {after:?} after the last heartbeat; the watch's timeout is 600 ms"
    );
    net.close().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn pdos_configured_by_sdo_go_both_ways() {
    let (net, _wire) = open();
    let _dev = boot(&net, "pdo").await;
    let node = net.node(NODE);
    let tpdo = node.tpdo(1);
    let mut map = tpdo.read().await.expect("read TPDO1's configuration");
    map.clear();
    // The two things canopend's dictionary lets a TPDO carry: the SDO server's request
    // COB-ID (0x1200:1) and the error register (0x1001).
    map.add(0x1200, 1, 32).unwrap();
    map.add(0x1001, 0, 8).unwrap();
    map.transmission_type = 255;
    map.event_timer_ms = Some(100);
    map.enabled = true;
    tpdo.save(&map).await.expect("save TPDO1");
    let back = tpdo.read().await.expect("read TPDO1 back");
    assert_eq!(back.entries.len(), 2);
    assert_eq!(back.event_timer_ms, Some(100));
    assert!(back.enabled);
    node.start().await.unwrap();
    let v = node
        .wait_for_pdo(1, Duration::from_secs(3))
        .await
        .expect("TPDO1 within 3 s");
    assert_eq!(
        v.at(0x1200, 1).and_then(|x| x.as_u64()),
        Some(u64::from(REQ))
    );
    assert_eq!(v.at(0x1001, 0).and_then(|x| x.as_u64()), Some(0));
    // By the names of its EDS, too.
    assert_eq!(
        v.get("COB-ID client to server (rx)")
            .and_then(|x| x.as_u64()),
        Some(u64::from(REQ)),
        "{v:?}"
    );

    // The other way: RPDO1 carries the SDO client's COB-ID (0x1280:1, the one entry canopend
    // lets an RPDO write); a value with bit 31 (not valid) is one it accepts at any time.
    let rpdo = node.rpdo(1);
    let mut map = rpdo.read().await.expect("read RPDO1's configuration");
    map.clear();
    map.add(0x1280, 1, 32).unwrap();
    map.transmission_type = 255;
    map.enabled = true;
    rpdo.save(&map).await.expect("save RPDO1");
    let before: u32 = node.sdo().read(0x1280, 1).await.expect("read 0x1280:1");
    assert_eq!(before, 0x8000_0000);
    let sent = 0x8000_0605u32;
    rpdo.send_named(&[("COB-ID client to server (tx)", sent.into())])
        .await
        .expect("send RPDO1");
    // canopend takes the PDO in its next cycle: read until it shows, at most 2 s.
    let deadline = tokio::time::Instant::now() + Duration::from_secs(2);
    loop {
        let now: u32 = node.sdo().read(0x1280, 1).await.expect("read 0x1280:1");
        if now == sent {
            break;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "0x1280:1 is {now:#010x} 2 s after RPDO1 carried {sent:#010x}"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    net.close().await;
}

/// canopend's heartbeat consumer made to send an EMCY (0x8130): it watches node 0x20's
/// heartbeat, 300 ms, and node 0x20 (a raw port here) sends one and goes silent. The EMCY, and
/// the network's time before the heartbeat.
async fn provoke_emcy(net: &Network) -> (duocan::emcy::EmcyMessage, Instant) {
    let node = net.node(NODE);
    node.sdo()
        .write(0x1016, 1, (0x20u32 << 16) | 300)
        .await
        .expect("write 0x1016:1");
    let mut raw = SocketCanPort::open("vcan0").expect("open vcan0");
    let since = net.now();
    raw.send(&Frame::from_array(Id::Standard(0x720), [0x7F]))
        .await
        .expect("send a heartbeat of 0x20");
    let emcy = node
        .wait_for_emcy(Duration::from_secs(3))
        .await
        .expect("canopend's EMCY within 3 s");
    (emcy, since)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tools_monitor_and_dump_decode_canopends_traffic() {
    let attach = format!("{NODE}={}", canopend_eds().display());
    let mut dump = Proc::tool("dump", &["--bus", "vcan0", "dump"]);
    let mut monitor = Proc::tool(
        "monitor",
        &[
            "--bus", "vcan0", "--eds", &attach, "monitor", "--plain", "--every", "0.5",
        ],
    );
    // Both listening before canopend boots: a heartbeat of node 0x7F until each has shown it,
    // and the monitor a status line (it reads the network's events by then).
    let mut raw = SocketCanPort::open("vcan0").expect("open vcan0");
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while !(dump.log().contains("node 127 heartbeat operational")
        && monitor.log().contains("node 0x7f: operational")
        && monitor.log().contains("status: "))
    {
        dump.assert_running();
        monitor.assert_running();
        assert!(
            std::time::Instant::now() < deadline,
            "the dump and the monitor did not show a heartbeat within 10 s"
        );
        raw.send(&Frame::from_array(Id::Standard(0x77F), [0x05]))
            .await
            .expect("send a heartbeat of 0x7F");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }

    // canopend boots, gets a 300 ms heartbeat and is read by SDO, is stopped and started,
    // and sends an EMCY.
    let (net, _wire) = open();
    let _dev = boot(&net, "decoded").await;
    let node = net.node(NODE);
    let t = Duration::from_secs(3);
    node.sdo()
        .write(0x1017, 0, 300u16)
        .await
        .expect("write 0x1017");
    let vendor: u32 = node.sdo().read(0x1018, 1).await.expect("read 0x1018:1");
    assert_eq!(vendor, 0);
    node.wait_for_state(NmtState::Operational, t).await.unwrap();
    node.stop().await.unwrap();
    node.wait_for_state(NmtState::Stopped, t).await.unwrap();
    node.start().await.unwrap();
    node.wait_for_state(NmtState::Operational, t).await.unwrap();
    let (emcy, _) = provoke_emcy(&net).await;
    assert_eq!(emcy.code, 0x8130, "{emcy:?}");
    net.close().await;

    // The dump: every frame decoded as what it is.
    let w = Duration::from_secs(5);
    for line in [
        "704       node 4 boot-up",
        "604       node 4 SDO download 0x1017:00",
        "584       node 4 SDO download 0x1017:00 accepted",
        "604       node 4 SDO upload 0x1018:01",
        "000       NMT stop node 4",
        "704       node 4 heartbeat stopped",
        "000       NMT start node 4",
        "704       node 4 heartbeat operational",
        "084       node 4 EMCY 0x8130",
    ] {
        dump.wait_for_output(line, w);
    }
    // The monitor: the node's states and its EMCY with the code's meaning; its heartbeat,
    // sent at once on each state change besides every 300 ms, never taken for silent.
    for line in [
        "node 0x04: boot-up",
        "node 0x04: operational",
        "node 0x04: stopped",
        "node 0x04: EMCY 0x8130",
    ] {
        monitor.wait_for_output(line, w);
    }
    let seen = monitor.log();
    assert!(
        !seen.contains("node 0x04 heartbeat silent"),
        "canopend's heartbeat never stopped:\n{seen}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn canopends_heartbeat_consumer_timeout_comes_as_an_emcy() {
    let (net, _wire) = open();
    let _dev = boot(&net, "emcy").await;
    let node = net.node(NODE);
    let (emcy, since) = provoke_emcy(&net).await;
    assert_eq!(emcy.code, 0x8130, "{emcy:?}");
    // The error register: a communication error.
    assert_eq!(emcy.register & 0x10, 0x10, "{emcy:?}");
    assert!(net.now() - since >= duocan::Duration::from_millis(300));
    // Its error history has it too.
    let n: u8 = node.sdo().read(0x1003, 0).await.expect("read 0x1003:0");
    assert!(n >= 1, "0x1003:0 = {n}");
    let newest: u32 = node.sdo().read(0x1003, 1).await.expect("read 0x1003:1");
    assert_eq!(newest & 0xFFFF, 0x8130, "0x1003:1 = {newest:#010x}");
    net.close().await;
}

/// LSS on the VM's emulated CPU: each answer may take 300 ms; an answered fastscan step ends
/// 20 ms after its last answer.
fn lss_options() -> NetOptions {
    let ms = duocan::Duration::from_millis;
    NetOptions::default().with_lss(
        LssMasterConfig::default()
            .with_timeout(ms(300))
            .with_settle(ms(20)),
    )
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn duocans_lss_master_configures_a_canopend_started_without_a_node_id() {
    let (net, _wire) = open_with(lss_options());
    let lss = net.lss();
    let (first, second) = (NodeId::new(0x0A).unwrap(), NodeId::new(0x0B).unwrap());
    let node = net.node(first.raw());
    let mut dev = Canopend::canopend("lss-master", &["-i", "0xFF"]);
    // It sends nothing without a node-ID, and its LSS slave has no identify services
    // (CANopenNode's CO_LSSslave.c serves switching, configuration, inquiry and fastscan
    // only): up once it says it runs.
    dev.wait_for_output("running", Duration::from_secs(10));
    // Fastscan finds it by its identity (the example dictionary's: all zeros), gives it 0x0A,
    // stores it, and switches it back to waiting: it boots with it and answers SDO there.
    let canopend = LssAddress::default();
    let scan = lss
        .fastscan(LssPlan::new().with_free([first]).with_store(true))
        .await
        .expect("fastscan");
    assert_eq!(scan.assigned, [(canopend, first)], "{scan:?}");
    assert_eq!(scan.stopped, None, "{scan:?}");
    node.wait_for_boot_up(Duration::from_secs(5))
        .await
        .expect("canopend's boot-up as 0x0A");
    let serial: u32 = node.sdo().read(0x1018, 4).await.expect("SDO to 0x0A");
    assert_eq!(serial, canopend.serial);

    // Selected by its address: the node-ID inquired, a new one given and stored.
    lss.switch_selective(canopend)
        .await
        .expect("switch state selective");
    assert_eq!(lss.inquire(Inquiry::NodeId).await.unwrap(), 0x0A);
    assert_eq!(lss.inquire(Inquiry::Serial).await.unwrap(), canopend.serial);
    lss.configure_node_id(second.raw())
        .await
        .expect("configure node-ID");
    // canopend has no bit rate to set: its program registers no bit-rate check with its LSS
    // slave, which then drops configure bit timing unanswered (CANopenNode's CO_LSSslave.c).
    // The master says no slave answered.
    match lss.configure_bit_timing(BitTiming::standard(2)).await {
        Err(NetError::Lss(LssError::Timeout(LssService::ConfigureBitTiming))) => {}
        other => panic!("configure bit timing (500 kbit/s) of canopend: {other:?}"),
    }
    lss.store().await.expect("store configuration");
    lss.switch_global(LssMode::Waiting).await.unwrap();
    // A node that has a node-ID takes the new one at its next communication reset.
    let moved = net.node(second.raw());
    node.reset_communication().await.unwrap();
    moved
        .wait_for_boot_up(Duration::from_secs(5))
        .await
        .expect("canopend's boot-up as 0x0B");
    let serial: u32 = moved.sdo().read(0x1018, 4).await.expect("SDO to 0x0B");
    assert_eq!(serial, canopend.serial);
    net.close().await;
}

/// canopend as node `node` with its 309-3 gateway on a local socket in its folder; the
/// socket's path once it is there.
fn canopend_with_gateway(name: &str, node: u8) -> (Canopend, PathBuf) {
    let sock = std::env::temp_dir()
        .join(format!("canopend-{name}"))
        .join("gw.sock");
    let mut dev = Canopend::canopend(
        name,
        &[
            "-i",
            &node.to_string(),
            "-c",
            &format!("local-{}", sock.display()),
        ],
    );
    // It says so once the socket is there.
    dev.wait_for_output(
        &format!("local socket \"{}\" started", sock.display()),
        Duration::from_secs(10),
    );
    (dev, sock)
}

#[test]
fn canopends_gateway_as_lss_master_configures_a_duocan_lss_slave() {
    let (_dev, sock) = canopend_with_gateway("lss-gateway", NODE);
    let mut slave = Proc::tool(
        "lss-slave",
        &["--bus", "vcan0", "device", "lss-slave", "--serial", "7"],
    );
    slave.wait_for_output("on vcan0", Duration::from_secs(10));
    let select = format!("[1] lss_switch_sel 0x{SIM_VENDOR:08X} 0x305 1 7");
    let address = format!("0x{SIM_VENDOR:08X} 0x00000305 0x00000001 0x00000007");
    // Selected by its address (switch state selective). Not by CANopenNode's fastscan: that
    // waits its whole timeout at each of its 133 steps and takes a late answer for none, so
    // on the VM's emulated CPU it needs 100 ms a step (13 s) not to miss one under load.
    let cases: Vec<(&str, String)> = vec![
        (&select, "[1] OK".into()),
        ("[2] lss_inquire_addr", format!("[2] {address}")),
        ("[3] lss_get_node", "[3] 0xFF".into()),
        ("[4] lss_set_node 0x21", "[4] OK".into()),
        ("[5] lss_conf_bitrate 0 2", "[5] OK".into()),
        ("[6] lss_store", "[6] OK".into()),
        ("[7] lss_switch_glob 0", "[7] OK".into()),
        // Back to waiting, it boots with its node-ID and answers canopend's SDO client.
        ("[8] 0x21 r 0x1018 4 u32", "[8] 7".into()),
    ];
    let (out, code) = cocomm_socket(&sock, &script(&cases));
    check_answers(&out, &cases);
    assert_eq!(code, 0, "{out}");
    slave.wait_for_output("boot node-id 0x21", Duration::from_secs(5));
    let log = slave.log();
    let said: Vec<&str> = log.lines().skip(1).collect();
    assert_eq!(
        said,
        [
            "mode configuration",
            "node-id configured 0x21",
            "bit rate configured 500 kbit/s",
            "stored",
            "mode waiting",
            "boot node-id 0x21"
        ],
        "{log}"
    );
}

/// How an answer of duocan's gateway may differ from CANopenNode's to the same request: the
/// differences its module documentation lists (`cli/src/cmd/gateway/mod.rs`), and only those.
/// `None`: the same, or a documented difference; else what differs.
fn undocumented(request: &str, theirs: &str, ours: &str) -> Option<String> {
    if theirs == ours {
        return None;
    }
    // "The text behind `#` is duocan's …; the code before it is the same."
    let code = |a: &str| a.split_once(" #").map_or(a, |(c, _)| c).to_string();
    if ours.contains(" ERROR:") && code(theirs) == code(ours) {
        return None;
    }
    let (_, their_answer) = theirs.split_once("] ").unwrap_or(("", theirs));
    // "A request without a readable sequence number is answered `[0] ERROR:101`; CANopenNode
    // answers it with the sequence number of the request before."
    if !request.starts_with('[') && ours.starts_with("[0] ERROR:101") {
        return (!their_answer.starts_with("ERROR:101"))
            .then(|| format!("{request:?}: CANopenNode {theirs:?}, duocan {ours:?}"));
    }
    // "`info version` is answered (309-3 has it); CANopenNode's gateway answers `ERROR:100`.
    // So are the 309-3 types CANopenNode lacks (`i24`…`i56`, `u24`…`u56`, `t`, `td`:
    // `ERROR:101` there)."
    let word = |w: &str| request.split_whitespace().any(|x| x == w);
    let lacks = [
        "i24", "i40", "i48", "i56", "u24", "u40", "u48", "u56", "t", "td",
    ];
    if (word("info") && their_answer.starts_with("ERROR:100"))
        || (lacks.iter().any(|t| word(t)) && their_answer.starts_with("ERROR:101"))
    {
        return ours
            .contains(" ERROR:")
            .then(|| format!("{request:?}: duocan refuses too: {ours:?}"));
    }
    Some(format!(
        "{request:?}: CANopenNode {theirs:?}, duocan {ours:?}"
    ))
}

#[test]
fn the_same_cocomm_requests_get_the_same_answers_from_duocans_gateway_and_canopends() {
    // canopend as node 4 is the device both gateways talk to; canopend's gateway is a second
    // canopend (node 0x10), duocan's the tool's, both on local sockets.
    let _dev = Canopend::start("side-device");
    let (_gw, theirs) = canopend_with_gateway("side-gateway", 0x10);
    let ours = Proc::folder("duocan-side-gw").join("gw.sock");
    let mut duocan_gw = Proc::tool(
        "side-gw",
        &[
            "--bus",
            "vcan0",
            "gateway",
            "--socket",
            ours.to_str().unwrap(),
        ],
    );
    duocan_gw.wait_for_output("listening on", Duration::from_secs(10));
    // Every request starts from the same state: what it writes, it writes the same, and the
    // NMT commands come last.
    let requests = [
        "# a comment",
        "",
        "[1] set node 4",
        "[2] w 0x1017 0 u16 0",
        "[3] r 0x1017 0 u16",
        "[4] w 0x1017 0 u16 300",
        "[5] r 0x1017 0 u16",
        "[6] r 0x1017 0 x16",
        "[7] r 0x1017 0 i16",
        "[8] 4 r 0x1018 1 u32",
        "[9] 0 4 r 0x1018 4 x32",
        "[10] r 0x1000 0 u32",
        "[11] r 0x1001 0 u8",
        "[12] r 0x1005 0 x32",
        "[13] r 0x1014 0 u32",
        "[14] r 0x1018 0 u8",
        "[15] r 0x1200 1 x32",
        "[16] r 0x1017 0 u32",
        "[17] r 0x1017 0 u8",
        "[18] r 0x1018 1 r32",
        "[19] r 0x1016 1 u32",
        "[20] w 0x1016 1 u32 0",
        "[21] w 0x1016 1 x32 0x00000000",
        "[22] r 0x1234 0 u8",
        "[23] r 0x1018 9 u32",
        "[24] w 0x1000 0 u32 1",
        "[25] w 0x1017 0 u32 1",
        "[26] w 0x1017 0 u8 1",
        "[27] r 0x1017 0 q7",
        "[28] w 0x1017 0 u16",
        "[29] r 0x1017",
        "[30] set sdo_timeout 500",
        "[31] set network 2",
        "[32] r 0x1016 2 hex",
        "[33] r 0x1018 2 os",
        "[34] w 0x1016 2 os AAAAAA==",
        "[35] set sdo_block 1",
        "[36] r 0x1016 1 u32",
        "[37] w 0x1016 1 u32 0",
        "[38] set sdo_block 0",
        "5 r 0x1018 1 u32",
        "[39] 5 r 0x1018 1 u32",
        "[40] 200 r 0x1018 1 u32",
        "[41] preop",
        "[42] start",
        "[43] 0 preop",
        "[44] 4 start",
        "[45] info version",
        "[46] r 0x1017 0 u24",
    ];
    let script: String = requests.iter().map(|l| format!("{l}\n")).collect();
    let answers = |sock: &Path| {
        let (out, _) = cocomm_socket(sock, &script);
        let lines: Vec<String> = out.split("\r\n").map(str::to_string).collect();
        assert_eq!(
            lines.len(),
            requests.len() + 1,
            "one answer a request: {out:?}"
        );
        lines
    };
    let (a, b) = (answers(&theirs), answers(&ours));
    let differ: Vec<String> = requests
        .iter()
        .zip(a.iter().zip(&b))
        .filter_map(|(r, (x, y))| undocumented(r, x, y))
        .collect();
    assert!(
        differ.is_empty(),
        "answers that differ otherwise than duocan's gateway documents:\n{}",
        differ.join("\n")
    );
}

/// The failover kit's scenario with canopend as both boards of the pair.
const PAIR_SCENARIO: &str = include_str!("../../cli/scenarios/canopend/board_power_loss.toml");

/// The kit's verdicts (the last line of its `--json` output): expectation, pass, measured.
fn verdicts(stdout: &str) -> Vec<(String, bool, String)> {
    let last = stdout.lines().last().unwrap_or("[]");
    let v: serde_json::Value = serde_json::from_str(last)
        .unwrap_or_else(|e| panic!("the kit's verdicts are not JSON ({e}):\n{stdout}"));
    v.as_array()
        .expect("an array of verdicts")
        .iter()
        .map(|r| {
            (
                r["expectation"].as_str().expect("its name").to_string(),
                r["result"].as_bool().expect("its result"),
                r["measured"].as_str().expect("its figure").to_string(),
            )
        })
        .collect()
}

/// `duocan --json kit ARGS` with canopend on PATH (the scenario names it as a user would).
fn kit(dir: &Path, args: &[&str]) -> (Option<i32>, String, String) {
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).expect("a folder for PATH");
    let link = bin.join("canopend");
    if !link.exists() {
        std::os::unix::fs::symlink(canopend_bin(), &link).expect("canopend on PATH");
    }
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let o = Command::new(tool_bin())
        .args(["--json", "kit"])
        .args(args)
        .current_dir(dir)
        .env("PATH", path)
        .env_remove("DUOCAN_BUS")
        .output()
        .expect("run duocan kit");
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn a_pair_of_canopend_boards_fails_over_under_duocans_redundant_masters_through_the_kit() {
    let dir = Proc::folder("kit-canopend-pair");
    let file = dir.join("board_power_loss.toml");
    std::fs::write(&file, PAIR_SCENARIO).expect("write the scenario");
    let out = dir.join("run");
    let (code, stdout, stderr) = kit(
        &dir,
        &[
            "run",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
    );
    let device_out =
        |d: &str| std::fs::read_to_string(out.join(format!("{d}.out"))).unwrap_or_default();
    let all = || {
        let devices: String = ["master_a", "master_b", "board_a", "board_b"]
            .iter()
            .map(|d| format!("--- {d}:\n{}", device_out(d)))
            .collect();
        format!("{stdout}{stderr}{devices}")
    };
    let v = verdicts(&stdout);
    for (e, pass, measured) in &v {
        println!("{} {e}: {measured}", if *pass { "pass" } else { "FAIL" });
    }
    assert_eq!(v.len(), 8, "every expectation measured:\n{}", all());
    let failed: Vec<_> = v.iter().filter(|(_, pass, _)| !pass).collect();
    assert!(failed.is_empty(), "failed: {failed:?}\n{}", all());
    assert_eq!(code, Some(0), "{}", all());

    // What the devices themselves say. The active master: A active first, B after A's power
    // loss, nothing else in between (B never took the role while A ran).
    let master = device_out("master_a");
    let roles: Vec<&str> = master
        .lines()
        .filter_map(|l| l.strip_prefix("pair 0x10/0x50: "))
        .collect();
    assert!(
        roles.len() == 2 && roles[0].starts_with("A active") && roles[1].starts_with("B active"),
        "roles {roles:?}\n{}",
        all()
    );
    // canopend B's own log: it went operational by itself, the master sent it back to
    // pre-operational (standby), and it ran again after A's loss, once started.
    let board_b = device_out("board_b");
    let states: Vec<&str> = board_b
        .lines()
        .filter_map(|l| l.split("NMT state changed to: \"").nth(1))
        .filter_map(|l| l.split('"').next())
        .collect();
    let mut want = states.iter().skip_while(|s| **s != "pre-operational");
    assert!(
        want.next().is_some() && want.any(|s| *s == "operational"),
        "canopend B: {states:?}\n{}",
        all()
    );

    // The kit checks what it says it checks with these boards: the same logs, measured
    // against a scenario asking for what did not happen, fail, each on its own figure.
    for (what, from, to, expectation) in [
        (
            "the start came at the pair timeout (300 ms), not within 250 ms",
            "within_ms = 400",
            "within_ms = 250",
            "after board A's last heartbeat, board B gets NMT start",
        ),
        (
            "board B was started before the end",
            "on = [\"vs2b\"]\nto_ms = 4500",
            "on = [\"vs2b\"]\nto_ms = 6500",
            "board B is not started while board A runs",
        ),
        (
            "board B ran after the fault",
            "from_ms = 4000\nto_ms = 4500",
            "from_ms = 5500\nto_ms = 6000",
            "board B waits pre-operational",
        ),
        (
            "board A's power loss silenced it: the master's heartbeat did not stop, A's did",
            "id = 0x701\non = [\"vs2b\"]",
            "id = 0x710\non = [\"vs1a\"]",
            "the master's heartbeat never missing",
        ),
    ] {
        assert!(
            PAIR_SCENARIO.contains(from),
            "{from:?} is no longer in the scenario"
        );
        let wrong = dir.join("wrong.toml");
        std::fs::write(&wrong, PAIR_SCENARIO.replacen(from, to, 1)).expect("write");
        let (code, stdout, stderr) = kit(
            &dir,
            &[
                "check",
                wrong.to_str().unwrap(),
                "--logs",
                out.to_str().unwrap(),
            ],
        );
        let v = verdicts(&stdout);
        let failed: Vec<&str> = v
            .iter()
            .filter(|(_, pass, _)| !pass)
            .map(|(e, _, _)| e.as_str())
            .collect();
        assert!(
            failed.len() == 1 && failed[0].starts_with(expectation),
            "{what}: expected only {expectation:?} to fail, failed: {failed:?}\n{stdout}{stderr}"
        );
        assert_eq!(code, Some(1), "{what}: {stdout}{stderr}");
    }
}
