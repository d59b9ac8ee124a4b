//! LSS (CiA 305) on python-can's UDP bus against a duocan LSS slave (`duocan device
//! lss-slave`, a process of the tool): python `canopen`'s LSS master finds it by fastscan,
//! inquires it, gives it a node-ID, stores it and watches it boot; then the tool's own master
//! (`duocan lss fastscan`) does the same. Runs inside `unshare -n` with the tool built first
//! (`cargo build -p duocan-cli`), `DUOCAN_PYTHON` pointing at a python with python-can and
//! canopen.

#[path = "common/peer.rs"]
mod peer;
#[path = "common/tool.rs"]
mod tool;

use duocan::port::udp::UdpBusConfig;
use peer::{group, Peer};
use std::process::Stdio;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, BufReader};
use tokio::process::{Child, Command};
use tool::{duocan, tool};

/// The slave's identity: duocan's vendor-ID, `device lss-slave`'s default product and revision.
const VENDOR: u32 = 0x00D0_CA00;
const PRODUCT: u32 = 0x305;

/// A `duocan device lss-slave` process and every line it printed so far.
struct Slave {
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
}

impl Slave {
    async fn start(bus: &str, serial: u32, medium: &std::path::Path) -> Slave {
        let mut child = Command::new(tool())
            .args(["--bus", bus, "device", "lss-slave", "--serial"])
            .arg(serial.to_string())
            .arg("--medium")
            .arg(medium)
            .env_remove("DUOCAN_BUS")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .kill_on_drop(true)
            .spawn()
            .expect("run duocan device lss-slave");
        let lines = Arc::new(Mutex::new(Vec::new()));
        let mut out = BufReader::new(child.stdout.take().unwrap()).lines();
        let sink = lines.clone();
        tokio::spawn(async move {
            while let Ok(Some(l)) = out.next_line().await {
                sink.lock().unwrap().push(l);
            }
        });
        // It says where it runs on stderr once its runtime is up.
        let mut err = BufReader::new(child.stderr.take().unwrap()).lines();
        let first = tokio::time::timeout(Duration::from_secs(10), err.next_line())
            .await
            .expect("the slave starts")
            .unwrap()
            .unwrap_or_default();
        assert!(first.starts_with("LSS slave vendor 0x00d0ca00"), "{first}");
        tokio::spawn(async move { while let Ok(Some(_)) = err.next_line().await {} });
        Slave { child, lines }
    }

    /// Waits up to `secs` for the line `want`.
    async fn expect(&self, want: &str, secs: u64) {
        for _ in 0..secs * 20 {
            if self.lines.lock().unwrap().iter().any(|l| l == want) {
                return;
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
        panic!(
            "the slave did not print {want:?}: {:?}",
            self.lines.lock().unwrap()
        );
    }

    async fn stop(mut self) {
        let _ = self.child.start_kill();
        let _ = self.child.wait().await;
    }
}

fn medium(name: &str) -> std::path::PathBuf {
    let p = std::env::temp_dir().join(format!("duocan-lss-{}-{name}.bin", std::process::id()));
    let _ = std::fs::remove_file(&p);
    p
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn python_canopens_lss_master_configures_a_duocan_slave() {
    let cfg = UdpBusConfig::numbered(40);
    let store = medium("python");
    let slave = Slave::start("udp:40", 0x1234, &store).await;
    let (g, p) = group(&cfg);
    let mut py = Peer::spawn(&["lss", "0x20", &g, &p]).await;
    py.send_line("go").await;
    assert_eq!(py.expect("NON-CONFIGURED", 10).await, "NON-CONFIGURED yes");
    // Fastscan finds the whole identity, bit by bit.
    let ident = format!("FASTSCAN True {VENDOR:08X} {PRODUCT:08X} 00000001 00001234");
    assert_eq!(py.expect("FASTSCAN", 60).await, ident);
    slave.expect("mode configuration", 5).await;
    assert_eq!(py.expect("INQUIRED", 10).await, "INQUIRED node-id 255");
    for want in [
        format!("INQUIRED vendor {VENDOR:08X}"),
        format!("INQUIRED product {PRODUCT:08X}"),
        "INQUIRED revision 00000001".to_string(),
        "INQUIRED serial 00001234".to_string(),
    ] {
        assert_eq!(py.expect("INQUIRED", 10).await, want);
    }
    assert_eq!(py.expect("CONFIGURED", 10).await, "CONFIGURED 32");
    slave.expect("node-id configured 0x20", 5).await;
    assert_eq!(py.expect("STORED", 10).await, "STORED");
    slave.expect("stored", 5).await;
    // Switched back to waiting, the slave boots with node-ID 0x20: its first NMT error control
    // frame is the boot-up (0), and its SDO server answers with its serial number.
    assert_eq!(py.expect("BOOT", 10).await, "BOOT 32 0");
    slave.expect("boot node-id 0x20", 5).await;
    assert_eq!(py.expect("SERIAL", 10).await, "SERIAL 34120000");
    assert_eq!(py.expect("SELECTED", 10).await, "SELECTED");
    assert_eq!(py.expect("INQUIRED", 10).await, "INQUIRED node-id 32");
    assert_eq!(py.expect("NON-CONFIGURED", 10).await, "NON-CONFIGURED no");
    py.expect("DONE", 10).await;
    py.stop().await;
    slave.stop().await;

    // Stored: the slave started again on the same medium boots at once with node-ID 0x20.
    let again = Slave::start("udp:40", 0x1234, &store).await;
    let (code, out, err) = duocan(
        "udp:40",
        &["--json", "scan", "--listen", "600", "--no-probe"],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    let rows: serde_json::Value = serde_json::from_str(&out).unwrap();
    let nodes: Vec<u64> = rows
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["node"].as_u64().unwrap())
        .collect();
    assert_eq!(nodes, [0x20], "{out}");
    again.stop().await;
    let _ = std::fs::remove_file(&store);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_tools_fastscan_configures_a_duocan_slave() {
    let store = medium("tool");
    let slave = Slave::start("udp:41", 9, &store).await;
    let (code, out, err) =
        duocan("udp:41", &["--json", "lss", "fastscan", "--assign", "0x30"]).await;
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(
        v["assigned"],
        serde_json::json!([{"vendor": VENDOR, "product": PRODUCT, "revision": 1, "serial": 9, "node": 48, "booted": true}])
    );
    // One board: the frames the protocol needs, to the frame.
    assert_eq!(v["requests"], v["protocol"]["requests"], "{v}");
    assert_eq!(v["answers"], v["protocol"]["answers"], "{v}");
    slave.expect("boot node-id 0x30", 5).await;
    // The booted node answers SDO with its identity.
    let (code, out, err) = duocan("udp:41", &["sdo", "read", "0x30", "0x1018", "4", "u32"]).await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.trim(), "9");
    // Select it by identity, read its node-ID, and nobody is left without one.
    let (code, out, err) = duocan(
        "udp:41",
        &[
            "--json",
            "lss",
            "--select",
            "0xD0CA00:0x305:1:9",
            "inquire",
            "node-id",
        ],
    )
    .await;
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.trim(), r#"{"node_id":48}"#);
    let (code, out, _) = duocan("udp:41", &["--json", "lss", "identify", "--non-configured"]).await;
    assert_eq!((code, out.trim()), (0, r#"{"answered":false}"#));
    slave.stop().await;
    let _ = std::fs::remove_file(&store);
}
