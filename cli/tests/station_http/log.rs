//! The station under test's log, read line by line, and the test files.

#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::time::Instant;

/// The lines `child` writes on standard error, read by a thread of their own (so that the
/// station never waits for the test to read them).
pub fn stderr_lines(child: &mut std::process::Child) -> std::sync::mpsc::Receiver<String> {
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().expect("stderr");
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    rx
}

/// The next line before `end`, if one comes.
pub fn next_before(rx: &std::sync::mpsc::Receiver<String>, end: Instant) -> Option<String> {
    rx.recv_timeout(end.saturating_duration_since(Instant::now()))
        .ok()
}

/// The address the station's HTTP server listens on, from its log, within 120 s; the station
/// is killed and the test fails if it does not say.
pub fn http_address(
    child: &mut std::process::Child,
    rx: &std::sync::mpsc::Receiver<String>,
) -> String {
    let end = Instant::now() + std::time::Duration::from_secs(120);
    loop {
        match next_before(rx, end) {
            Some(l) => {
                if let Some(a) = l.split("http listening on ").nth(1) {
                    return a.trim().to_string();
                }
            }
            None => {
                let _ = child.kill();
                panic!("no http address in 120 s");
            }
        }
    }
}

pub fn file(rel: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(rel)
        .to_string_lossy()
        .into_owned()
}
