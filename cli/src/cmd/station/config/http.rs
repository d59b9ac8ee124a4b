//! The `http*` keys of the `[station]` table: where the station serves HTTP and who may read
//! and who may control (see [`crate::cmd::station::access`]).
//!
//! The rule, so that control is never open to another machine by default:
//!
//! - reads (status, metrics, events, SDO reads) need `http_token` if it is set, else are open;
//!   any address but loopback needs `http_token`;
//! - control (SDO writes, NMT, switch-overs, LSS) is off unless the file turns it on, with
//!   `http_control_token` (16 characters or more, not `http_token`: requests carry it), or
//!   `http_control = "loopback"`, which opens control to every client of a loopback address
//!   and is refused on any other address and beside `http_token` (a station whose reads need a
//!   token gives control a token of its own).
//!
//! With `http_tls_cert` and `http_tls_key` it serves HTTPS instead ([`super::tls`]); the rule
//! stays the same (tokens travel encrypted then).
//!
//! `http_max_connections` bounds the connections open at once (REST, event streams and
//! dashboards together; [`HTTP_MAX_CONNECTIONS`] by default, 1 to [`HTTP_CONNECTIONS_LIMIT`]):
//! one more is answered 503 and closed.

use super::{Source, StationTable};
use toml::Spanned;

/// Who may send control requests.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Control {
    /// Nobody: the station is only watched (the default).
    Off,
    /// Every client of the station's loopback address (`http_control = "loopback"`).
    Loopback,
    /// Whoever carries this token (`http_control_token`).
    Token(String),
}

/// Where the station serves HTTP, and to whom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Http {
    /// The address and port.
    pub addr: std::net::SocketAddr,
    /// The read-only token, if reads need one.
    pub token: Option<String>,
    /// Who may control.
    pub control: Control,
    /// The certificate and key of HTTPS, if the station serves it (else plain HTTP).
    pub tls: Option<super::Tls>,
    /// Most connections open at once; more are refused (503).
    pub max_connections: usize,
}

/// [`Http::max_connections`] when the file does not say: a few dashboards, scripts and
/// monitoring scrapes, each with a connection or two.
pub const HTTP_MAX_CONNECTIONS: usize = 64;
/// The most `http_max_connections` may be: each connection holds a file descriptor and its
/// buffers.
pub const HTTP_CONNECTIONS_LIMIT: usize = 4096;

/// The shortest token taken.
const MIN_TOKEN: usize = 16;

/// The HTTP settings of table `t`, checked.
pub(super) fn http(src: &Source<'_>, t: &StationTable) -> Result<Option<Http>, String> {
    let token = long_enough(src, t.http_token.as_ref(), "http_token")?;
    let control_token = long_enough(src, t.http_control_token.as_ref(), "http_control_token")?;
    let Some(at) = &t.http else {
        // A setting of HTTP without the address is an address forgotten.
        let others = [
            ("http_token", t.http_token.as_ref().map(Spanned::span)),
            (
                "http_control_token",
                t.http_control_token.as_ref().map(Spanned::span),
            ),
            ("http_control", t.http_control.as_ref().map(Spanned::span)),
            ("http_tls_cert", t.http_tls_cert.as_ref().map(Spanned::span)),
            ("http_tls_key", t.http_tls_key.as_ref().map(Spanned::span)),
            (
                "http_max_connections",
                t.http_max_connections.as_ref().map(Spanned::span),
            ),
        ];
        if let Some((key, Some(span))) = others.into_iter().find(|(_, s)| s.is_some()) {
            return Err(src.span(span, key, "set http too"));
        }
        return Ok(None);
    };
    let addr: std::net::SocketAddr = at.get_ref().trim().parse().map_err(|_| {
        let why = format!(
            "{:?} is not an address and port such as \"127.0.0.1:8080\"",
            at.get_ref()
        );
        src.span(at.span(), "http", why)
    })?;
    let loopback = addr.ip().is_loopback();
    if !loopback && token.is_none() {
        let why = format!("{addr} is reachable from other machines: set http_token too");
        return Err(src.span(at.span(), "http", why));
    }
    if let (Some(c), Some(r)) = (&control_token, &token) {
        if c == r {
            let span = t
                .http_control_token
                .as_ref()
                .map_or(at.span(), Spanned::span);
            let why = "the same as http_token: a reader's token must not control";
            return Err(src.span(span, "http_control_token", why));
        }
    }
    let control = match (&t.http_control, control_token) {
        (None, None) => Control::Off,
        (None, Some(c)) => Control::Token(c),
        (Some(c), token_too) => {
            let bad = |why: &str| src.span(c.span(), "http_control", why);
            match c.get_ref().trim() {
                "none" if token_too.is_none() => Control::Off,
                "loopback" if token_too.is_some() => {
                    return Err(bad("set it or http_control_token, not both"))
                }
                "loopback" if !loopback => {
                    return Err(bad(&format!(
                        "{addr} is reachable from other machines: set http_control_token instead"
                    )))
                }
                "loopback" if token.is_some() => {
                    return Err(bad(
                        "reads need http_token here: give control a token of its own \
                         (http_control_token) instead",
                    ))
                }
                "loopback" => Control::Loopback,
                "none" => return Err(bad("\"none\" beside http_control_token: leave one out")),
                other => {
                    return Err(bad(&format!(
                        "{other:?} is not allowed: \"none\" (the default) or \"loopback\" \
                         (any client of a loopback address may control)"
                    )))
                }
            }
        }
    };
    let max_connections = match &t.http_max_connections {
        None => HTTP_MAX_CONNECTIONS,
        Some(n) if (1..=HTTP_CONNECTIONS_LIMIT).contains(n.get_ref()) => *n.get_ref(),
        Some(n) => {
            let why = format!("1 to {HTTP_CONNECTIONS_LIMIT} connections");
            return Err(src.span(n.span(), "http_max_connections", why));
        }
    };
    Ok(Some(Http {
        addr,
        token,
        control,
        tls: super::tls::tls(src, t)?,
        max_connections,
    }))
}

/// The token of `key`, if given, checked for length.
fn long_enough(
    src: &Source<'_>,
    tk: Option<&Spanned<String>>,
    key: &str,
) -> Result<Option<String>, String> {
    match tk {
        Some(tk) if tk.get_ref().chars().count() < MIN_TOKEN => {
            Err(src.span(tk.span(), key, "at least 16 characters"))
        }
        Some(tk) => Ok(Some(tk.get_ref().clone())),
        None => Ok(None),
    }
}
