//! A headless Chromium driven through the DevTools protocol over a pipe
//! (`--remote-debugging-pipe`: JSON messages ended by a NUL byte, read by Chromium on its file
//! descriptor 3 and written on 4). No WebSocket, no crate: a shell maps the child's standard
//! input and output to those descriptors. Every call has a deadline; the browser is killed
//! when dropped.

use serde_json::{json, Value};
use std::io::{Read, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// How long any one call may take.
const CALL: Duration = Duration::from_secs(30);

pub struct Browser {
    child: Child,
    input: ChildStdin,
    output: Receiver<Value>,
    next: u64,
}

/// The Chromium to run: `DUOCAN_CHROMIUM`, else `chromium` (Debian's package) on PATH.
pub fn chromium() -> String {
    std::env::var("DUOCAN_CHROMIUM").unwrap_or_else(|_| "chromium".into())
}

impl Browser {
    /// Starts a headless Chromium with its profile in `dir` and its standard error in
    /// `dir/chromium.log`, and waits until it answers. Panics, saying what to install, if
    /// there is no Chromium.
    pub fn start(dir: &Path) -> Browser {
        let bin = chromium();
        let version = Command::new(&bin).arg("--version").output();
        match &version {
            Ok(o) if o.status.success() => {
                eprintln!("browser: {}", String::from_utf8_lossy(&o.stdout).trim())
            }
            _ => panic!(
                "this test needs Chromium ({bin}: {version:?}): apt-get install chromium, or \
                 DUOCAN_CHROMIUM=/path/to/chrome"
            ),
        }
        let log = std::fs::File::create(dir.join("chromium.log")).expect("chromium.log");
        let mut child = Command::new("bash")
            .arg("-c")
            .arg(r#"exec "$0" "$@" 3<&0 4>&1 </dev/null >/dev/null"#)
            .arg(&bin)
            .args([
                "--headless=new",
                // Root in a container has no user namespace to sandbox in.
                "--no-sandbox",
                "--disable-gpu",
                "--no-first-run",
                "--remote-debugging-pipe",
                "about:blank",
            ])
            .arg(format!("--user-data-dir={}", dir.join("profile").display()))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(log)
            .spawn()
            .expect("run chromium through bash");
        let input = child.stdin.take().expect("stdin");
        let mut out = child.stdout.take().expect("stdout");
        let (tx, output) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let (mut buf, mut chunk) = (Vec::new(), [0u8; 65536]);
            while let Ok(n) = out.read(&mut chunk) {
                if n == 0 {
                    return;
                }
                buf.extend_from_slice(&chunk[..n]);
                while let Some(end) = buf.iter().position(|&b| b == 0) {
                    let msg: Vec<u8> = buf.drain(..=end).collect();
                    if let Ok(v) = serde_json::from_slice(&msg[..end]) {
                        if tx.send(v).is_err() {
                            return;
                        }
                    }
                }
            }
        });
        let mut b = Browser {
            child,
            input,
            output,
            next: 0,
        };
        let v = b.call(None, "Browser.getVersion", json!({}));
        eprintln!("browser: DevTools protocol {}", v["protocolVersion"]);
        b
    }

    /// Calls `method` (on the page of `session`, if any) and returns its result; panics on an
    /// error or after [`CALL`].
    pub fn call(&mut self, session: Option<&str>, method: &str, params: Value) -> Value {
        self.next += 1;
        let id = self.next;
        let mut msg = json!({ "id": id, "method": method, "params": params });
        if let Some(s) = session {
            msg["sessionId"] = json!(s);
        }
        let mut bytes = serde_json::to_vec(&msg).expect("json");
        bytes.push(0);
        self.input
            .write_all(&bytes)
            .unwrap_or_else(|e| panic!("{method}: chromium has gone: {e}"));
        let end = Instant::now() + CALL;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            let v = self
                .output
                .recv_timeout(left)
                .unwrap_or_else(|e| panic!("{method}: no answer from chromium in {CALL:?}: {e}"));
            // Events and the answers to earlier calls are not this one's.
            if v["id"] != json!(id) {
                continue;
            }
            if let Some(e) = v.get("error") {
                panic!("{method}: {e}");
            }
            return v["result"].clone();
        }
    }

    /// Opens `url` in a new page of `width` x `height` and returns the page's session.
    pub fn open(&mut self, url: &str, width: u32, height: u32) -> String {
        let target = self.call(None, "Target.createTarget", json!({ "url": "about:blank" }));
        let s = self.call(
            None,
            "Target.attachToTarget",
            json!({ "targetId": target["targetId"], "flatten": true }),
        );
        let s = s["sessionId"].as_str().expect("sessionId").to_string();
        self.call(
            Some(&s),
            "Emulation.setDeviceMetricsOverride",
            json!({ "width": width, "height": height, "deviceScaleFactor": 1, "mobile": false }),
        );
        self.call(Some(&s), "Page.navigate", json!({ "url": url }));
        s
    }

    /// The value of the JavaScript expression `js` on the page of `session`.
    pub fn eval(&mut self, session: &str, js: &str) -> Value {
        let r = self.call(
            Some(session),
            "Runtime.evaluate",
            json!({ "expression": js, "returnByValue": true }),
        );
        if let Some(e) = r.get("exceptionDetails") {
            panic!("{js}: {e}");
        }
        r["result"]["value"].clone()
    }

    /// The page of `session` as a PNG.
    pub fn screenshot(&mut self, session: &str) -> Vec<u8> {
        let r = self.call(
            Some(session),
            "Page.captureScreenshot",
            json!({ "format": "png" }),
        );
        unbase64(r["data"].as_str().expect("screenshot data"))
    }
}

impl Drop for Browser {
    /// Asks Chromium to close (its helper processes go with it), and kills it if it has not
    /// within five seconds.
    fn drop(&mut self) {
        let _ = self
            .input
            .write_all(b"{\"id\":0,\"method\":\"Browser.close\"}\0");
        let end = Instant::now() + Duration::from_secs(5);
        while Instant::now() < end {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Standard base64 decoded (what the protocol sends binary data as).
fn unbase64(s: &str) -> Vec<u8> {
    const ABC: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let (mut out, mut acc, mut bits) = (Vec::new(), 0u32, 0);
    for c in s.bytes().filter(|&c| c != b'=') {
        let v = ABC.iter().position(|&x| x == c).expect("base64") as u32;
        acc = acc << 6 | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
            acc &= (1 << bits) - 1;
        }
    }
    out
}
