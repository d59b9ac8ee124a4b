//! The station's CiA 309-3 ASCII gateway: the tool's own gateway (`duocan gateway`, the same
//! parser, executor and connection handling), serving every network of the station, on a TCP
//! port and on a local socket (`gateway`, `gateway_socket`: [`super::config`]).
//!
//! A request's net number picks the network (each network's `gateway_net`, else its place in
//! the file from 1); a client starts on the file's first network, and `set network N` moves
//! it. A net no network has is `ERROR:106`, naming the nets there are. Both listeners share
//! one limit of clients at once; one past it is told `ERROR:102` and closed, and counted in
//! the log and in `/metrics` (`duocan_gateway_refused_total`, with the clients served now,
//! `duocan_gateway_clients`: [`Running::stats`]). A remote client is never refused at run
//! time: a TCP address other than loopback is refused by the check, unless
//! `gateway_allow_remote` opens it to all. They are bound before any network opens (a station that cannot serve its gateway
//! does not start), and close with the station: its clients are disconnected and the socket
//! file removed.

use super::config::{self, Gateway};
use crate::cmd::gateway::socket::{self, SocketFile};
use crate::cmd::gateway::{accept, GatewayListener, GatewayNets, GatewayStats, Served};
use crate::fail::Fail;
use duocan_redundancy::net::RedundantNetwork;

/// The gateway's listeners, bound and not yet serving.
#[derive(Debug)]
pub struct Bound {
    listeners: Vec<GatewayListener>,
    file: Option<SocketFile>,
}

/// Binds the listeners of `cfg`; the error names the key whose address cannot be taken.
pub async fn bind(cfg: &Gateway) -> Result<Bound, Fail> {
    let mut listeners = Vec::new();
    if let Some(addr) = cfg.tcp {
        let l = tokio::net::TcpListener::bind(addr)
            .await
            .map_err(|e| Fail::usage(format!("gateway: cannot listen on {addr}: {e}")))?;
        let local = l.local_addr()?;
        tracing::info!(target: "duocan::station", "309-3 gateway listening on {local}");
        listeners.push(GatewayListener::Tcp(l));
    }
    let mut file = None;
    if let Some(path) = &cfg.socket {
        let shown = path.display();
        let (l, f) = socket::bind(path, cfg.socket_mode).map_err(|why| {
            Fail::usage(format!("gateway_socket: cannot listen on {shown}: {why}"))
        })?;
        tracing::info!(target: "duocan::station", "309-3 gateway listening on {shown}");
        listeners.push(GatewayListener::Unix(l));
        file = Some(f);
    }
    Ok(Bound { listeners, file })
}

/// The gateway serving, until [`Running::stop`].
pub struct Running {
    stop: tokio::sync::watch::Sender<bool>,
    tasks: tokio::task::JoinSet<()>,
    file: Option<SocketFile>,
    stats: GatewayStats,
}

/// Serves `nets` (each with its network's settings) on the listeners of `bound`, each client
/// starting with the SDO time-out `timeout_ms`, at most `max_clients` at once.
pub fn start(
    bound: Bound,
    nets: &[(&config::Network, RedundantNetwork)],
    timeout_ms: u64,
    max_clients: usize,
) -> Running {
    let list = nets
        .iter()
        .map(|(n, net)| (n.gateway_net, n.name.clone(), (**net).clone()))
        .collect();
    let served = Served::new(GatewayNets::numbered(list), timeout_ms, max_clients, note);
    let stats = served.stats();
    let (stop, _) = tokio::sync::watch::channel(false);
    let mut tasks = tokio::task::JoinSet::new();
    for l in bound.listeners {
        let mut stopped = stop.subscribe();
        let stopping = async move {
            let _ = stopped.wait_for(|s| *s).await;
        };
        tasks.spawn(accept(l, served.clone(), stopping));
    }
    Running {
        stop,
        tasks,
        file: bound.file,
        stats,
    }
}

impl Running {
    /// Its clients' counts, live (what `/metrics` shows).
    #[must_use]
    pub fn stats(&self) -> GatewayStats {
        self.stats.clone()
    }

    /// Closes the listeners and every client's connection, then removes the socket file.
    pub async fn stop(mut self) {
        self.stop.send_replace(true);
        while self.tasks.join_next().await.is_some() {}
        drop(self.file.take());
        tracing::info!(target: "duocan::station", "309-3 gateway closed");
    }
}

/// What the listeners cannot tell a client, in the station's log.
fn note(what: &str) {
    tracing::warn!(target: "duocan::station", "309-3 gateway: {what}");
}
