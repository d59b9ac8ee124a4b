//! The station's HTTP access: what each network is doing, for people and for a plant's
//! monitoring.
//!
//! - `GET /`: the dashboard, a page for a browser that shows all of the below as it changes
//!   ([`dashboard`](super::dashboard)).
//! - `GET /api/networks`: every network as JSON — its buses, whether it is open, this master's
//!   role, each master's (`masters`: this one and its peers, node-ID, priority, role as this
//!   master knows it, when a peer was last heard), the dual-bus policy it runs (`link`: active-active, CiA 302-6 active-standby or
//!   ECSS bus toggle), each port's state and counters, each pair's running board, the node table (state,
//!   heard on which bus, last EMCY) and its last events with their times.
//! - `GET /metrics`: the same as Prometheus metrics (text format 0.0.4): frames, error frames,
//!   dropped frames and re-opens per port, port up, each port's lag behind the other (as the
//!   dual-bus layer measures it), master active, running board per pair,
//!   events and failovers per network; with a broker, the MQTT publisher's (`duocan_mqtt_*`);
//!   with a 309-3 gateway, its clients refused for want of room
//!   (`duocan_gateway_refused_total{reason="too_many_clients"}`), served now and at most
//!   (`duocan_gateway_clients`, `duocan_gateway_max_clients`).
//! - `GET /api/events`: every network's events from now on, as server-sent events: one
//!   `event: NETWORK` with the event's one line as its data, each as it happens. A client that
//!   falls behind the network's bounded event queue is told how many it missed (`data: missed
//!   N events`) and goes on with the newest; at most [`MAX_STREAMS`] streams at once (more get
//!   503).
//! - `GET /api/role`: what the request's token may do, `{"role": "read"}` or `{"role":
//!   "control"}` (the dashboard shows operator actions to the latter only).
//!
//! - SDO reads and writes, NMT, forced switch-overs and LSS on any network, JSON in and out
//!   ([`rest`](super::rest), which lists the routes, their roles and their errors).
//!
//! **Security.** The station listens on loopback unless its file names another address, and
//! then only with a read token (`http_token`): every request must carry `Authorization: Bearer
//! TOKEN` or gets 401 (the dashboard's 401 is a page that sends the token of its address's
//! fragment: `/#token=TOKEN`). Control (SDO writes, NMT, switch-overs, LSS) is off unless the
//! file gives it a token of its own (`http_control_token`) or, on loopback alone, opens it to
//! loopback clients (`http_control = "loopback"`); a read token there is 403. Read and
//! control requests are bounded in rate, each kind on its own (429 over it:
//! [`access`](super::access)). Anything but these routes is 404; another method is 405.
//! Bodies are bounded ([`rest::MAX_BODY`](super::rest::MAX_BODY), 413 over it); at most
//! [`MAX_CLIENTS`] status and metrics requests are worked on at once (more wait for their
//! turn), and at most `http_max_connections` connections are open at once (one more is 503:
//! [`conns`](super::conns)). `/metrics` counts the refusals
//! (`duocan_http_refused_total{reason=…}`: `too_many_connections`, `read_rate`,
//! `control_rate`) and the connections open (`duocan_http_connections`,
//! `duocan_http_max_connections`).
//!
//! **TLS.** With `http_tls_cert` and `http_tls_key` the station serves all of this over HTTPS
//! only (rustls; [`tls`](super::tls) shakes hands before a connection reaches the router, and
//! [`config::Tls`](super::config::Tls) says what the files hold). The rules above stay as
//! they are; the tokens travel encrypted.

use super::access::{error, unauthorized, Access};
use super::audit::AuditLog;
use super::conns::ConnStats;
use super::dashboard::{self, Recent};
use crate::cmd::gateway::GatewayStats;
use axum::extract::State;
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;
use duocan_redundancy::net::RedundantNetwork;
use duocan_redundancy::supervisor::flying_master::{FlyingMaster, MasterRole};
use duocan_redundancy::Member;
use serde_json::json;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tokio::sync::Semaphore;

