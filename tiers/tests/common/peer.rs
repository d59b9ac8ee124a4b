//! The python peer (`tiers/python/peer.py`) as a child process the tests talk to through its
//! standard input and output lines.
#![allow(dead_code)]

use duocan::port::udp::UdpBusConfig;
use std::process::Stdio;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncBufReadExt, BufReader, Lines};
use tokio::process::{Child, ChildStdout, Command};

/// A running peer.
pub struct Peer {
    child: Child,
    out: Lines<BufReader<ChildStdout>>,
    /// Everything the peer wrote to stderr so far (python tracebacks, library warnings): shown
    /// when the peer does not answer, so that a failure says why.
    err: Arc<Mutex<String>>,
}

impl Peer {
    pub async fn spawn(args: &[&str]) -> Peer {
        Self::spawn_script("peer.py", args).await
    }

    /// A peer running `script` of `tiers/python/` (`peer.py`, `bench.py`).
    pub async fn spawn_script(script: &str, args: &[&str]) -> Peer {
        let python = std::env::var("DUOCAN_PYTHON").unwrap_or_else(|_| {
            panic!("DUOCAN_PYTHON is not set: point it at a python with python-can, canopen and msgpack (.ci/tier-python.sh does)")
        });
        let script = format!("{}/python/{script}", env!("CARGO_MANIFEST_DIR"));
        let mut child = Command::new(&python)
            .arg(script)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .kill_on_drop(true)
            .spawn()
            .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
        let out = BufReader::new(child.stdout.take().expect("stdout piped")).lines();
        let err = Arc::new(Mutex::new(String::new()));
        let mut lines = BufReader::new(child.stderr.take().expect("stderr piped")).lines();
        let sink = err.clone();
        tokio::spawn(async move {
            while let Ok(Some(l)) = lines.next_line().await {
                eprintln!("python peer: {l}");
                let mut s = sink.lock().unwrap();
                s.push_str(&l);
                s.push('\n');
            }
        });
        let mut p = Peer { child, out, err };
        p.expect("READY", 20).await;
        p
    }

    /// Waits for a line starting with `prefix`; returns the line. A line starting with `ERROR`
    /// (the peer could not carry out a command) fails at once.
    pub async fn expect(&mut self, prefix: &str, secs: u64) -> String {
        let r = tokio::time::timeout(Duration::from_secs(secs), async {
            while let Some(l) = self.out.next_line().await.expect("peer stdout") {
                if l.starts_with(prefix) || l.starts_with("ERROR") {
                    return Some(l);
                }
            }
            None
        })
        .await;
        if r.is_err() {
            // Ask the peer for every thread's stack (its faulthandler) before reporting.
            if let Some(pid) = self.child.id() {
                let _ = std::process::Command::new("kill")
                    .args(["-USR1", &pid.to_string()])
                    .status();
                tokio::time::sleep(Duration::from_millis(500)).await;
            }
        }
        let stderr = || self.err.lock().unwrap().clone();
        match r {
            Ok(Some(l)) if l.starts_with(prefix) => l,
            Ok(Some(l)) => panic!("python peer: {l}\nits stderr:\n{}", stderr()),
            Ok(None) => panic!(
                "python peer exited before printing {prefix:?}; its stderr:\n{}",
                stderr()
            ),
            Err(_) => panic!(
                "python peer did not print {prefix:?} within {secs} s; its stderr:\n{}",
                stderr()
            ),
        }
    }

    /// Waits for a line starting with `prefix` (`Ok`) or `ERROR` (`Err`: the peer could not
    /// carry out a command, and goes on).
    pub async fn result(&mut self, prefix: &str, secs: u64) -> Result<String, String> {
        let r = tokio::time::timeout(Duration::from_secs(secs), async {
            while let Some(l) = self.out.next_line().await.expect("peer stdout") {
                if l.starts_with(prefix) {
                    return Ok(l);
                }
                if l.starts_with("ERROR") {
                    return Err(l);
                }
            }
            Err("the peer exited".into())
        })
        .await;
        r.unwrap_or_else(|_| Err(format!("no {prefix:?} within {secs} s")))
    }

    pub async fn send_line(&mut self, line: &str) {
        use tokio::io::AsyncWriteExt;
        let stdin = self.child.stdin.as_mut().expect("stdin piped");
        stdin
            .write_all(format!("{line}\n").as_bytes())
            .await
            .unwrap();
        stdin.flush().await.unwrap();
    }

    pub async fn stop(mut self) {
        drop(self.child.stdin.take());
        let _ = tokio::time::timeout(Duration::from_secs(5), self.child.wait()).await;
    }
}

pub fn group(cfg: &UdpBusConfig) -> (String, String) {
    (cfg.group.to_string(), cfg.port.to_string())
}
