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

pub fn file(rel: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join(rel)
        .to_string_lossy()
        .into_owned()
}
