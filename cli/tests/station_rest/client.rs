//! A small HTTP/1.1 client for the REST tests: one request per connection, JSON answers.

use serde_json::Value;
use std::io::{Read, Write};
use std::time::{Duration, Instant};

/// The station at `addr`, asked with `token` (if any).
#[derive(Clone, Copy)]
pub struct Client<'a> {
    pub addr: &'a str,
    pub token: Option<&'a str>,
}

impl Client<'_> {
    /// The same station asked with `token`.
    pub fn with<'b>(&'b self, token: Option<&'b str>) -> Client<'b> {
        Client {
            addr: self.addr,
            token,
        }
    }

    /// `METHOD path` with `body` (if any): the status code and the body, as JSON when it is.
    pub fn send(&self, method: &str, path: &str, body: Option<&str>) -> (u16, Value) {
        let mut s = std::net::TcpStream::connect(self.addr).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
        let auth = self
            .token
            .map_or(String::new(), |t| format!("Authorization: Bearer {t}\r\n"));
        let body = body.unwrap_or("");
        let head = format!(
            "{method} {path} HTTP/1.1\r\nHost: {}\r\n{auth}Content-Type: application/json\r\n\
             Content-Length: {}\r\nConnection: close\r\n\r\n",
            self.addr,
            body.len()
        );
        s.write_all(head.as_bytes()).unwrap();
        // A server that refuses the body early may close before all of it is sent.
        let _ = s.write_all(body.as_bytes());
        let mut raw = Vec::new();
        let _ = s.read_to_end(&mut raw);
        let text = String::from_utf8_lossy(&raw).into_owned();
        let code = text
            .split(' ')
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        let body = text.split_once("\r\n\r\n").map_or("", |(_, b)| b);
        let v = serde_json::from_str(body).unwrap_or_else(|_| Value::String(body.to_string()));
        (code, v)
    }

    pub fn get(&self, path: &str) -> (u16, Value) {
        self.send("GET", path, None)
    }

    /// Asks `GET path` until `want` accepts the answer (within `secs`); the one it accepted.
    pub fn get_until(&self, path: &str, secs: u64, want: impl Fn(&Value) -> bool) -> Value {
        let end = Instant::now() + Duration::from_secs(secs);
        loop {
            let (code, v) = self.get(path);
            if code == 200 && want(&v) {
                return v;
            }
            assert!(
                Instant::now() < end,
                "{path}: not as wanted in {secs} s: {code} {v}"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

/// The error text of an answer.
pub fn why(v: &Value) -> &str {
    v["error"].as_str().unwrap_or_default()
}
