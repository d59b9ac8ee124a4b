//! A station file: any number of logical networks, each a redundant master on two buses, read
//! from TOML and checked whole before anything is opened.
//!
//! ```toml
//! [station]
//! name = "depot"                   # optional: the file's name without .toml
//! audit_dir = "/var/lib/duocan/audit"   # optional: the persistent audit trail (relative:
//!                                  # to this file's folder), one file per network
//! audit_max_bytes = 1048576        # a file is rotated before it grows past this
//! audit_keep = 5                   # rotated files kept per network
//! http = "127.0.0.1:8080"          # optional: status and metrics over HTTP (port 0: any)
//! http_token = "…"                 # reads need it; needed for any address but loopback
//! http_control_token = "…"         # optional: control (SDO writes, NMT, LSS…) with it
//! http_control = "loopback"        # or: control open to loopback clients (default "none")
//! http_tls_cert = "tls/cert.pem"   # optional, with http_tls_key: HTTPS (PEM files, relative:
//! http_tls_key = "tls/key.pem"     # to this file's folder)
//! http_max_connections = 64        # connections open at once (more: 503)
//! mqtt = "127.0.0.1:1883"          # optional: report to the plant's MQTT broker (host:port)
//! mqtt_client_id = "duocan-depot"  # default: duocan-STATION
//! mqtt_prefix = "duocan/depot"     # every topic's first levels; default: duocan/STATION
//! mqtt_username = "…"              # optional, with mqtt_password if the broker asks
//! mqtt_outbox = 1024               # messages held while the broker is away
//! gateway = "127.0.0.1:5555"       # optional: the CiA 309-3 ASCII gateway on TCP (loopback
//!                                  # unless gateway_allow_remote = true: 309-3 has no
//!                                  # authentication)
//! gateway_socket = "gateway.sock"  # optional: and on a local socket (relative: to this
//!                                  # file's folder), mode gateway_socket_mode (0o600 or 0o660)
//! gateway_max_clients = 16         # clients at once, TCP and socket together
//!
//! [[network]]
//! name = "rack-1"                  # unique in the station
//! buses = "can0,can1"              # two interfaces as --bus names them (udp:N too), or
//!                                  # "sim-pairs" / "sim-pairs:quiet" /
//!                                  # "sim-pairs:failover" (simulated buses)
//! node_id = 1                      # this master
//! priority = 0                     # flying-master priority (lower wins)
//! heartbeat_ms = 50                # this master's heartbeat
//! master_timeout_ms = 150          # a silent master has failed after this long
//! sync_ms = 10                     # optional: SYNC production
//! time_ms = 1000                   # optional: TIME production (this machine's clock, UTC)
//! boot_timeout_ms = 2000           # optional: a slave's boot process gives up after this
//! pairs = [[0x10, 0x50], [0x11, 0x51]]   # A/B node-IDs
//! pair_heartbeat_ms = 50
//! pair_timeout_ms = 150
//! peers = [{ node = 2, priority = 1 }]   # the other masters of the network
//! boards = [{ node = 0x10, eds = "io.eds" }, { node = 0x50, dcf = "io-b.dcf" }]
//!                                  # optional: a pair member's EDS (names, types) or DCF
//!                                  # (and its values written at boot); see [`boards`]
//! profile = "predefined"           # the identifier profile: or "railway29" (see [`link`])
//! link = "active-active"           # the dual-bus policy: or "cia302-6", "ecss" ([`link`])
//! merge = "exact"                  # active-active's receive merge: or "sticky"
//! merge_timeout_ms = 40            # sticky: a sender's silence before it switches bus
//! default_bus = 1                  # cia302-6 / ecss: the bus to start on (1 or 2)
//! on_stop = "stop"                 # NMT to all nodes when the station stops: none (default),
//!                                  # stop, preop, reset, reset-comm
//! gateway_net = 1                  # its 309-3 net number (default: its place in the file,
//!                                  # from 1)
//! ```
//!
//! Every error names the file, the line and column, and the key, and says what is allowed:
//! the syntax and the keys by the TOML reader (an unknown key lists the known ones), the
//! values by the same checks the redundant network's builder makes, placed on the key that
//! holds the value.

use duocan::nmt::NmtCommand;
use duocan_redundancy::RedundantNetworkBuilder;
use serde::Deserialize;
use std::ops::Range;
use toml::Spanned;

pub mod boards;
mod gateway;
mod http;
pub mod link;
mod mqtt;
mod network;
mod tls;
pub use boards::Board;
pub use gateway::Gateway;
pub use http::{Control, Http, HTTP_MAX_CONNECTIONS};
pub use mqtt::Mqtt;
pub use tls::{server_config, Tls};

/// The simulated buses a network may name: the builder's plant with its fault script, and
/// the same plant without faults.
pub const SIM_BUSES: [&str; 3] = ["sim-pairs", "sim-pairs:quiet", "sim-pairs:failover"];

