//! The `gateway*` keys of the `[station]` table and `gateway_net` of each `[[network]]`: the
//! CiA 309-3 ASCII gateway the station serves on a TCP port and on a local socket (see
//! [`crate::cmd::station::gateway`]).
//!
//! 309-3 has no authentication: whoever reaches the gateway drives every network of the
//! station. So the TCP address is loopback unless `gateway_allow_remote = true` says
//! otherwise, and the socket file is its owner's (`gateway_socket_mode = 0o600`, the default)
//! or its owner's and group's (`0o660`), never everyone's.
//!
//! Each network answers to a net number: its `gateway_net`, else its place in the file from 1.

use super::{Source, StationTable};
use std::net::SocketAddr;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// Where the station serves the 309-3 gateway, and to how many clients.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Gateway {
    /// The TCP address and port, if it serves one.
    pub tcp: Option<SocketAddr>,
    /// The local socket's path, if it serves one.
    pub socket: Option<PathBuf>,
    /// The socket file's permission bits.
    pub socket_mode: u32,
    /// Most clients served at once, TCP and socket together.
    pub max_clients: usize,
}

/// [`Gateway::socket_mode`] when the file does not say: the owner's only.
pub const GATEWAY_SOCKET_MODE: u32 = 0o600;
/// [`Gateway::max_clients`] when the file does not say (the standalone gateway's limit).
pub const GATEWAY_MAX_CLIENTS: usize = crate::cmd::gateway::MAX_CLIENTS;
/// The longest socket path the system takes (`sun_path` holds 108 bytes with its NUL).
const MAX_SOCKET_PATH: usize = 107;

/// The gateway settings of table `t`, checked.
pub(super) fn gateway(src: &Source<'_>, t: &StationTable) -> Result<Option<Gateway>, String> {
    if t.gateway.is_none() && t.gateway_socket.is_none() {
        // A setting of the gateway without where it listens is an address forgotten.
        let others = [
            (
                "gateway_allow_remote",
                t.gateway_allow_remote.as_ref().map(Spanned::span),
            ),
            (
                "gateway_socket_mode",
                t.gateway_socket_mode.as_ref().map(Spanned::span),
            ),
            (
                "gateway_max_clients",
                t.gateway_max_clients.as_ref().map(Spanned::span),
            ),
        ];
        if let Some((key, Some(span))) = others.into_iter().find(|(_, s)| s.is_some()) {
            return Err(src.span(span, key, "set gateway or gateway_socket too"));
        }
        return Ok(None);
    }
    let remote = t
        .gateway_allow_remote
        .as_ref()
        .is_some_and(|r| *r.get_ref());
    let tcp = match &t.gateway {
        None => {
            if let Some(r) = &t.gateway_allow_remote {
                return Err(src.span(r.span(), "gateway_allow_remote", "set gateway too"));
            }
            None
        }
        Some(at) => Some(tcp(src, at, remote)?),
    };
    let socket = match &t.gateway_socket {
        None => {
            if let Some(m) = &t.gateway_socket_mode {
                let why = "set gateway_socket too";
                return Err(src.span(m.span(), "gateway_socket_mode", why));
            }
            None
        }
        Some(p) => Some(socket(src, p)?),
    };
    let socket_mode = match &t.gateway_socket_mode {
        None => GATEWAY_SOCKET_MODE,
        Some(m) if matches!(*m.get_ref(), 0o600 | 0o660) => *m.get_ref(),
        Some(m) => {
            let why = format!(
                "{:#o} is not allowed: 0o600 (its owner only, the default) or 0o660 (its owner \
                 and group); CiA 309-3 has no authentication, so others may not connect",
                m.get_ref()
            );
            return Err(src.span(m.span(), "gateway_socket_mode", why));
        }
    };
    let max_clients = match &t.gateway_max_clients {
        None => GATEWAY_MAX_CLIENTS,
        Some(n) if (1..=256).contains(n.get_ref()) => *n.get_ref(),
        Some(n) => {
            return Err(src.span(n.span(), "gateway_max_clients", "1 to 256 clients"));
        }
    };
    Ok(Some(Gateway {
        tcp,
        socket,
        socket_mode,
        max_clients,
    }))
}

/// `gateway`: an address and port, loopback unless `remote`.
fn tcp(src: &Source<'_>, at: &Spanned<String>, remote: bool) -> Result<SocketAddr, String> {
    let addr: SocketAddr = at.get_ref().trim().parse().map_err(|_| {
        let why = format!(
            "{:?} is not an address and port such as \"127.0.0.1:5555\"",
            at.get_ref()
        );
        src.span(at.span(), "gateway", why)
    })?;
    if !addr.ip().is_loopback() && !remote {
        let why = format!(
            "{addr} is reachable from other machines, and CiA 309-3 has no authentication: \
             anyone who reaches it drives every network. Use gateway_socket, or a loopback \
             address and SSH; or set gateway_allow_remote = true to serve it anyway"
        );
        return Err(src.span(at.span(), "gateway", why));
    }
    Ok(addr)
}

/// `gateway_socket`: a path, relative to the station file's folder.
fn socket(src: &Source<'_>, p: &Spanned<String>) -> Result<PathBuf, String> {
    let text = p.get_ref().trim();
    if text.is_empty() {
        let why = "a socket file's path, or leave the key out";
        return Err(src.span(p.span(), "gateway_socket", why));
    }
    let base = Path::new(src.name).parent().unwrap_or(Path::new(""));
    let path = base.join(text);
    let len = path.as_os_str().len();
    if len > MAX_SOCKET_PATH {
        let why = format!(
            "{} is {len} bytes long; a socket's path is at most {MAX_SOCKET_PATH}",
            path.display()
        );
        return Err(src.span(p.span(), "gateway_socket", why));
    }
    Ok(path)
}

/// A network's `gateway_net` as the file gives it, its name, and where its name stands.
pub(super) type GivenNet = (Option<Spanned<i64>>, String, Range<usize>);

/// Each network's net number, in file order: its `gateway_net` (1 to 65535), else its place
/// in the file from 1; no two alike.
pub(super) fn net_numbers(src: &Source<'_>, tables: &[GivenNet]) -> Result<Vec<u16>, String> {
    let mut numbers: Vec<u16> = Vec::new();
    for (i, (given, name, name_at)) in tables.iter().enumerate() {
        let n = match given {
            Some(g) => u16::try_from(*g.get_ref())
                .ok()
                .filter(|&n| n != 0)
                .ok_or_else(|| {
                    src.span(
                        g.span(),
                        "gateway_net",
                        "a CiA 309-3 net number, 1 to 65535",
                    )
                })?,
            // Past 65535 networks no station goes; a number is still not made up.
            None => u16::try_from(i + 1).unwrap_or(u16::MAX),
        };
        if let Some(j) = numbers.iter().position(|&m| m == n) {
            let other = &tables[j].1;
            return Err(match given {
                Some(g) => {
                    let why = format!("net {n} is network {other:?}'s already: give each its own");
                    src.span(g.span(), "gateway_net", why)
                }
                None => {
                    let why = format!(
                        "network {name:?} is net {n} by its place in the file, and network \
                         {other:?} has that number by its gateway_net: give {name:?} a \
                         gateway_net of its own"
                    );
                    src.span(name_at.clone(), "gateway_net", why)
                }
            });
        }
        numbers.push(n);
    }
    Ok(numbers)
}

#[cfg(test)]
#[path = "gateway_tests.rs"]
mod tests;
