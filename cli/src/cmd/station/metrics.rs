//! `GET /metrics`: the station in the Prometheus text format (0.0.4) — each port's frames,
//! errors, drops, re-opens, state and lag, each network's master and pairs, events and
//! failovers, the HTTP side's connections and refusals, the 309-3 gateway's clients and the
//! MQTT publisher's counts. [`http`](super::http) lists them.

use super::access::unauthorized;
use super::http::{view, Shared};
use crate::cmd::gateway::GatewayStats;
use axum::extract::State;
use axum::http::{header, HeaderMap};
use axum::response::{IntoResponse, Response};
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::Member;
use std::fmt::Write as _;
use std::sync::atomic::Ordering;
use std::sync::Arc;

/// One of a port's counters.
type Counter = fn(&duocan::port::PortCountersSnapshot) -> u64;

/// A label value, escaped as the text format asks.
fn label(s: &str) -> String {
    s.replace('\\', "\\\\")
        .replace('"', "\\\"")
        .replace('\n', "\\n")
}

/// The metrics, to the read role.
pub(super) async fn metrics(State(s): State<Arc<Shared>>, headers: HeaderMap) -> Response {
    if !s.access.may_read(&headers) {
        return unauthorized();
    }
    let _turn = s.turns.acquire().await;
    let mut views = Vec::new();
    for w in &s.networks {
        views.push((w, view(w).await));
    }
    let mut out = String::new();
    let port_metrics: [(&str, &str, Counter); 5] = [
        (
            "duocan_port_rx_frames_total",
            "Frames received on the port",
            |c| c.rx_frames,
        ),
        (
            "duocan_port_tx_frames_total",
            "Frames sent on the port",
            |c| c.tx_frames,
        ),
        (
            "duocan_port_rx_error_frames_total",
            "Error frames seen on the port",
            |c| c.rx_error_frames,
        ),
        (
            "duocan_port_tx_dropped_total",
            "Frames dropped for want of room in the port's queue",
            |c| c.tx_dropped,
        ),
        (
            "duocan_port_reopened_total",
            "Times the port was re-opened after a failure",
            |c| c.reopened,
        ),
    ];
    for (name, help, value) in port_metrics {
        let _ = writeln!(out, "# HELP {name} {help}.\n# TYPE {name} counter");
        for (w, v) in &views {
            for p in &v.ports {
                let _ = writeln!(
                    out,
                    "{name}{{network=\"{}\",bus=\"{}\",port=\"{}\"}} {}",
                    label(&w.name),
                    p.index + 1,
                    label(&p.name),
                    value(&p.counters)
                );
            }
        }
    }
    let _ = writeln!(
        out,
        "# HELP duocan_port_up Whether the port works (state ok).\n# TYPE duocan_port_up gauge"
    );
    for (w, v) in &views {
        for p in &v.ports {
            let up = u8::from(p.state == "ok");
            let _ = writeln!(
                out,
                "duocan_port_up{{network=\"{}\",bus=\"{}\",port=\"{}\"}} {up}",
                label(&w.name),
                p.index + 1,
                label(&p.name)
            );
        }
    }
    let _ = writeln!(
        out,
        "# HELP duocan_port_lag_seconds How much later the port's copies come than the other \
         port's (the dual-bus layer's lag meter; 0 for the earlier port).\n\
         # TYPE duocan_port_lag_seconds gauge"
    );
    for (w, v) in &views {
        for p in &v.ports {
            let lag = v.lag_us.get(p.index).copied().unwrap_or(0);
            let _ = writeln!(
                out,
                "duocan_port_lag_seconds{{network=\"{}\",bus=\"{}\",port=\"{}\"}} {}.{:06}",
                label(&w.name),
                p.index + 1,
                label(&p.name),
                lag / 1_000_000,
                lag % 1_000_000
            );
        }
    }
    let _ = writeln!(out, "# HELP duocan_master_active Whether this station's master is the network's active one.\n# TYPE duocan_master_active gauge");
    for (w, v) in &views {
        let active = u8::from(v.role == Some(MasterRole::Active));
        let _ = writeln!(
            out,
            "duocan_master_active{{network=\"{}\"}} {active}",
            label(&w.name)
        );
    }
    let _ = writeln!(out, "# HELP duocan_pair_active_member The pair's running board: 0 none, 1 A, 2 B.\n# TYPE duocan_pair_active_member gauge");
    for (w, v) in &views {
        for (pair, m) in &v.pairs {
            let n = match m {
                None => 0,
                Some(Member::A) => 1,
                Some(Member::B) => 2,
            };
            let _ = writeln!(
                out,
                "duocan_pair_active_member{{network=\"{}\",pair=\"{pair}\"}} {n}",
                label(&w.name)
            );
        }
    }
    for (name, help, failovers) in [
        ("duocan_events_total", "Events the network reported", false),
        (
            "duocan_failovers_total",
            "Failovers (bus, master, pair) the network reported",
            true,
        ),
    ] {
        let _ = writeln!(out, "# HELP {name} {help}.\n# TYPE {name} counter");
        for (w, _) in &views {
            let n = if failovers { &w.failovers } else { &w.events };
            let _ = writeln!(
                out,
                "{name}{{network=\"{}\"}} {}",
                label(&w.name),
                n.load(Ordering::Relaxed)
            );
        }
    }
    http_metrics(&mut out, &s);
    if let Some(gw) = &s.gateway {
        gateway_metrics(&mut out, gw);
    }
    super::mqtt::metrics(&mut out);
    (
        [(
            header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        out,
    )
        .into_response()
}

/// The HTTP side's own lines of `/metrics`: its connections and what it refused.
fn http_metrics(out: &mut String, s: &Shared) {
    let (read, control) = s.access.refused();
    let _ = writeln!(
        out,
        "# HELP duocan_http_refused_total HTTP requests and connections refused: too many \
         connections open (503), over the read or the control rate (429).\n\
         # TYPE duocan_http_refused_total counter\n\
         duocan_http_refused_total{{reason=\"too_many_connections\"}} {}\n\
         duocan_http_refused_total{{reason=\"read_rate\"}} {read}\n\
         duocan_http_refused_total{{reason=\"control_rate\"}} {control}",
        s.conns.refused()
    );
    let _ = writeln!(
        out,
        "# HELP duocan_http_connections HTTP connections open now.\n\
         # TYPE duocan_http_connections gauge\nduocan_http_connections {}",
        s.conns.open()
    );
    let _ = writeln!(
        out,
        "# HELP duocan_http_max_connections The most HTTP connections open at once \
         (http_max_connections).\n\
         # TYPE duocan_http_max_connections gauge\nduocan_http_max_connections {}",
        s.conns.max()
    );
}

/// The 309-3 gateway's lines of `/metrics`.
fn gateway_metrics(out: &mut String, gw: &GatewayStats) {
    let _ = writeln!(
        out,
        "# HELP duocan_gateway_refused_total CiA 309-3 gateway clients refused (told \
         ERROR:102 and closed): too many at once (gateway_max_clients).\n\
         # TYPE duocan_gateway_refused_total counter\n\
         duocan_gateway_refused_total{{reason=\"too_many_clients\"}} {}",
        gw.refused()
    );
    let _ = writeln!(
        out,
        "# HELP duocan_gateway_clients CiA 309-3 gateway clients served now (TCP and socket).\n\
         # TYPE duocan_gateway_clients gauge\nduocan_gateway_clients {}",
        gw.clients()
    );
    let _ = writeln!(
        out,
        "# HELP duocan_gateway_max_clients The most CiA 309-3 gateway clients served at once.\n\
         # TYPE duocan_gateway_max_clients gauge\nduocan_gateway_max_clients {}",
        gw.max_clients()
    );
}
