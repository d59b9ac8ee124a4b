//! `duocan station check|run FILE`: a whole station from one file — any number of logical
//! networks, each a redundant master (CiA 302-2, A/B pair supervisor, flying master) on two
//! buses — checked, or run until stopped.
//!
//! ```text
//! duocan station check examples/station/demo.toml
//! duocan station run examples/station/demo.toml     # until SIGINT or SIGTERM
//! ```
//!
//! `run` opens every network (none if one cannot be opened: the error names it), logs each
//! network's events as one line each through `tracing` on standard error (warnings for
//! failovers; `DUOCAN_LOG` filters as `RUST_LOG` does, by default the station's events and
//! the library's warnings; without timestamps under systemd,
//! whose journal stamps each line itself), and on SIGINT or SIGTERM sends each network's
//! `on_stop` NMT command, closes the networks and exits 0. With an `audit_dir`, each network's
//! audit records are appended to a file of their own as they happen, durably ([`audit`]). With
//! an `http` address, it serves its status, metrics, events and a dashboard for a browser
//! ([`http`], [`dashboard`]; HTTPS with `http_tls_cert` and `http_tls_key`: [`tls`]), and SDO, NMT and switch-overs to the roles the file allows
//! ([`rest`], [`access`]). With `mqtt`, the networks' state and events go to the plant's
//! broker ([`mqtt`]). With `gateway` or `gateway_socket`, it serves the CiA 309-3 ASCII
//! gateway over all of its networks ([`gateway`]). The file format: [`config`].

pub mod access;
pub mod audit;
pub mod config;
pub mod conns;
pub mod dashboard;
pub mod gateway;
pub mod http;
mod metrics;
pub mod mqtt;
pub mod rest;
mod summary;
pub mod tls;

use crate::args::parse_timeout_ms;
use crate::fail::Fail;
use crate::{ports, Global};
use audit::AuditLog;
use config::{Buses, Network};
use duocan_redundancy::net::RedundantNetwork;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// `duocan station` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum Station {
    /// Check a station file (every error names the file, line and key) and print what it runs
    Check {
        /// The station file (TOML)
        file: PathBuf,
    },
    /// Run a station's networks until SIGINT or SIGTERM, logging their events
    Run {
        /// The station file (TOML)
        file: PathBuf,
        /// Stop after this long (default: run until interrupted)
        #[arg(long, value_parser = parse_timeout_ms)]
        duration_ms: Option<u64>,
    },
}

/// Reads and checks the station file at `path`.
pub fn load(path: &Path) -> Result<config::Station, Fail> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path)
        .map_err(|e| Fail::usage(format!("{name}: cannot read the station file: {e}")))?;
    config::parse(&text, &name).map_err(Fail::usage)
}

/// Runs `duocan station`.
pub async fn run(g: &Global, s: Station) -> Result<(), Fail> {
    match s {
        Station::Check { file } => {
            let st = load(&file)?;
            print!("{}", summary::summary(&st));
            Ok(())
        }
        Station::Run { file, duration_ms } => {
            let st = load(&file)?;
            logging();
            serve(g, &st, duration_ms).await
        }
    }
}

/// Logs to standard error, one line per record; `DUOCAN_LOG` filters (default: the station's
/// events, and the library's warnings).
fn logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_env("DUOCAN_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn,duocan::station=info"));
    let fmt = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(false);
    // systemd says so when standard error goes to its journal, which stamps every line.
    let _ = if std::env::var_os("JOURNAL_STREAM").is_some() {
        fmt.without_time().try_init()
    } else {
        fmt.try_init()
    };
}

/// Opens network `n`.
fn open(g: &Global, n: &Network) -> Result<RedundantNetwork, Fail> {
    let failed = |e: &dyn std::fmt::Display| Fail::bus(format!("network {}: {e}", n.name));
    match &n.buses {
        Buses::Sim(name) => n.builder.open_named(name).map_err(|e| failed(&e)),
        Buses::Ports([a, b]) => {
            let pa = ports::open(a, g.udp_interface).map_err(|e| failed(&e))?;
            let pb = ports::open(b, g.udp_interface).map_err(|e| failed(&e))?;
            n.builder.open(pa, pb).map_err(|e| failed(&e))
        }
    }
}