/// A checked station.
#[derive(Debug)]
pub struct Station {
    /// Its name.
    pub name: String,
    /// Where its audit trail is kept, if anywhere.
    pub audit: Option<Audit>,
    /// Where it serves HTTP, if anywhere, and to whom.
    pub http: Option<Http>,
    /// The MQTT broker it reports to, if any.
    pub mqtt: Option<Mqtt>,
    /// Where it serves the CiA 309-3 gateway, if anywhere.
    pub gateway: Option<Gateway>,
    /// Its networks, in file order.
    pub networks: Vec<Network>,
}

/// The persistent audit trail's settings (see [`super::audit`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Audit {
    /// The folder of the files.
    pub dir: std::path::PathBuf,
    /// A file is rotated before it grows past this.
    pub max_bytes: u64,
    /// Rotated files kept per network.
    pub keep: u32,
}

/// [`Audit::max_bytes`] when the file does not say.
pub const AUDIT_MAX_BYTES: u64 = 1 << 20;
/// [`Audit::keep`] when the file does not say.
pub const AUDIT_KEEP: u32 = 5;

/// A checked network.
#[derive(Debug)]
pub struct Network {
    /// Its name in the station.
    pub name: String,
    /// Its buses: a simulated plant's name, or two interfaces.
    pub buses: Buses,
    /// Its master's settings.
    pub builder: RedundantNetworkBuilder,
    /// What NMT command goes to all nodes when the station stops.
    pub on_stop: Option<NmtCommand>,
    /// Its CiA 309-3 net number on the station's gateway.
    pub gateway_net: u16,
    /// The device descriptions of its pairs' boards ([`boards`]).
    pub boards: Vec<Board>,
    /// Its identifier profile and dual-bus policy, as `check` shows them ([`link`]).
    pub link: link::Link,
}

/// Where a network runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Buses {
    /// One of [`SIM_BUSES`].
    Sim(String),
    /// Two interfaces, bus 1 first.
    Ports([String; 2]),
}

