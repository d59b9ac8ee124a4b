//! LSS (CiA 305) on a network of the station: `POST /api/networks/NET/lss` (control role:
//! LSS requests change what the devices do), one command a request.
//!
//! | body | does | answer |
//! |---|---|---|
//! | `{"command":"identify-non-configured"}` | asks whether any device without a node-ID is there (waits the LSS timeout) | `{"network","non_configured":true}` |
//! | `{"command":"configure","address":{"vendor":…,"product":…,"revision":…,"serial":…},"node":16,"store":true}` | selects the device of that address, gives it the node-ID, stores it if `store`, and switches every device back to waiting | `{"network","node","stored"}` |
//! | `{"command":"fastscan","assign":[32,47],"store":true}` | finds every device without a node-ID (CiA 305 fastscan) and gives each the lowest free node-ID of `assign` (first and last, inclusive), stored if `store` | `{"network","assigned":[{"vendor","product","revision","serial","node"}],"stopped","requests","answers","restarts","took_ms"}` |
//!
//! A fastscan that stopped on the way (a device found that got no node-ID: the range used up)
//! is 200 too, with why in `stopped` (`null`: every device without a node-ID was found); the
//! devices in `assigned` keep their node-IDs.
//!
//! No device answering the selection is 504 (nothing was configured); the errors otherwise as
//! the other routes' ([`rest`](super)).

use super::{bad, body, net_error, network, node_id, outcome, record, Reply};
use crate::cmd::station::http::Shared;
use axum::body::Bytes;
use axum::extract::rejection::BytesRejection;
use axum::extract::{ConnectInfo, Path, State};
use axum::http::HeaderMap;
use axum::response::IntoResponse;
use duocan::cia305::{LssAddress, LssMode, LssPlan};
use duocan::net::{NetError, LSS_PLAN};
use duocan::NodeId;
use serde::Deserialize;
use serde_json::{json, Value};
use std::net::SocketAddr;
use std::sync::Arc;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Lss {
    command: String,
    address: Option<Address>,
    node: Option<Value>,
    assign: Option<[Value; 2]>,
    #[serde(default)]
    store: bool,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Address {
    vendor: u32,
    product: u32,
    revision: u32,
    serial: u32,
}

/// What a command does, checked before anything is sent.
enum Command {
    Identify,
    Configure(LssAddress, u8, bool),
    Fastscan(u8, u8, bool),
}

/// A node-ID given as a number or a text (`16`, `"0x10"`), for `what`.
fn node_value(v: &Value, what: &str) -> Result<u8, axum::response::Response> {
    let n = match v {
        Value::Number(n) => node_id(&n.to_string(), false),
        Value::String(t) => node_id(t, false),
        _ => return Err(bad(format!("{what}: a node-ID (1 to 127)"))),
    };
    n.map_err(|_| bad(format!("{what}: {v} is not a node-ID (1 to 127)")))
}

pub(super) async fn lss(
    State(s): State<Arc<Shared>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    Path(net): Path<String>,
    b: Result<Bytes, BytesRejection>,
) -> Reply {
    let who = s.access.control(&headers)?;
    let req: Lss = body(b)?;
    let cmd = match req.command.as_str() {
        "identify-non-configured" => Command::Identify,
        "configure" => {
            let a = req
                .address
                .ok_or_else(|| bad("address: configure needs the device's address"))?;
            let node = match &req.node {
                Some(Value::Number(n)) => node_id(&n.to_string(), false)?,
                Some(Value::String(t)) => node_id(t, false)?,
                _ => return Err(bad("node: configure needs the node-ID to give (1 to 127)")),
            };
            let address = LssAddress {
                vendor: a.vendor,
                product: a.product,
                revision: a.revision,
                serial: a.serial,
            };
            Command::Configure(address, node, req.store)
        }
        "fastscan" => {
            let [first, last] = req.assign.as_ref().ok_or_else(|| {
                bad("assign: fastscan needs the node-IDs to give, [first, last]")
            })?;
            let (first, last) = (node_value(first, "assign")?, node_value(last, "assign")?);
            if first > last {
                return Err(bad(format!(
                    "assign: [{first}, {last}] is empty: the first node-ID comes first"
                )));
            }
            Command::Fastscan(first, last, req.store)
        }
        other => {
            return Err(bad(format!(
                "command: {other:?} is not an LSS command: identify-non-configured, configure or fastscan"
            )))
        }
    };
    let w = network(&s, &net)?;
    let _turn = s.turns.acquire().await;
    let lss = w.net.lss();
    match cmd {
        Command::Identify => {
            let r = lss.identify_non_configured().await;
            record(
                w,
                who,
                peer,
                &format!("lss identify-non-configured: {}", outcome(&r)),
            );
            let found = r.map_err(|e| net_error(&e))?;
            Ok(axum::Json(json!({ "network": w.name, "non_configured": found })).into_response())
        }
        Command::Configure(address, node, store) => {
            let r: Result<(), NetError> = async {
                lss.switch_selective(address).await?;
                let r = async {
                    lss.configure_node_id(node).await?;
                    if store {
                        lss.store().await?;
                    }
                    Ok(())
                }
                .await;
                // Back to waiting whatever happened: the device may be selected again.
                let back = lss.switch_global(LssMode::Waiting).await;
                r.and(back)
            }
            .await;
            let what = format!(
                "lss configure {:#010x}:{:#010x}:{:#010x}:{:#010x} node {node:#04x}{}: {}",
                address.vendor,
                address.product,
                address.revision,
                address.serial,
                if store { " stored" } else { "" },
                outcome(&r)
            );
            record(w, who, peer, &what);
            r.map_err(|e| net_error(&e))?;
            Ok(
                axum::Json(json!({ "network": w.name, "node": node, "stored": store }))
                    .into_response(),
            )
        }
        Command::Fastscan(first, last, store) => {
            let free = (first..=last).filter_map(NodeId::new);
            let plan = LssPlan::<LSS_PLAN>::new().with_free(free).with_store(store);
            let r = lss.fastscan(plan).await;
            let what = match &r {
                Ok(rep) => format!(
                    "lss fastscan {first:#04x}-{last:#04x}{}: {} assigned{}",
                    if store { " stored" } else { "" },
                    rep.assigned.len(),
                    rep.stopped
                        .as_ref()
                        .map(|e| format!(", stopped: {e}"))
                        .unwrap_or_default()
                ),
                Err(_) => format!("lss fastscan {first:#04x}-{last:#04x}: {}", outcome(&r)),
            };
            record(w, who, peer, &what);
            let rep = r.map_err(|e| net_error(&e))?;
            let assigned: Vec<Value> = rep
                .assigned
                .iter()
                .map(|(a, n)| {
                    json!({"vendor": a.vendor, "product": a.product, "revision": a.revision,
                        "serial": a.serial, "node": n.raw()})
                })
                .collect();
            Ok(axum::Json(json!({
                "network": w.name,
                "assigned": assigned,
                "stopped": rep.stopped.map(|e| e.to_string()),
                "requests": rep.requests,
                "answers": rep.answers,
                "restarts": rep.restarts,
                "took_ms": rep.took.as_millis(),
            }))
            .into_response())
        }
    }
}
