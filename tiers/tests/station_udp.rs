//! The station on python-can's UDP bus: the shipped SocketCAN station file
//! (`examples/station/vcan.toml`, two racks each on two buses) with its interfaces renamed to
//! UDP buses, run by `duocan station run`, its boards `duocan device board` processes on the
//! same buses, watched through the station's REST API. The A board of the turnout rack is
//! killed: that rack runs B, the signal rack (buses of its own) keeps A; SIGTERM stops the
//! station cleanly with the switch-over in its audit trail. Runs inside `unshare -n` with the
//! tool built first (`.ci/tier-python.sh` does both); the VM tier runs the same file on vcan.

#[path = "common/tool.rs"]
mod tool;
use serde_json::Value;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use tool::tool;

const HTTP: &str = "127.0.0.1:18181";

/// Kills what it holds when dropped (a failed assertion leaves no process behind).
struct Procs(Vec<Child>);
impl Drop for Procs {
    fn drop(&mut self) {
        for c in &mut self.0 {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn board(buses: &str, node: &str) -> Child {
    Command::new(tool())
        .args(["--bus", buses, "device", "board", "--node", node])
        .args(["--heartbeat-ms", "200"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start a board")
}

/// `GET path` on the station's HTTP port: the body, or `None` while it does not answer.
fn get(path: &str) -> Option<String> {
    let mut s = TcpStream::connect(HTTP).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(2))).ok()?;
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut text = String::new();
    s.read_to_string(&mut text).ok()?;
    text.starts_with("HTTP/1.1 200")
        .then(|| text.split_once("\r\n\r\n").map(|(_, b)| b.to_string()))?
}

/// The networks' status, as `/api/networks` gives it.
fn networks() -> Option<Vec<Value>> {
    serde_json::from_str::<Value>(&get("/api/networks")?)
        .ok()?
        .as_array()
        .cloned()
}

/// Network `name`'s running member of pair 0x11/0x21 ("A", "B") and this master's role.
fn rack(nets: &[Value], name: &str) -> Option<(String, String)> {
    let n = nets.iter().find(|n| n["name"] == name)?;
    let pair = n["pairs"]
        .as_array()?
        .iter()
        .find(|p| p["pair"] == "0x11/0x21")?;
    Some((pair["active"].as_str()?.into(), n["role"].as_str()?.into()))
}

/// Waits up to `secs` until `ok` holds of the status; panics naming `what` and the last status.
fn until(station: &mut Child, secs: u64, what: &str, ok: impl Fn(&[Value]) -> bool) {
    let end = Instant::now() + Duration::from_secs(secs);
    let mut last = None;
    while Instant::now() < end {
        if let Ok(Some(st)) = station.try_wait() {
            panic!("the station exited ({st}) while waiting until {what}");
        }
        if let Some(nets) = networks() {
            if ok(&nets) {
                return;
            }
            last = Some(nets);
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("not within {secs} s: {what}; status: {last:?}");
}

#[test]
fn the_shipped_station_file_runs_on_the_udp_bus_and_fails_over_a_killed_board() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let shipped = std::fs::read_to_string(root.join("examples/station/vcan.toml")).unwrap();
    let dir = std::env::temp_dir().join(format!("duocan-station-udp-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let audit = dir.join("audit");
    // Only the buses, the listening ports (beside other tests) and an audit trail differ.
    let file = shipped
        .replace("\"vcan0,vcan1\"", "\"udp:80,udp:81\"")
        .replace("\"vcan2,vcan3\"", "\"udp:82,udp:83\"")
        .replace("127.0.0.1:8080", HTTP)
        .replace("127.0.0.1:5555", "127.0.0.1:18182")
        .replace(
            "[station]\n",
            &format!("[station]\naudit_dir = \"{}\"\n", audit.display()),
        );
    assert_ne!(file, shipped);
    assert!(
        !file.contains("buses = \"vcan"),
        "every interface renamed: {file}"
    );
    let path = dir.join("station.toml");
    std::fs::write(&path, &file).unwrap();

    let check = Command::new(tool())
        .args(["station", "check"])
        .arg(&path)
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&check.stdout);
    assert!(
        check.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&check.stderr)
    );
    assert!(said.contains("turnout rack on udp:80,udp:81"), "{said}");
    assert!(said.contains("signal rack on udp:82,udp:83"), "{said}");

    // The A boards first (a pair's first member configured runs), then the station.
    let mut procs = Procs(vec![
        board("udp:80,udp:81", "0x11"),
        board("udp:82,udp:83", "0x11"),
    ]);
    let log = std::fs::File::create(dir.join("station.log")).unwrap();
    let mut station = Command::new(tool())
        .args(["station", "run"])
        .arg(&path)
        .stdout(log.try_clone().unwrap())
        .stderr(log)
        .spawn()
        .unwrap();
    let a_runs = |n: &[Value], name: &str| rack(n, name) == Some(("A".into(), "active".into()));
    until(
        &mut station,
        30,
        "both racks active, each pair running A",
        |n| a_runs(n, "turnout rack") && a_runs(n, "signal rack"),
    );
    procs.0.push(board("udp:80,udp:81", "0x21"));
    procs.0.push(board("udp:82,udp:83", "0x21"));
    let b_standby = |n: &[Value], name: &str| {
        n.iter().find(|n| n["name"] == name).is_some_and(|n| {
            n["nodes"].as_array().is_some_and(|nodes| {
                nodes
                    .iter()
                    .any(|x| x["node"] == "0x21" && x["state"] == "pre-operational")
            })
        })
    };
    until(&mut station, 30, "the B boards standing by", |n| {
        b_standby(n, "turnout rack") && b_standby(n, "signal rack")
    });

    // The turnout rack's A board dies: B runs there; the signal rack keeps A.
    procs.0[0].kill().unwrap();
    procs.0[0].wait().unwrap();
    until(
        &mut station,
        30,
        "the turnout rack running B, the signal rack A",
        |n| {
            rack(n, "turnout rack") == Some(("B".into(), "active".into()))
                && a_runs(n, "signal rack")
        },
    );
    let nets = networks().unwrap();
    let failovers = |name: &str| {
        nets.iter()
            .find(|n| n["name"] == name)
            .and_then(|n| n["failovers"].as_u64())
    };
    assert_eq!(failovers("turnout rack"), Some(1));
    assert_eq!(failovers("signal rack"), Some(0));

    // SIGTERM: a clean stop, the switch-over in the audit trail.
    let pid = station.id().to_string();
    assert!(Command::new("kill")
        .args(["-TERM", &pid])
        .status()
        .unwrap()
        .success());
    let end = Instant::now() + Duration::from_secs(15);
    let status = loop {
        if let Some(s) = station.try_wait().unwrap() {
            break s;
        }
        assert!(
            Instant::now() < end,
            "the station did not stop within 15 s of SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(50));
    };
    let log = std::fs::read_to_string(dir.join("station.log")).unwrap();
    assert!(status.success(), "{status}: {log}");
    for n in ["turnout rack", "signal rack"] {
        assert!(
            log.lines()
                .any(|l| l.contains("audit closed") && l.contains(n)),
            "the audit trail of {n} not closed: {log}"
        );
    }
    let trail = |prefix: &str| {
        std::fs::read_dir(&audit)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix))
            .map(|p| std::fs::read_to_string(p).unwrap())
            .collect::<String>()
    };
    assert!(
        trail("turnout").contains("active A -> B"),
        "the turnout rack's audit trail holds the switch-over: {}",
        trail("turnout")
    );
    assert!(!trail("signal").contains("active A -> B"));
    let _ = std::fs::remove_dir_all(&dir);
}