/// Requests served at once.
pub const MAX_CLIENTS: usize = 16;
/// Event streams open at once.
pub const MAX_STREAMS: usize = 8;
/// Events a stream's client may be behind before it misses some.
pub const STREAM_QUEUE: usize = 256;

/// One network as the HTTP side sees it.
pub struct Watched {
    /// Its name.
    pub name: String,
    /// Its buses, as the file gave them.
    pub buses: String,
    /// The network.
    pub net: RedundantNetwork,
    /// Events so far.
    pub events: AtomicU64,
    /// Failovers so far (bus, master, pair).
    pub failovers: AtomicU64,
    /// Its last events and each node's last EMCY (the dashboard's timeline and node table).
    pub recent: Recent,
    /// Its audit file, if the station keeps a trail: operators' actions go there too.
    pub audit: Option<Operators>,
}

/// A network's audit file as the HTTP side writes to it.
pub struct Operators {
    /// The file, shared with the keeper that copies the network's own records.
    pub log: Arc<std::sync::Mutex<AuditLog>>,
    /// The station's run (its start in Unix milliseconds).
    pub run: u128,
}

/// What every request's handler sees.
pub(super) struct Shared {
    pub(super) networks: Vec<Arc<Watched>>,
    pub(super) access: Access,
    pub(super) turns: Semaphore,
    streams: Arc<Semaphore>,
    pub(super) gateway: Option<GatewayStats>,
    pub(super) conns: ConnStats,
}

/// The router over `networks`, under the rules of `access`; `gateway`: the station's 309-3
/// gateway's counts, for `/metrics`, if it serves one; `conns`: the connections its listener
/// holds and refuses ([`conns`](super::conns)), for `/metrics`.
pub fn router(
    networks: Vec<Arc<Watched>>,
    access: Access,
    gateway: Option<GatewayStats>,
    conns: ConnStats,
) -> Router {
    let shared = Arc::new(Shared {
        networks,
        access,
        gateway,
        conns,
        turns: Semaphore::new(MAX_CLIENTS),
        streams: Arc::new(Semaphore::new(MAX_STREAMS)),
    });
    Router::new()
        .route("/", get(page))
        .route("/api/networks", get(networks_json))
        .route("/metrics", get(super::metrics::metrics))
        .route("/api/events", get(events))
        .route("/api/role", get(role))
        .merge(super::rest::routes())
        .fallback(|| async {
            error(
                StatusCode::NOT_FOUND,
                "no such page: /, /api/networks (and under it each network's nodes/ID/sdo/, \
                 nmt and pairs/ID/switch), /api/events, /api/role and /metrics are served",
            )
        })
        .layer(axum::middleware::from_fn_with_state(
            shared.clone(),
            read_rate,
        ))
        .with_state(shared)
}

/// Takes a read request (`GET`, `HEAD`) from the read rate once its role is checked: a
/// request without the token it needs is refused by its route (401), at no cost to readers.
async fn read_rate(
    State(s): State<Arc<Shared>>,
    req: axum::extract::Request,
    next: axum::middleware::Next,
) -> Response {
    use axum::http::Method;
    let read = matches!(*req.method(), Method::GET | Method::HEAD);
    if read && s.access.may_read(req.headers()) {
        if let Err(refused) = s.access.read_rate() {
            return refused;
        }
    }
    next.run(req).await
}

/// What is known of one network now.
pub(super) struct View {
    /// This master's role (none: the network is closed).
    pub(super) role: Option<MasterRole>,
    /// Its ports.
    pub(super) ports: Vec<duocan::net::PortView>,
    /// Each pair (`A/B` node-IDs) and its running board.
    pub(super) pairs: Vec<(String, Option<Member>)>,
    /// The dual-bus layer's policy as it runs (`link` of the file).
    link: Option<String>,
    /// How much later each port's copies come than the other port's, as the dual-bus layer
    /// measures it (its lag meter; zero for the earlier port), in microseconds.
    pub(super) lag_us: [u64; 2],
    /// This master and its peers, as its flying master knows them (this master first).
    masters: Vec<serde_json::Value>,
}