/// Runs the station until stopped.
async fn serve(g: &Global, st: &config::Station, duration_ms: Option<u64>) -> Result<(), Fail> {
    // Taken before anything opens: a signal from now on stops the station cleanly.
    use tokio::signal::unix::{signal, SignalKind};
    let mut term = signal(SignalKind::terminate())?;
    let mut int = signal(SignalKind::interrupt())?;
    // The audit files open first: a station that cannot keep its trail does not start.
    let mut logs_of = Vec::new();
    for n in &st.networks {
        logs_of.push(match &st.audit {
            Some(a) => Some(Arc::new(std::sync::Mutex::new(
                AuditLog::open(&a.dir, &n.name, a.max_bytes, a.keep).map_err(|e| {
                    Fail::usage(format!(
                        "network {}: audit trail in {}: {e}",
                        n.name,
                        a.dir.display()
                    ))
                })?,
            ))),
            None => None,
        });
    }
    // So does its HTTP address, and the certificate of HTTPS read again (it may have changed
    // since the file was checked): taken before any network opens.
    let listener = match &st.http {
        Some(h) => Some(
            tokio::net::TcpListener::bind(h.addr)
                .await
                .map_err(|e| Fail::usage(format!("http: cannot listen on {}: {e}", h.addr)))?,
        ),
        None => None,
    };
    let tls = match st.http.as_ref().and_then(|h| h.tls.as_ref()) {
        Some(t) => Some(
            config::server_config(t).map_err(|(key, why)| Fail::usage(format!("{key}: {why}")))?,
        ),
        None => None,
    };
    // And the 309-3 gateway's TCP port and socket.
    let gateway = match &st.gateway {
        Some(gw) => Some((gateway::bind(gw).await?, gw.max_clients)),
        None => None,
    };
    let run = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
        .as_millis();
    let mut nets: Vec<(&Network, RedundantNetwork)> = Vec::new();
    for n in &st.networks {
        match open(g, n) {
            Ok(net) => nets.push((n, net)),
            Err(e) => {
                for (_, net) in &nets {
                    net.close().await;
                }
                return Err(e);
            }
        }
        tracing::info!(target: "duocan::station", network = %n.name, buses = %n.buses, "started");
        // Each board's description: its names and types for SDO by name.
        if let Some((_, net)) = nets.last() {
            for b in &n.boards {
                for w in &b.desc.warnings {
                    tracing::warn!(target: "duocan::station", network = %n.name,
                        node = b.node, "{w}");
                }
                net.add_node(b.node, b.desc.clone());
            }
        }
    }
    tracing::info!(target: "duocan::station", station = %st.name, networks = nets.len(), "running");
    let mut logs = tokio::task::JoinSet::new();
    let (stop_audit, _) = tokio::sync::watch::channel(false);
    let mut audits = tokio::task::JoinSet::new();
    let mut watched = Vec::new();
    for ((n, net), log) in nets.iter().zip(logs_of) {
        let mut events = net.events();
        let name = n.name.clone();
        let w = Arc::new(http::Watched {
            name: n.name.clone(),
            buses: n.buses.to_string(),
            net: net.clone(),
            events: AtomicU64::new(0),
            failovers: AtomicU64::new(0),
            recent: dashboard::Recent::default(),
            audit: log.as_ref().map(|log| http::Operators {
                log: log.clone(),
                run,
            }),
        });
        watched.push(w.clone());
        logs.spawn(async move {
            while let Some(e) = events.next().await {
                w.events.fetch_add(1, Ordering::Relaxed);
                w.recent.push(&e);
                if e.is_failover() {
                    w.failovers.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(target: "duocan::station", network = %name, "{e}");
                } else {
                    tracing::info!(target: "duocan::station", network = %name, "{e}");
                }
            }
        });
        if let Some(log) = log {
            let keeper = Keeper {
                net: net.clone(),
                name: n.name.clone(),
                log,
                run,
                next: 1,
            };
            audits.spawn(keeper.run(stop_audit.subscribe()));
        }
    }
    let plant = st.mqtt.as_ref().map(|m| mqtt::start(m, &watched));
    let gateway = gateway.map(|(bound, max)| gateway::start(bound, &nets, g.timeout, max));
    if let Some(listener) = listener {
        let local = listener.local_addr()?;
        let scheme = if tls.is_some() { "https" } else { "http" };
        tracing::info!(target: "duocan::station", "{scheme} listening on {local}");
        let gw = gateway.as_ref().map(gateway::Running::stats);
        let max = st
            .http
            .as_ref()
            .map_or(config::HTTP_MAX_CONNECTIONS, |h| h.max_connections);
        let conns = conns::ConnStats::new(max);
        let access = access::Access::new(st.http.as_ref());
        let app = http::router(watched, access, gw, conns.clone());
        // Each request knows its client's address: control actions are logged with it.
        let app = app.into_make_service_with_connect_info::<std::net::SocketAddr>();
        logs.spawn(tls::serve(listener, tls, app, conns));
    }
    let timer = async {
        match duration_ms {
            Some(ms) => tokio::time::sleep(std::time::Duration::from_millis(ms)).await,
            None => std::future::pending().await,
        }
    };
    let why = tokio::select! {
        () = timer => "its time is up",
        _ = term.recv() => "SIGTERM",
        _ = int.recv() => "SIGINT",
    };
    tracing::info!(target: "duocan::station", station = %st.name, "stopping: {why}");
    // No more requests from outside while the networks close.
    if let Some(gw) = gateway {
        gw.stop().await;
    }
    // The records up to the stop written before the networks close.
    stop_audit.send_replace(true);
    while audits.join_next().await.is_some() {}
    if let Some(p) = plant {
        p.stop().await;
    }
    for (n, net) in &nets {
        if let Some(cmd) = n.on_stop {
            match net.nmt_all(cmd).await {
                Ok(()) => {
                    tracing::info!(target: "duocan::station", network = %n.name, "on_stop: {cmd:?} sent to every node")
                }
                Err(e) => {
                    tracing::warn!(target: "duocan::station", network = %n.name, "on_stop: {e}")
                }
            }
        }
        net.close().await;
    }
    logs.abort_all();
    tracing::info!(target: "duocan::station", station = %st.name, "stopped");
    Ok(())
}

