//! One network's topics: its events as they come, its state and its pairs' running boards
//! after them.

use super::Publisher;
use crate::cmd::station::http::Watched;
use duocan::net::NetEvent;
use duocan_redundancy::Member;
use serde_json::json;
use std::sync::Arc;

fn member(m: Option<Member>) -> &'static str {
    match m {
        Some(Member::A) => "A",
        Some(Member::B) => "B",
        None => "none",
    }
}

fn wall_ms() -> u128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default()
        .as_millis()
}

/// Publishes one network's events as they come and its state after them.
pub(super) async fn watch(w: Arc<Watched>, p: Publisher) {
    let base = format!(
        "{}/{}",
        p.prefix,
        crate::cmd::station::audit::file_name(&w.name)
    );
    let mut events = w.net.events();
    let mut every = tokio::time::interval(super::STATE_EVERY);
    every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut changed = true;
    loop {
        tokio::select! {
            e = events.next() => {
                let Some(e) = e else { break };
                let body = match &e {
                    NetEvent::Lagged(n) => json!({ "wall_ms": wall_ms(), "missed": n }),
                    e => json!({
                        "wall_ms": wall_ms(),
                        "failover": e.is_failover(),
                        "event": e.to_string(),
                    }),
                };
                p.event(format!("{base}/events"), body.to_string().into_bytes());
                changed = true;
            }
            _ = every.tick(), if changed => {
                changed = false;
                publish_state(&w, &p, &base).await;
            }
        }
    }
    let closed = json!({ "network": w.name, "buses": w.buses, "open": false });
    p.retain(format!("{base}/state"), closed.to_string().into_bytes());
}

/// Reads the network's state (from its own task, as the HTTP status does) and sets the
/// retained topics.
async fn publish_state(w: &Watched, p: &Publisher, base: &str) {
    let role = w.net.role().await.ok();
    let ports = w.net.ports().await.unwrap_or_default();
    let Ok(pairs) = w
        .net
        .with(|n, _| {
            n.pairs()
                .map(|(_, pr)| {
                    let (a, b) = (pr.spec.node(Member::A).raw(), pr.spec.node(Member::B).raw());
                    (a, b, pr.active)
                })
                .collect::<Vec<_>>()
        })
        .await
    else {
        return;
    };
    let ports: Vec<_> = ports
        .iter()
        .map(|x| json!({ "bus": x.index + 1, "name": x.name, "state": x.state }))
        .collect();
    let boards: Vec<_> = pairs
        .iter()
        .map(|(a, b, m)| json!({ "pair": format!("{a:#04x}/{b:#04x}"), "active": member(*m) }))
        .collect();
    let state = json!({
        "network": w.name,
        "buses": w.buses,
        "open": true,
        "role": role.map(|r| r.to_string()),
        "ports": ports,
        "pairs": boards,
    });
    for (a, _, m) in &pairs {
        p.retain(
            format!("{base}/pair/{a:#04x}"),
            member(*m).as_bytes().to_vec(),
        );
    }
    p.retain(format!("{base}/state"), state.to_string().into_bytes());
}