/// This master and each peer master of `n` as JSON: node-ID, priority, role and, for a peer,
/// how long ago it was last heard. A peer's role is what this master can tell: `active` (the
/// master it follows), `standby` (heard, not active),
/// `lost` (silent longer than the master timeout) or `unheard` (never heard since the start).
fn masters(fm: &FlyingMaster, now: duocan::Instant) -> Vec<serde_json::Value> {
    let me = fm.rank();
    let mut out = vec![json!({
        "node": me.node.raw(),
        "priority": me.priority,
        "role": fm.role().to_string(),
        "self": true,
    })];
    let timeout = fm.config().master_timeout;
    for p in fm.peers() {
        let age = p.last.map(|t| now.saturating_since(t));
        let role = match age {
            None => "unheard",
            Some(a) if a > timeout => "lost",
            _ if fm.active_master() == Some(p.rank) => "active",
            _ => "standby",
        };
        out.push(json!({
            "node": p.rank.node.raw(),
            "priority": p.rank.priority,
            "role": role,
            "self": false,
            "heard_ms_ago": age.map(|a| a.as_micros() / 1000),
        }));
    }
    out
}

/// What is known of `w` now.
pub(super) async fn view(w: &Watched) -> View {
    let role = w.net.role().await.ok();
    let ports = w.net.ports().await.unwrap_or_default();
    let (pairs, link, lag_us, masters) = w
        .net
        .with(|n, now| {
            let pairs = n
                .pairs()
                .map(|(_, p)| {
                    let (a, b) = (p.spec.node(Member::A).raw(), p.spec.node(Member::B).raw());
                    (format!("{a:#04x}/{b:#04x}"), p.active)
                })
                .collect();
            let link = &n.station().link;
            let lag = [0, 1].map(|p| link.lag().lag(p).as_micros());
            (
                pairs,
                Some(link.mode().to_string()),
                lag,
                masters(n.supervisor().flying_master(), now),
            )
        })
        .await
        .unwrap_or_default();
    View {
        role,
        ports,
        pairs,
        link,
        lag_us,
        masters,
    }
}

fn member(m: Option<Member>) -> &'static str {
    match m {
        Some(Member::A) => "A",
        Some(Member::B) => "B",
        None => "none",
    }
}

async fn page(State(s): State<Arc<Shared>>, headers: HeaderMap) -> Response {
    dashboard::page(s.access.may_read(&headers))
}

/// The role of the request's token: `{"role": "read"}` or `{"role": "control"}` (the
/// dashboard offers operator actions to the latter).
async fn role(State(s): State<Arc<Shared>>, headers: HeaderMap) -> Response {
    if !s.access.may_read(&headers) {
        return unauthorized();
    }
    let role = if s.access.may_control(&headers) {
        "control"
    } else {
        "read"
    };
    axum::Json(json!({ "role": role })).into_response()
}

async fn networks_json(State(s): State<Arc<Shared>>, headers: HeaderMap) -> Response {
    if !s.access.may_read(&headers) {
        return unauthorized();
    }
    let _turn = s.turns.acquire().await;
    let mut out = Vec::new();
    for w in &s.networks {
        let v = view(w).await;
        out.push(json!({
            "name": w.name,
            "buses": w.buses,
            // A closed network (a simulated plant's end) answers nothing.
            "open": v.role.is_some(),
            "role": v.role.map(|r| r.to_string()),
            "masters": v.masters,
            "link": v.link,
            "ports": v.ports.iter().map(|p| json!({
                "name": p.name,
                "state": p.state,
                "rx_frames": p.counters.rx_frames,
                "tx_frames": p.counters.tx_frames,
                "rx_error_frames": p.counters.rx_error_frames,
                "tx_dropped": p.counters.tx_dropped,
                "reopened": p.counters.reopened,
            })).collect::<Vec<_>>(),
            "pairs": v.pairs.iter().map(|(p, m)| json!({ "pair": p, "active": member(*m) })).collect::<Vec<_>>(),
            "nodes": dashboard::nodes(&w.net, &w.recent).await,
            "events": w.events.load(Ordering::Relaxed),
            "failovers": w.failovers.load(Ordering::Relaxed),
            "recent": w.recent.json(),
        }));
    }
    axum::Json(out).into_response()
}