/// How often the audit keeper reads a network's new records.
const AUDIT_EVERY: std::time::Duration = std::time::Duration::from_millis(100);

/// Copies one network's new audit records into its file as they come.
struct Keeper {
    net: RedundantNetwork,
    name: String,
    /// Shared with the HTTP side, which appends operators' actions.
    log: Arc<std::sync::Mutex<AuditLog>>,
    run: u128,
    /// The sequence number of the next record to write.
    next: u32,
}

impl Keeper {
    async fn run(mut self, mut stop: tokio::sync::watch::Receiver<bool>) {
        loop {
            let stopping = tokio::select! {
                () = tokio::time::sleep(AUDIT_EVERY) => false,
                _ = stop.wait_for(|s| *s) => true,
            };
            // A network closed by its own plant (a simulated script's end) has no more.
            if !self.write_new().await || stopping {
                break;
            }
        }
        let path = self.lock().path().display().to_string();
        tracing::info!(target: "duocan::station::audit", network = %self.name,
            file = %path, "audit closed");
    }

    /// Writes the records since the last; false when the network has closed.
    async fn write_new(&mut self) -> bool {
        let next = self.next;
        let got = self
            .net
            .with(move |n, _| {
                let trail = n.audit();
                // The oldest record the trail still holds, to tell what was overwritten.
                let oldest = trail.iter().next().map(|r| r.seq);
                let lines: Vec<(u32, String)> = trail
                    .since(next.saturating_sub(1))
                    .map(|r| (r.seq, r.to_string()))
                    .collect();
                (oldest, lines)
            })
            .await;
        let Ok((oldest, lines)) = got else {
            return false;
        };
        if let Some(first) = oldest.filter(|&o| o > self.next) {
            let lost = first - self.next;
            tracing::warn!(target: "duocan::station::audit", network = %self.name, lost,
                "audit records overwritten before they were written");
            let line = format!(
                "{} run={} {lost} records overwritten before they were written",
                audit::wall(),
                self.run
            );
            self.write(&line, None);
        }
        for (seq, text) in lines {
            if seq < self.next {
                continue;
            }
            let line = format!("{} run={} {text}", audit::wall(), self.run);
            self.write(&line, Some(seq));
            self.next = seq + 1;
        }
        true
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, AuditLog> {
        // A writer that panicked left the file as it was: go on with it.
        self.log
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn write(&mut self, line: &str, seq: Option<u32>) {
        let mut log = self.lock();
        match log.append(line) {
            Ok(()) => tracing::debug!(target: "duocan::station::audit", network = %self.name,
                run = self.run, seq, "written"),
            Err(e) => tracing::error!(target: "duocan::station::audit", network = %self.name,
                file = %log.path().display(), "cannot write the audit record: {e}"),
        }
    }
}
