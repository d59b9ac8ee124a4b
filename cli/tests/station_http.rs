//! The station's HTTP access (`duocan station run` with `http`): its status and metrics, only
//! with the token when it has one; the dashboard; its events as server-sent events as they
//! happen. The REST routes (SDO, NMT, switch-overs, LSS, the roles) are `station_rest.rs`'s.

mod common;
#[path = "station_http/log.rs"]
mod log;
use log::{file, http_address, next_before, stderr_lines};
use std::time::{Duration, Instant};

/// `GET path` on `addr`, with the bearer `token` if any: the status code and the body.
fn get(addr: &str, path: &str, token: Option<&str>) -> (u16, String) {
    let (code, _, body) = get_with_head(addr, path, token);
    (code, body)
}

/// `GET path` on `addr`, with the bearer `token` if any: the status code, the head (status
/// line and headers, lower-case as the station sends them) and the body.
fn get_with_head(addr: &str, path: &str, token: Option<&str>) -> (u16, String, String) {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let auth = token.map_or(String::new(), |t| format!("Authorization: Bearer {t}\r\n"));
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\n{auth}Connection: close\r\n\r\n"
    )
    .unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).expect("read");
    let code = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    (code, head.to_string(), body.to_string())
}

/// `POST path` on `addr` with the JSON `body`: the status code and the answer's body.
fn post(addr: &str, path: &str, body: &str) -> (u16, String) {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    write!(
        s,
        "POST {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).expect("read");
    let code = text
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (
        code,
        text.split_once("\r\n\r\n")
            .map_or("", |(_, b)| b)
            .to_string(),
    )
}

/// The dashboard at `/` on `addr`: its status code, and whether it came as HTML with the
/// page's rules (no framing, not cached).
fn dashboard(addr: &str, token: Option<&str>) -> (u16, String) {
    let (code, head, body) = get_with_head(addr, "/", token);
    assert!(
        head.contains("content-type: text/html; charset=utf-8"),
        "{head}"
    );
    assert!(head.contains("frame-ancestors 'none'"), "{head}");
    assert!(head.contains("cache-control: no-store"), "{head}");
    (code, body)
}

/// The station's HTTP access: with a token, none is served without it; the status JSON and
/// the Prometheus metrics say which master is active and which board runs in each pair, and
/// count each port's frames.
#[test]
fn the_station_serves_its_status_and_metrics_over_http() {
    let _one = common::one_station();
    let dir = std::env::temp_dir().join(format!("duocan-station-http-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let station = dir.join("web.toml");
    let token = "test-token-0123456789";
    let two = std::fs::read_to_string(file("tests/station_files/two.toml")).unwrap();
    std::fs::write(
        &station,
        format!("[station]\nhttp = \"127.0.0.1:0\"\nhttp_token = \"{token}\"\n\n{two}"),
    )
    .unwrap();
    let mut child = common::station_run(station.to_str().unwrap())
        .spawn()
        .expect("run duocan");
    let rx = stderr_lines(&mut child);
    let end = Instant::now() + Duration::from_secs(120);
    let mut addr = None;
    let mut active = 0;
    let mut seen = vec![];
    while let Some(line) = next_before(&rx, end) {
        seen.push(line.clone());
        if let Some(a) = line.split("http listening on ").nth(1) {
            addr = Some(a.trim().to_string());
        }
        if line.contains("pair 0x10/0x50: A active") {
            active += 1;
        }
        if addr.is_some() && active == 2 {
            break;
        }
    }
    let Some(addr) = addr.filter(|_| active == 2) else {
        let _ = child.kill();
        panic!(
            "no http address or no pair active in 120 s:\n{}",
            seen.join("\n")
        );
    };
    let (code, body) = get(&addr, "/metrics", None);
    assert_eq!(code, 401, "{body}");
    // The dashboard too: without the token, a page that only asks for it.
    let (code, page) = dashboard(&addr, None);
    assert_eq!(code, 401, "{page}");
    assert!(page.contains("needs a token"), "{page}");
    assert!(!page.contains("data-network"), "{page}");
    let (code, page) = dashboard(&addr, Some(token));
    assert_eq!(code, 200, "{page}");
    assert!(
        page.contains("data-network") && page.contains("/api/events"),
        "{page}"
    );
    let (code, _) = get(&addr, "/metrics", Some("test-token-0123456788"));
    assert_eq!(code, 401);
    let (code, metrics) = get(&addr, "/metrics", Some(token));
    let (jcode, json) = get(&addr, "/api/networks", Some(token));
    let (ncode, _) = get(&addr, "/nothing", Some(token));
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!((code, jcode, ncode), (200, 200, 404));
    for net in ["east", "west"] {
        assert!(
            metrics.contains(&format!("duocan_master_active{{network=\"{net}\"}} 1")),
            "{metrics}"
        );
        assert!(
            metrics.contains(&format!(
                "duocan_pair_active_member{{network=\"{net}\",pair=\"0x10/0x50\"}} 1"
            )),
            "{metrics}"
        );
    }
    let rx: Vec<u64> = metrics
        .lines()
        .filter(|l| l.starts_with("duocan_port_rx_frames_total{"))
        .map(|l| l.rsplit(' ').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(rx.len(), 4, "{metrics}");
    assert!(rx.iter().all(|&n| n > 0), "{metrics}");
    // Each port's lag behind the other (the meter's figure, in seconds): two ports per
    // network, at most one of them behind (on a loaded machine a reader may run behind; the
    // figure is then the port's, and the other's is zero).
    let lag: Vec<f64> = metrics
        .lines()
        .filter(|l| l.starts_with("duocan_port_lag_seconds{"))
        .map(|l| l.rsplit(' ').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(lag.len(), 4, "{metrics}");
    assert!(
        lag.chunks(2)
            .all(|p| p.iter().all(|&s| (0.0..1.0).contains(&s)) && p.contains(&0.0)),
        "{metrics}"
    );
    assert!(
        metrics.contains("# TYPE duocan_port_lag_seconds gauge")
            && metrics.contains("duocan_port_lag_seconds{network=\"west\",bus=\"2\","),
        "{metrics}"
    );
    let v: serde_json::Value = serde_json::from_str(&json).expect("json");
    assert_eq!(v[0]["name"], "east");
    assert_eq!(v[0]["role"], "active");
    assert_eq!(v[1]["pairs"][0]["pair"], "0x10/0x50");
    assert_eq!(v[1]["pairs"][0]["active"], "A");
    assert_eq!(v[1]["ports"].as_array().map(Vec::len), Some(2));
    // Every master of each network, this one first, its peers with their role as this master
    // knows it: east has no peer; west's peer (node 4, priority 1) is heard and follows.
    let me = serde_json::json!({ "node": 1, "priority": 0, "role": "active", "self": true });
    assert_eq!(v[0]["masters"], serde_json::json!([me]), "{json}");
    let masters = v[1]["masters"].as_array().expect("masters");
    assert_eq!(masters.len(), 2, "{json}");
    assert_eq!(
        (&masters[0]["node"], &masters[0]["role"]),
        (&3.into(), &"active".into())
    );
    let peer = &masters[1];
    assert_eq!(
        (
            &peer["node"],
            &peer["priority"],
            &peer["role"],
            &peer["self"]
        ),
        (&4.into(), &1.into(), &"standby".into(), &false.into()),
        "{json}"
    );
    assert!(
        peer["heard_ms_ago"].as_u64().is_some_and(|ms| ms < 2000),
        "{json}"
    );
    // What the dashboard shows: the node table (both members of the pair, A running, heard on
    // a bus) and the recent events with their times.
    assert_eq!(v[0]["open"], true);
    let node = |id: &str| {
        v[0]["nodes"]
            .as_array()
            .and_then(|n| n.iter().find(|x| x["node"] == id))
            .cloned()
            .unwrap_or_else(|| panic!("no node {id} in {json}"))
    };
    let a = node("0x10");
    // Started as it became the running board: operational now or in a moment.
    assert!(
        ["pre-operational", "operational"].contains(&a["state"].as_str().unwrap_or("")),
        "{a}"
    );
    let heard = a["heard"].as_array().expect("heard on which bus");
    assert_eq!(heard.len(), 2, "{a}");
    assert!(heard.iter().any(|h| h == true), "{a}");
    assert_eq!(a["pair"]["member"], "A", "{a}");
    assert_eq!(a["pair"]["running"], true, "{a}");
    assert_eq!(node("0x50")["pair"]["running"], false, "{json}");
    let recent = v[0]["recent"].as_array().expect("recent");
    assert!(
        recent
            .iter()
            .any(|e| e["line"] == "pair 0x10/0x50: A active" && e["at_ms"].as_u64() > Some(0)),
        "{json}"
    );
}

/// `GET /api/events`: the networks' events as server-sent events, each named after its
/// network, as they happen: the simulated plants cut bus 1 two seconds after the start, and
/// the client, connected before, reads each network's failover from the stream.
#[test]
fn the_station_streams_its_events_over_http() {
    use std::io::Read;
    let _one = common::one_station();
    let dir = std::env::temp_dir().join(format!("duocan-station-sse-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let station = dir.join("sse.toml");
    let two = std::fs::read_to_string(file("tests/station_files/two.toml")).unwrap();
    let faulty = two.replace("sim-pairs:quiet", "sim-pairs");
    assert_ne!(faulty, two);
    std::fs::write(
        &station,
        format!("[station]\nhttp = \"127.0.0.1:0\"\n\n{faulty}"),
    )
    .unwrap();
    let mut child = common::station_run(station.to_str().unwrap())
        .spawn()
        .expect("run duocan");
    let rx = stderr_lines(&mut child);
    let addr = http_address(&mut child, &rx);
    // Without a token in the file, the dashboard is served to anyone on loopback.
    let (code, page) = dashboard(&addr, None);
    assert_eq!(code, 200, "{page}");
    // And nothing is controlled: the file does not turn control on.
    let (code, body) = post(
        &addr,
        "/api/networks/east/nmt",
        r#"{"command":"stop","node":0}"#,
    );
    assert_eq!(code, 403, "{body}");
    assert!(body.contains("control is off"), "{body}");
    let mut s = std::net::TcpStream::connect(&addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    use std::io::Write;
    write!(s, "GET /api/events HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
    let mut got = String::new();
    let mut buf = [0u8; 4096];
    let want = [
        "event: east\ndata: bus 1: failed (port down: interface down)",
        "event: west\ndata: bus 1: failed (port down: interface down)",
    ];
    // The plants' script ends 6 s after the start (the stream with it); a minute at most.
    let end = Instant::now() + Duration::from_secs(60);
    while !want.iter().all(|w| got.contains(w)) && Instant::now() < end {
        match s.read(&mut buf) {
            Ok(0) => break,
            // Quiet for a while: look again, until the deadline.
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(e) => panic!("reading the stream: {e}"),
            Ok(n) => got.push_str(&String::from_utf8_lossy(&buf[..n])),
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(got.starts_with("HTTP/1.1 200"), "{got}");
    assert!(got.contains("content-type: text/event-stream"), "{got}");
    for w in want {
        assert!(got.contains(w), "{w:?} not in:\n{got}");
    }
}
