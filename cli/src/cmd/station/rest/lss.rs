//! LSS (CiA 305) on a network of the station: `POST /api/networks/NET/lss` (control role:
//! LSS requests change what the devices do), one command a request.
//!
//! | body | does | answer |
//! |---|---|---|
//! | `{"command":"identify-non-configured"}` | asks whether any device without a node-ID is there (waits the LSS timeout) | `{"network","non_configured":true}` |
//! | `{"command":"configure","address":{"vendor":…,"product":…,"revision":…,"serial":…},"node":16,"store":true}` | selects the device of that address, gives it the node-ID, stores it if `store`, and switches every device back to waiting | `{"network","node","stored"}` |
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
use duocan::cia305::{LssAddress, LssMode};
use duocan::net::NetError;
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
        other => {
            return Err(bad(format!(
                "command: {other:?} is not an LSS command: identify-non-configured or configure"
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
    }
}
