//! The station's web dashboard: `GET /`, one page (HTML with its CSS and script inline, built
//! into the binary: no file to install, nothing fetched from elsewhere).
//!
//! Per network it shows bus 1 and bus 2 (state, frames, error frames), this master's role,
//! each A/B pair with the board that runs in it, the node table (NMT state, missing, heard on
//! which bus, boot error status, last emergency unless reset since), the network's recent
//! events as a timeline (an SVG strip of the last minute, failovers in red, and their list
//! with times), and the live events of every network as they come. Every text from the
//! station is escaped before it is shown. It reads `GET /api/networks` every 500 ms (an answer late by 5 s is
//! reported at the top) and the event stream `GET /api/events` (opened again a second after it
//! ends, or after 40 s without even a keep-alive); a network whose plant has closed keeps its
//! last state, marked closed.
//!
//! Every element a test or a script may look for carries a stable attribute:
//! `data-network="NAME"` (with `data-role`, `data-open`), `data-bus="1"` (with `data-state`),
//! `data-pair="0x11"` (the A member's node-ID, with `data-running="A"`, `"B"` or `"none"`),
//! `data-node="0x11"` (with `data-state`, `data-heard="12"`: the buses it was heard on),
//! `data-event` items in `#events` (live) and in each network's timeline (`data-failover`);
//! with control, `button[data-action="switch"]` in a pair's row and
//! `button[data-action="nmt"][data-command="stop"]` (and the others) in a node's row.
//!
//! **Security.** The page is a route like the others: with a token configured, a request
//! without it gets 401. The 401 answer to `/` is a small page that reads the token from the
//! address's fragment (`http://HOST:PORT/#token=TOKEN`: a fragment never leaves the browser)
//! and asks for the dashboard again with `Authorization: Bearer TOKEN`, which the dashboard
//! then sends with each of its own requests; it shows nothing of the station. It offers
//! operator actions (per node NMT start, stop, preop and reset; per pair a switch-over) only
//! when `GET /api/role` says its token may control (the control token in the fragment, or
//! `http_control = "loopback"`), and sends none before the operator confirms it in a bar on
//! the page (`#confirm`, buttons `data-confirm="yes"`/`"no"`); the answer, or the station's
//! error, shows at the top (`#result`). Both answers forbid framing and other origins
//! (Content-Security-Policy) and are not cached.

use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use duocan::net::NetEvent;
use duocan_redundancy::net::RedundantNetwork;
use duocan_redundancy::{Member, SupervisedLink};
use serde_json::{json, Value};
use std::collections::{BTreeMap, VecDeque};
use std::sync::Mutex;

/// The page.
const PAGE: &str = include_str!("dashboard.html");

/// The 401 answer to `/` when a token is needed: fetches the page with the token of the
/// address's fragment and shows it.
const LOADER: &str = r#"<!doctype html><meta charset="utf-8"><title>duocan station</title>
<p id="why">This station needs a token: open it as <code>/#token=TOKEN</code>.</p>
<script>
{ // A block: the page written over this one shares its global scope (document.open keeps it).
  const t = new URLSearchParams(location.hash.slice(1)).get("token");
  if (t) fetch("/", { headers: { Authorization: "Bearer " + t }, cache: "no-store" })
    .then(r => r.ok ? r.text() : Promise.reject(r.status))
    .then(html => { document.open(); document.write(html); document.close(); })
    .catch(() => { document.getElementById("why").textContent = "The token was refused."; });
}
</script>"#;

/// Inline script and style only; data from this station only; never inside a frame.
const CSP: &str = "default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; \
                   connect-src 'self'; img-src 'self' data:; frame-ancestors 'none'";

/// The dashboard, or with `allowed` false the 401 loader.
pub fn page(allowed: bool) -> Response {
    let (code, body) = if allowed {
        (StatusCode::OK, PAGE)
    } else {
        (StatusCode::UNAUTHORIZED, LOADER)
    };
    (
        code,
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CONTENT_SECURITY_POLICY, CSP),
            (header::CACHE_CONTROL, "no-store"),
            (header::REFERRER_POLICY, "no-referrer"),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
        ],
        body,
    )
        .into_response()
}

/// Events kept per network for the timeline.
pub const RECENT: usize = 64;

/// What a network's event stream told that its status does not keep: its last [`RECENT`]
/// events with their wall-clock times (for a page opened after them), and each node's last
/// emergency.
#[derive(Default)]
pub struct Recent(Mutex<Seen>);

#[derive(Default)]
struct Seen {
    events: VecDeque<(u64, String, bool)>,
    /// Node-ID to its last EMCY, as text; an error reset (code 0) removes it.
    emcy: BTreeMap<u8, String>,
}