impl std::fmt::Display for Buses {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Buses::Sim(s) => f.write_str(s),
            Buses::Ports([a, b]) => write!(f, "{a},{b}"),
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    station: Option<StationTable>,
    #[serde(default)]
    network: Vec<Spanned<NetworkTable>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct StationTable {
    name: Option<String>,
    audit_dir: Option<Spanned<String>>,
    audit_max_bytes: Option<Spanned<u64>>,
    audit_keep: Option<u32>,
    http: Option<Spanned<String>>,
    http_token: Option<Spanned<String>>,
    http_control_token: Option<Spanned<String>>,
    http_control: Option<Spanned<String>>,
    http_tls_cert: Option<Spanned<String>>,
    http_tls_key: Option<Spanned<String>>,
    http_max_connections: Option<Spanned<usize>>,
    mqtt: Option<Spanned<String>>,
    mqtt_client_id: Option<Spanned<String>>,
    mqtt_prefix: Option<Spanned<String>>,
    mqtt_username: Option<Spanned<String>>,
    mqtt_password: Option<Spanned<String>>,
    mqtt_outbox: Option<Spanned<usize>>,
    gateway: Option<Spanned<String>>,
    gateway_allow_remote: Option<Spanned<bool>>,
    gateway_socket: Option<Spanned<String>>,
    gateway_socket_mode: Option<Spanned<u32>>,
    gateway_max_clients: Option<Spanned<usize>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NetworkTable {
    name: Spanned<String>,
    buses: Spanned<String>,
    node_id: Spanned<u8>,
    #[serde(default)]
    priority: u8,
    heartbeat_ms: Option<Spanned<u64>>,
    master_timeout_ms: Option<Spanned<u64>>,
    sync_ms: Option<Spanned<u64>>,
    time_ms: Option<Spanned<u64>>,
    boot_timeout_ms: Option<Spanned<u64>>,
    #[serde(default)]
    pairs: Option<Spanned<Vec<[u8; 2]>>>,
    pair_heartbeat_ms: Option<Spanned<u64>>,
    pair_timeout_ms: Option<Spanned<u64>>,
    #[serde(default)]
    peers: Option<Spanned<Vec<Peer>>>,
    boards: Option<Spanned<Vec<Spanned<boards::BoardTable>>>>,
    profile: Option<Spanned<String>>,
    link: Option<Spanned<String>>,
    merge: Option<Spanned<String>>,
    merge_timeout_ms: Option<Spanned<u64>>,
    default_bus: Option<Spanned<i64>>,
    on_stop: Option<Spanned<String>>,
    gateway_net: Option<Spanned<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Peer {
    node: u8,
    #[serde(default)]
    priority: u8,
}

/// The file's text and name, to place errors.
struct Source<'a> {
    name: &'a str,
    text: &'a str,
}

impl Source<'_> {
    /// `file:line:column: what` for the byte offset `at` (lines and columns from 1).
    fn at(&self, at: usize, what: impl std::fmt::Display) -> String {
        // A span is a byte offset; one inside a character counts from the character's start.
        let mut at = at.min(self.text.len());
        while !self.text.is_char_boundary(at) {
            at -= 1;
        }
        let before = &self.text[..at];
        let line = before.matches('\n').count() + 1;
        let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        format!("{}:{line}:{col}: {what}", self.name)
    }
    fn span(&self, span: Range<usize>, key: &str, what: impl std::fmt::Display) -> String {
        self.at(span.start, format_args!("{key}: {what}"))
    }
}

/// Reads and checks the station in `text`; `name` (the file's path) names it in errors.
pub fn parse(text: &str, name: &str) -> Result<Station, String> {
    let src = Source { name, text };
    let file: File = toml::from_str(text).map_err(|e| {
        let at = e.span().map_or(0, |s| s.start);
        src.at(at, e.message().trim_end())
    })?;
    if file.network.is_empty() {
        return Err(format!(
            "{name}: no [[network]]: a station runs at least one (see `duocan station --help`)"
        ));
    }
    let (audit, http) = match &file.station {
        Some(t) => (audit(&src, t)?, http::http(&src, t)?),
        None => (None, None),
    };
    let station = file
        .station
        .as_ref()
        .and_then(|s| s.name.clone())
        .unwrap_or_else(|| stem(name));
    let mqtt = match &file.station {
        Some(t) => mqtt::mqtt(&src, t, &station)?,
        None => None,
    };
    let gateway = match &file.station {
        Some(t) => gateway::gateway(&src, t)?,
        None => None,
    };
    let mut names = Vec::new();
    let mut networks: Vec<Network> = Vec::new();
    let mut nets = Vec::new();
    for n in file.network {
        let span = n.span();
        let t = n.into_inner();
        let (name_at, buses_at) = (t.name.span(), t.buses.span());
        let given_net = t.gateway_net.clone();
        let net = network::network(&src, t, span)?;
        if networks.iter().any(|o| o.name == net.name) {
            let why = format!("{:?} names two networks: each has its own name", net.name);
            return Err(src.span(name_at, "name", why));
        }
        // Two masters of one station on one interface would be two networks on one bus.
        if let Buses::Ports(mine) = &net.buses {
            for o in &networks {
                if let Buses::Ports(theirs) = &o.buses {
                    if let Some(p) = mine.iter().find(|p| theirs.contains(p)) {
                        let why = format!("{p} is a bus of network {:?} already", o.name);
                        return Err(src.span(buses_at, "buses", why));
                    }
                }
            }
        }
        nets.push((given_net, net.name.clone(), name_at.clone()));
        names.push((net.name.clone(), name_at));
        networks.push(net);
    }
    if mqtt.is_some() {
        mqtt::distinct_topics(&src, &names)?;
    }
    for (net, number) in networks.iter_mut().zip(gateway::net_numbers(&src, &nets)?) {
        net.gateway_net = number;
    }
    Ok(Station {
        name: station,
        audit,
        http,
        mqtt,
        gateway,
        networks,
    })
}

/// The audit trail's settings of the `[station]` table, its folder relative to the file's.
fn audit(src: &Source<'_>, t: &StationTable) -> Result<Option<Audit>, String> {
    let Some(dir) = &t.audit_dir else {
        if let Some(m) = &t.audit_max_bytes {
            return Err(src.span(m.span(), "audit_max_bytes", "set audit_dir too"));
        }
        return Ok(None);
    };
    if dir.get_ref().trim().is_empty() {
        return Err(src.span(dir.span(), "audit_dir", "a folder, or leave the key out"));
    }
    let max_bytes = t
        .audit_max_bytes
        .as_ref()
        .map_or(AUDIT_MAX_BYTES, |m| *m.get_ref());
    if max_bytes < 4096 {
        let at = t.audit_max_bytes.as_ref().map_or(dir.span(), Spanned::span);
        return Err(src.span(
            at,
            "audit_max_bytes",
            "at least 4096 (a record is a line of up to some 200 bytes)",
        ));
    }
    let base = std::path::Path::new(src.name)
        .parent()
        .unwrap_or(std::path::Path::new(""));
    Ok(Some(Audit {
        dir: base.join(dir.get_ref().trim()),
        max_bytes,
        keep: t.audit_keep.unwrap_or(AUDIT_KEEP),
    }))
}

/// The file's name without its folder and extension.
fn stem(path: &str) -> String {
    std::path::Path::new(path)
        .file_stem()
        .map_or_else(|| path.to_string(), |s| s.to_string_lossy().into_owned())
}

#[cfg(test)]
mod tests;
