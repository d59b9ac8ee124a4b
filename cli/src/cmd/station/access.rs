//! Who may do what over the station's HTTP: the read role (status, metrics, events, SDO
//! reads) and the control role (SDO writes, NMT, switch-overs, LSS), from the tokens of the
//! station file ([`config::Http`](super::config::Http), whose module says the rule), and the
//! rates at which read and control requests are taken.
//!
//! A token is compared in constant time in its length: a wrong guess says nothing of where it
//! went wrong. The control token also reads. Control requests, once their role is checked,
//! draw from a token bucket of [`CONTROL_BURST`] refilled at [`CONTROL_PER_SECOND`] a second
//! (shared by all clients): an operator's clicks pass, a script gone wild gets 429 and
//! changes nothing. Read requests (every `GET`, once its role is checked) draw from a bucket
//! of their own, [`READ_BURST`] refilled at [`READ_PER_SECOND`] a second: room for a few
//! dashboards (each asks three times a second or so) and scrapes, while a client polling in
//! a tight loop gets 429 rather than the station's time. Both refusals are counted
//! ([`Access::refused`], in `/metrics`).

use super::config::{Control, Http};
use axum::http::{header, HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use serde_json::json;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

/// Control requests taken at once before the rate bound applies.
pub const CONTROL_BURST: f64 = 20.0;
/// Control requests taken a second, in the long run.
pub const CONTROL_PER_SECOND: f64 = 2.0;
/// Read requests taken at once before the rate bound applies.
pub const READ_BURST: f64 = 200.0;
/// Read requests taken a second, in the long run.
pub const READ_PER_SECOND: f64 = 50.0;

/// The station's access rules.
pub struct Access {
    token: Option<String>,
    control: Control,
    control_rate: Bucket,
    read_rate: Bucket,
}

/// A token bucket: `burst` at once, refilled at `per_second`; counts what it refused.
struct Bucket {
    burst: f64,
    per_second: f64,
    /// Tokens left, and when they were last filled.
    left: Mutex<(f64, Instant)>,
    refused: AtomicU64,
}

impl Bucket {
    fn new(burst: f64, per_second: f64) -> Self {
        Self {
            burst,
            per_second,
            left: Mutex::new((burst, Instant::now())),
            refused: AtomicU64::new(0),
        }
    }

    /// Takes one token, if one is left; else counts the refusal.
    fn take(&self) -> bool {
        let mut b = self
            .left
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let now = Instant::now();
        let filled = b.0 + now.duration_since(b.1).as_secs_f64() * self.per_second;
        *b = (filled.min(self.burst), now);
        if b.0 >= 1.0 {
            b.0 -= 1.0;
            true
        } else {
            self.refused.fetch_add(1, Ordering::Relaxed);
            false
        }
    }
}

/// An error response: the status and a JSON body `{"error": why}`.
pub fn error(code: StatusCode, why: &str) -> Response {
    (code, axum::Json(json!({ "error": why }))).into_response()
}

/// The 401 of a request without the token it needs.
pub fn unauthorized() -> Response {
    error(
        StatusCode::UNAUTHORIZED,
        "a token is needed: Authorization: Bearer TOKEN",
    )
}

fn same(given: &str, token: &str) -> bool {
    let (a, b) = (given.as_bytes(), token.as_bytes());
    let mut diff = a.len() ^ b.len();
    for (i, &t) in b.iter().enumerate() {
        diff |= usize::from(a.get(i).copied().unwrap_or(0) ^ t);
    }
    diff == 0
}

fn bearer(headers: &HeaderMap) -> &str {
    headers
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "))
        .unwrap_or("")
}

impl Access {
    /// The rules of `http` (none: everything read, nothing controlled).
    pub fn new(http: Option<&Http>) -> Access {
        Access {
            token: http.and_then(|h| h.token.clone()),
            control: http.map_or(Control::Off, |h| h.control.clone()),
            control_rate: Bucket::new(CONTROL_BURST, CONTROL_PER_SECOND),
            read_rate: Bucket::new(READ_BURST, READ_PER_SECOND),
        }
    }

    /// Requests refused so far for their rate: read requests, control requests.
    pub fn refused(&self) -> (u64, u64) {
        let n = |b: &Bucket| b.refused.load(Ordering::Relaxed);
        (n(&self.read_rate), n(&self.control_rate))
    }

    /// Whether a read request may be taken now, its role checked already; else the 429 that
    /// refuses it.
    pub fn read_rate(&self) -> Result<(), Response> {
        if self.read_rate.take() {
            Ok(())
        } else {
            Err(error(
                StatusCode::TOO_MANY_REQUESTS,
                &format!(
                    "too many read requests: at most {READ_PER_SECOND} a second (all clients \
                     together), try again in a second"
                ),
            ))
        }
    }

    fn is_control_token(&self, given: &str) -> bool {
        matches!(&self.control, Control::Token(t) if same(given, t))
    }

    /// Whether the request may read.
    pub fn may_read(&self, headers: &HeaderMap) -> bool {
        let Some(token) = &self.token else {
            return true;
        };
        let given = bearer(headers);
        // Both compared, whichever matches: the time says nothing of which token it was.
        let read = same(given, token);
        let control = self.is_control_token(given);
        read | control
    }

    /// Whether the request's role may control, the rate left aside: what the dashboard asks
    /// (`GET /api/role`) before it offers operator actions. Takes nothing from the bucket.
    pub fn may_control(&self, headers: &HeaderMap) -> bool {
        match &self.control {
            Control::Off => false,
            Control::Loopback => true,
            Control::Token(_) => self.is_control_token(bearer(headers)),
        }
    }

    /// Whether the request may control, and then who it is (for the logs and the audit
    /// trail); else the response that refuses it: 401 without the token, 403 with a token
    /// of the read role or when control is off, 429 over the rate.
    pub fn control(&self, headers: &HeaderMap) -> Result<&'static str, Response> {
        let who = match &self.control {
            Control::Off => {
                return Err(error(
                    StatusCode::FORBIDDEN,
                    "control is off: the station file sets neither http_control_token nor \
                     http_control = \"loopback\"",
                ))
            }
            Control::Loopback => "loopback",
            Control::Token(_) => {
                let given = bearer(headers);
                if self.is_control_token(given) {
                    "control-token"
                } else if self.token.as_deref().is_some_and(|t| same(given, t)) {
                    return Err(error(
                        StatusCode::FORBIDDEN,
                        "this token may only read: control needs the control token",
                    ));
                } else {
                    return Err(unauthorized());
                }
            }
        };
        if !self.control_rate.take() {
            return Err(error(
                StatusCode::TOO_MANY_REQUESTS,
                "too many control requests: try again in a second",
            ));
        }
        Ok(who)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn with(token: Option<&str>) -> HeaderMap {
        let mut h = HeaderMap::new();
        if let Some(t) = token {
            h.insert(
                header::AUTHORIZATION,
                format!("Bearer {t}").parse().unwrap(),
            );
        }
        h
    }

    #[test]
    fn the_roles_follow_the_tokens() {
        let http = Http {
            addr: "0.0.0.0:1".parse().unwrap(),
            token: Some("read-0123456789ab".into()),
            control: Control::Token("ctl-0123456789abc".into()),
            tls: None,
            max_connections: 4,
        };
        let a = Access::new(Some(&http));
        assert!(!a.may_read(&with(None)));
        assert!(a.may_read(&with(Some("read-0123456789ab"))));
        assert!(a.may_read(&with(Some("ctl-0123456789abc"))));
        assert!(!a.may_read(&with(Some("read-0123456789aX"))));
        let status = |r: Result<&'static str, Response>| r.map_err(|e| e.status());
        assert_eq!(
            status(a.control(&with(None))),
            Err(StatusCode::UNAUTHORIZED)
        );
        assert_eq!(
            status(a.control(&with(Some("read-0123456789ab")))),
            Err(StatusCode::FORBIDDEN)
        );
        assert_eq!(
            status(a.control(&with(Some("ctl-0123456789abc")))),
            Ok("control-token")
        );
        assert!(a.may_control(&with(Some("ctl-0123456789abc"))));
        assert!(!a.may_control(&with(Some("read-0123456789ab"))));
        assert!(!a.may_control(&with(None)));
        // Without a station file's say, nothing is controlled.
        let off = Access::new(None);
        assert!(off.may_read(&with(None)));
        assert_eq!(status(off.control(&with(None))), Err(StatusCode::FORBIDDEN));
        assert!(!off.may_control(&with(None)));
    }

    #[test]
    fn control_requests_beyond_the_burst_are_refused() {
        let http = Http {
            addr: "127.0.0.1:1".parse().unwrap(),
            token: None,
            control: Control::Loopback,
            tls: None,
            max_connections: 4,
        };
        let a = Access::new(Some(&http));
        let taken = (0..100).filter(|_| a.control(&with(None)).is_ok()).count();
        // The burst, and at most a few refilled while the loop ran.
        assert!((20..25).contains(&taken), "{taken}");
        assert_eq!(a.refused(), (0, 100 - taken as u64));
    }

    #[test]
    fn read_requests_beyond_their_burst_are_refused_and_counted() {
        let a = Access::new(None);
        let taken = (0..1000).filter(|_| a.read_rate().is_ok()).count();
        // The burst, and what refilled while the loop ran (well under a second).
        assert!((200..260).contains(&taken), "{taken}");
        assert_eq!(a.refused(), (1000 - taken as u64, 0));
        let e = a.read_rate().unwrap_err();
        assert_eq!(e.status(), StatusCode::TOO_MANY_REQUESTS);
    }
}