impl Recent {
    /// Keeps `e`, dropping the oldest event beyond [`RECENT`]: the oldest that is no failover
    /// while failovers fill less than half of them, so that a failover (what the timeline is
    /// for) outlives the chatter that follows it (a rack of ten pairs reports some sixty events
    /// around one bus cut).
    pub fn push(&self, e: &NetEvent) {
        let at = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX));
        let mut s = self.0.lock().unwrap_or_else(|e| e.into_inner());
        if s.events.len() == RECENT {
            let failovers = s.events.iter().filter(|e| e.2).count();
            let chatter = (failovers < RECENT / 2)
                .then(|| s.events.iter().position(|e| !e.2))
                .flatten();
            match chatter {
                Some(i) => {
                    s.events.remove(i);
                }
                None => {
                    s.events.pop_front();
                }
            }
        }
        s.events.push_back((at, e.to_string(), e.is_failover()));
        if let Some((node, msg)) = e.emcy() {
            if msg.code == 0 {
                s.emcy.remove(&node.raw());
            } else {
                s.emcy
                    .insert(node.raw(), format!("{:#06x} {}", msg.code, msg.text()));
            }
        }
    }

    /// The events, oldest first: `{"at_ms", "line", "failover"}` each.
    pub fn json(&self) -> Vec<Value> {
        let s = self.0.lock().unwrap_or_else(|e| e.into_inner());
        s.events
            .iter()
            .map(|(at, line, f)| json!({ "at_ms": at, "line": line, "failover": f }))
            .collect()
    }

    /// Node `id`'s last emergency, unless reset since.
    fn emcy(&self, id: u8) -> Option<String> {
        let s = self.0.lock().unwrap_or_else(|e| e.into_inner());
        s.emcy.get(&id).cloned()
    }
}

/// The node table: every slave of the master, pair members included, with its NMT state,
/// whether it is missing, the buses it was heard on lately, its boot error status, its last
/// emergency (from `recent`).
pub async fn nodes(net: &RedundantNetwork, recent: &Recent) -> Vec<Value> {
    let mut table: Vec<Value> = net
        .with(|n, _| {
            let bus = n.station().link.dual_bus();
            n.slaves()
                .map(|v| {
                    let heard = bus.reach().heard(v.node);
                    let pair = n.pairs().find_map(|(_, p)| {
                        [Member::A, Member::B]
                            .into_iter()
                            .find(|&m| p.spec.node(m) == v.node)
                            .map(|m| (p.spec.node(Member::A).raw(), m, p.active == Some(m)))
                    });
                    json!({
                        "node": format!("{:#04x}", v.node.raw()),
                        "state": v.state.map_or("unknown".to_string(), |s| s.to_string()),
                        "missing": v.missing,
                        "heard": heard.map(|h| h.to_vec()),
                        "error": v.last_error.map(|e| e.to_string()),
                        "pair": pair.map(|(a, m, running)| json!({
                            "a": format!("{a:#04x}"),
                            "member": if m == Member::A { "A" } else { "B" },
                            "running": running,
                        })),
                    })
                })
                .collect()
        })
        .await
        .unwrap_or_default();
    for row in &mut table {
        let id = row["node"]
            .as_str()
            .and_then(|x| u8::from_str_radix(x.trim_start_matches("0x"), 16).ok());
        row["emcy"] = json!(id.and_then(|id| recent.emcy(id)));
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;

    fn emcy(id: u8, code: u16) -> NetEvent {
        NetEvent::Emcy {
            node: duocan::NodeId::new(id).unwrap(),
            msg: duocan::cia301::emcy::EmcyMessage {
                code,
                register: 1,
                data: [0; 5],
            },
            at: duocan::Instant::ZERO,
        }
    }

    #[test]
    fn the_recent_events_are_bounded_and_keep_the_newest() {
        let r = Recent::default();
        for i in 0..RECENT + 6 {
            r.push(&emcy(5, 0x1000 + i as u16));
        }
        let j = r.json();
        assert_eq!(j.len(), RECENT);
        assert_eq!(j[0]["line"], "node 0x05: EMCY 0x1006 generic error");
        assert_eq!(j[0]["failover"], false);
        assert!(j[0]["at_ms"].as_u64() > Some(0));
        let last = 0x1000 + RECENT as u16 + 5;
        assert_eq!(r.emcy(5), Some(format!("{last:#06x} generic error")));
        // An error reset clears the node's emergency.
        r.push(&emcy(5, 0));
        assert_eq!(r.emcy(5), None);
    }

    #[test]
    fn a_failover_outlives_the_chatter_after_it_up_to_half_the_events() {
        let r = Recent::default();
        let cut = NetEvent::PortState {
            port: 0,
            from: duocan::machine::PortState::Ok,
            to: duocan::machine::PortState::Failed,
            reason: duocan::machine::PortReason::Down(duocan::machine::ErrorCause::InterfaceDown),
            at: duocan::Instant::ZERO,
        };
        assert!(cut.is_failover());
        r.push(&cut);
        for i in 0..3 * RECENT {
            r.push(&emcy(5, 0x1000 + i as u16));
        }
        let j = r.json();
        assert_eq!(j.len(), RECENT);
        assert_eq!(j[0]["failover"], true, "{j:?}");
        assert_eq!(j.iter().filter(|e| e["failover"] == true).count(), 1);
        // Failovers fill at most half: beyond, the oldest goes, failover or not.
        for _ in 0..RECENT {
            r.push(&cut);
        }
        let j = r.json();
        assert_eq!(j.len(), RECENT);
        assert!(j.iter().all(|e| e["failover"] == true), "{j:?}");
    }

    #[test]
    fn without_the_token_the_page_is_a_401_that_shows_nothing_of_the_station() {
        assert_eq!(page(false).status(), StatusCode::UNAUTHORIZED);
        assert_eq!(page(true).status(), StatusCode::OK);
        assert!(!LOADER.contains("/api/"));
        // Self-contained: nothing is loaded from elsewhere.
        assert!(!PAGE.contains("http://") && !PAGE.contains("https://"));
        assert!(!PAGE.contains(" src="));
    }
}
