//! The station under test: its process, its log, its metrics.

use std::io::{BufRead, BufReader};
use std::process::Child;
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// `duocan station run` on `file`, its standard error read line by line by a thread.
pub fn station(file: &std::path::Path) -> (Child, Receiver<String>) {
    let mut child = crate::common::station_run(file.to_str().unwrap())
        .spawn()
        .expect("run duocan");
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    (child, rx)
}

/// Reads the station's log until a line contains `want` (within `secs`); the lines so far.
pub fn log_until(rx: &Receiver<String>, log: &mut Vec<String>, secs: u64, want: &str) -> String {
    let end = Instant::now() + Duration::from_secs(secs);
    if let Some(l) = log.iter().find(|l| l.contains(want)) {
        return l.clone();
    }
    loop {
        match rx.recv_timeout(end.saturating_duration_since(Instant::now())) {
            Ok(l) => {
                log.push(l.clone());
                if l.contains(want) {
                    return l;
                }
            }
            Err(_) => panic!("{want:?} not logged in {secs} s:\n{}", log.join("\n")),
        }
    }
}

/// `GET /metrics` from the station at `addr`: each sample line's value by its name and labels.
pub fn metrics(addr: &str) -> std::collections::BTreeMap<String, u64> {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(
        s,
        "GET /metrics HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).expect("read");
    assert!(text.starts_with("HTTP/1.1 200"), "{text}");
    text.lines()
        .filter(|l| l.starts_with("duocan_"))
        .filter_map(|l| {
            let (k, v) = l.rsplit_once(' ')?;
            Some((k.to_string(), v.parse().ok()?))
        })
        .collect()
}

/// Reads the metrics until `want` accepts them (within `secs`); the ones it accepted.
pub fn metrics_until(
    addr: &str,
    secs: u64,
    what: &str,
    want: impl Fn(&std::collections::BTreeMap<String, u64>) -> bool,
) -> std::collections::BTreeMap<String, u64> {
    let end = Instant::now() + Duration::from_secs(secs);
    loop {
        let m = metrics(addr);
        if want(&m) {
            return m;
        }
        assert!(Instant::now() < end, "{what}: not in {secs} s: {m:#?}");
        std::thread::sleep(Duration::from_millis(50));
    }
}