/// One of a network's event lines to a stream's queue `tx`: first `missed N events` if the
/// queue had no room for the last `missed` and has some now, then the line, or the line
/// counted in `missed` if there is no room. False once the stream is gone.
fn forward(
    tx: &tokio::sync::mpsc::Sender<(String, String)>,
    name: &str,
    line: String,
    missed: &mut u64,
) -> bool {
    use tokio::sync::mpsc::error::TrySendError;
    if *missed > 0
        && tx
            .try_send((name.to_string(), format!("missed {missed} events")))
            .is_ok()
    {
        *missed = 0;
    }
    match tx.try_send((name.to_string(), line)) {
        Ok(()) => true,
        Err(TrySendError::Full(_)) => {
            *missed += 1;
            true
        }
        Err(TrySendError::Closed(_)) => false,
    }
}

async fn events(State(s): State<Arc<Shared>>, headers: HeaderMap) -> Response {
    use axum::response::sse::{Event, KeepAlive, Sse};
    use duocan::net::NetEvent;
    if !s.access.may_read(&headers) {
        return unauthorized();
    }
    let Ok(permit) = s.streams.clone().try_acquire_owned() else {
        return error(
            StatusCode::SERVICE_UNAVAILABLE,
            "too many event streams open: try again later",
        );
    };
    // One bounded queue per client: each network's stream feeds it; a full queue drops the
    // client's oldest-to-come events and counts them, never holding a network up.
    let (tx, rx) = tokio::sync::mpsc::channel::<(String, String)>(STREAM_QUEUE);
    let mut feeds = tokio::task::JoinSet::new();
    for w in &s.networks {
        let mut ev = w.net.events();
        let (tx, name) = (tx.clone(), w.name.clone());
        feeds.spawn(async move {
            let mut missed = 0u64;
            while let Some(e) = ev.next().await {
                let line = match e {
                    NetEvent::Lagged(n) => format!("missed {n} events"),
                    e => e.to_string(),
                };
                if !forward(&tx, &name, line, &mut missed) {
                    return;
                }
            }
        });
    }
    drop(tx);
    // The stream owns the feeds and the permit: both go when the client does.
    let stream =
        futures_util::stream::unfold((rx, feeds, permit), |(mut rx, feeds, permit)| async move {
            let (name, line) = rx.recv().await?;
            let event = Event::default().event(name).data(line);
            Some((
                Ok::<_, std::convert::Infallible>(event),
                (rx, feeds, permit),
            ))
        });
    Sse::new(stream)
        .keep_alive(KeepAlive::default())
        .into_response()
}

#[cfg(test)]
mod tests {
    use super::forward;

    #[test]
    fn a_stream_that_falls_behind_is_told_how_many_events_it_missed() {
        let (tx, mut rx) = tokio::sync::mpsc::channel(2);
        let mut missed = 0;
        for i in 0..5 {
            assert!(forward(&tx, "east", format!("e{i}"), &mut missed));
        }
        assert_eq!(missed, 3);
        let mut got = vec![rx.try_recv().unwrap().1, rx.try_recv().unwrap().1];
        // Room again: the count first, then the next event; the count starts over.
        assert!(forward(&tx, "east", "e5".into(), &mut missed));
        got.extend([rx.try_recv().unwrap().1, rx.try_recv().unwrap().1]);
        assert_eq!(got, ["e0", "e1", "missed 3 events", "e5"]);
        assert_eq!(missed, 0);
        drop(rx);
        assert!(!forward(&tx, "east", "e6".into(), &mut missed));
    }
}
