//! The station's HTTP bounds (`duocan station run` with `http`): connections open at once
//! (`http_max_connections`; one more is 503), event streams open at once (one more is 503),
//! and the read rate (429 over it), each refusal with its message and counted in `/metrics`.

mod common;
#[path = "station_http/log.rs"]
mod log;
use log::{file, http_address, stderr_lines};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// One keep-alive HTTP/1.1 connection, its answers read one by one.
struct Conn {
    s: TcpStream,
    /// What came and is not read yet.
    buf: Vec<u8>,
}

impl Conn {
    fn open(addr: &str) -> Conn {
        let s = TcpStream::connect(addr).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        // Each request goes in one segment, at once (no wait for the station's ACK).
        s.set_nodelay(true).unwrap();
        Conn { s, buf: vec![] }
    }

    /// Reads until `buf` holds `n` bytes, or the connection ends.
    fn fill(&mut self, n: usize) {
        let mut chunk = [0u8; 4096];
        while self.buf.len() < n {
            match self.s.read(&mut chunk) {
                Ok(0) => return,
                Ok(k) => self.buf.extend_from_slice(&chunk[..k]),
                Err(e) => panic!("reading: {e}"),
            }
        }
    }

    /// The head of the next answer (status line and headers), once it is all here.
    fn head(&mut self) -> String {
        let mut chunk = [0u8; 4096];
        loop {
            if let Some(i) = self.buf.windows(4).position(|w| w == b"\r\n\r\n") {
                let head = String::from_utf8_lossy(&self.buf[..i]).into_owned();
                self.buf.drain(..i + 4);
                return head;
            }
            match self.s.read(&mut chunk) {
                Ok(0) => panic!(
                    "closed before a head: {:?}",
                    String::from_utf8_lossy(&self.buf)
                ),
                Ok(k) => self.buf.extend_from_slice(&chunk[..k]),
                Err(e) => panic!("reading a head: {e}"),
            }
        }
    }

    /// Sends `GET path`, whole in one write.
    fn send(&mut self, path: &str) {
        let req = format!("GET {path} HTTP/1.1\r\nHost: station\r\n\r\n");
        self.s.write_all(req.as_bytes()).expect("send");
    }

    /// `GET path` on this connection (kept alive): the status code and the body.
    fn get(&mut self, path: &str) -> (u16, String) {
        self.send(path);
        let head = self.head();
        let code = head
            .split(' ')
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        let len: usize = head
            .lines()
            .find_map(|l| {
                l.to_ascii_lowercase()
                    .strip_prefix("content-length: ")
                    .map(str::to_string)
            })
            .and_then(|n| n.trim().parse().ok())
            .unwrap_or_else(|| panic!("no content-length in {head}"));
        self.fill(len);
        let body: Vec<u8> = self.buf.drain(..len.min(self.buf.len())).collect();
        (code, String::from_utf8_lossy(&body).into_owned())
    }
}

/// The value of the metric line starting `name ` in `metrics`.
fn metric(metrics: &str, name: &str) -> Option<u64> {
    metrics
        .lines()
        .find_map(|l| l.strip_prefix(name)?.strip_prefix(' ')?.parse().ok())
}

/// Asks `path` on `c` until `want` holds of its 200 answer, for at most 30 s.
fn until(c: &mut Conn, path: &str, want: impl Fn(&str) -> bool) -> String {
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let (code, body) = c.get(path);
        if code == 200 && want(&body) {
            return body;
        }
        assert!(Instant::now() < end, "{path}: {code} {body}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// At most `http_max_connections` connections (here 10) and 8 event streams are open at once;
/// one more of either is 503 with a message, and a freed slot is taken again. Read requests
/// beyond the burst are 429 with a message. `/metrics` counts each refusal.
#[test]
fn connections_streams_and_reads_are_bounded() {
    let _one = common::one_station();
    let dir = std::env::temp_dir().join(format!("duocan-station-limits-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let station = dir.join("limits.toml");
    let two = std::fs::read_to_string(file("tests/station_files/two.toml")).unwrap();
    std::fs::write(
        &station,
        format!("[station]\nhttp = \"127.0.0.1:0\"\nhttp_max_connections = 10\n\n{two}"),
    )
    .unwrap();
    let mut child = common::station_run(station.to_str().unwrap())
        .spawn()
        .expect("run duocan");
    let rx = stderr_lines(&mut child);
    let addr = http_address(&mut child, &rx);
    let check = std::panic::catch_unwind(|| bounded(&addr));
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);
    if let Err(e) = check {
        std::panic::resume_unwind(e);
    }
}

fn bounded(addr: &str) {
    // The watcher's own connection, the only one open: counted as such.
    let mut watch = Conn::open(addr);
    let m = until(&mut watch, "/metrics", |m| {
        metric(m, "duocan_http_connections") == Some(1)
    });
    assert_eq!(metric(&m, "duocan_http_max_connections"), Some(10), "{m}");
    // Eight event streams, each answered 200 and left open.
    let mut streams = vec![];
    for _ in 0..8 {
        let mut c = Conn::open(addr);
        c.send("/api/events");
        let head = c.head();
        assert!(head.starts_with("HTTP/1.1 200"), "{head}");
        streams.push(c);
    }
    // A ninth stream is refused (its connection, the tenth, is open).
    let mut tenth = Conn::open(addr);
    let (code, body) = tenth.get("/api/events");
    assert_eq!(code, 503, "{body}");
    assert!(body.contains("too many event streams open"), "{body}");
    // An eleventh connection is refused before any request is read.
    let mut eleventh = Conn::open(addr);
    let (code, body) = eleventh.get("/api/role");
    assert_eq!(code, 503, "{body}");
    assert!(
        body.contains("too many connections open (at most 10)"),
        "{body}"
    );
    let (code, m) = watch.get("/metrics");
    assert_eq!(code, 200, "{m}");
    let refused = "duocan_http_refused_total{reason=\"too_many_connections\"}";
    assert_eq!(metric(&m, refused), Some(1), "{m}");
    assert_eq!(metric(&m, "duocan_http_connections"), Some(10), "{m}");
    // A connection closed frees its slot: a new one is served once the station sees it (at
    // once for a connection between requests, whose end the station reads).
    drop(tenth);
    let end = Instant::now() + Duration::from_secs(30);
    loop {
        let (code, body) = Conn::open(addr).get("/api/role");
        if code == 200 {
            assert_eq!(body, r#"{"role":"read"}"#);
            break;
        }
        assert_eq!(code, 503, "{body}");
        assert!(Instant::now() < end, "no slot freed in 30 s");
        std::thread::sleep(Duration::from_millis(50));
    }
    // Reads in a tight loop: the burst passes, then 429 with a message.
    let mut passed = 0;
    let refusal = loop {
        let (code, body) = watch.get("/api/role");
        match code {
            200 => passed += 1,
            429 => break body,
            _ => panic!("{code} {body}"),
        }
        assert!(passed < 5000, "no read refused after {passed}");
    };
    assert!(passed >= 100, "only {passed} reads before a 429");
    assert!(refusal.contains("too many read requests"), "{refusal}");
    // Served again a moment later, and the refusal counted.
    let m = until(&mut watch, "/metrics", |_| true);
    let over = metric(&m, "duocan_http_refused_total{reason=\"read_rate\"}");
    assert!(over.is_some_and(|n| n >= 1), "{m}");
}
