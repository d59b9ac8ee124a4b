//! The station's REST access, in the spirit of CiA 309-5: SDO reads and writes with the 309
//! data-type names, NMT, forced switch-overs and LSS, on any network of the station, JSON in and
//! out. A network is named by its name (URL-encoded: `signal%20rack`) or its index in the file
//! (from 0); a node by its node-ID (`16` or `0x10`).
//!
//! | request | role | body | answer |
//! |---|---|---|---|
//! | `GET /api/networks/NET/nodes/ID/sdo/INDEX/SUB?type=u32` | read | | `{"network","node","index","sub","type","value"}` |
//! | `PUT /api/networks/NET/nodes/ID/sdo/INDEX/SUB` | control | `{"type":"u32","value":1234}` | the same |
//! | `GET /api/networks/NET/nodes/ID/sdo/NAME` | read | | the same, with `"name"` |
//! | `PUT /api/networks/NET/nodes/ID/sdo/NAME` | control | `{"value":1234}` | the same |
//! | `POST /api/networks/NET/nmt` | control | `{"command":"stop","node":16}` (`0`: all nodes) | `{"network","node","command"}` |
//! | `POST /api/networks/NET/pairs/ID/switch` | control | none, or `{"to":"A"}` / `{"to":"B"}` | `{"network","pair","active"}` |
//! | `POST /api/networks/NET/lss` | control | `{"command":"identify-non-configured"}`, or `configure` ([`lss`]) | `{"network",…}` |
//!
//! INDEX and SUB are numbers (`0x1018`, `4120`; `1`, `0x01`); the type is a CiA 309 name
//! ([`value`]; a read without `?type=` gets the bytes, `hex`); a value whose size is not its
//! type's is answered as its bytes (`"type":"hex"`). NMT commands: `start`, `stop`, `preop`,
//! `reset`, `reset-comm`.
//!
//! **Names and types from the board's description.** A board whose EDS or DCF the station
//! file names (`boards`, see [`config::boards`](super::config::boards)) is read and written by
//! the name of an entry as the description resolves it (`Producer%20heartbeat%20time`,
//! `Identity%20object.Vendor-ID`, `0x1017sub0`; without regard to case; an unknown or ambiguous
//! name is a 404 listing the candidates), and a request that names no type gets the entry's
//! data type (its CiA 309 name; `hex` where 309 has none), by name or by INDEX/SUB alike. A
//! node without a description takes INDEX/SUB, and a read without a type gets its bytes.
//!
//! A switch-over names the pair by either member's node-ID and goes to
//! `to`, or by default to the member that is not running.
//!
//! **Errors**, each a JSON `{"error": why}` naming what was wrong, and none changing anything:
//! 400 a malformed index, sub-index, node-ID, type, value or body; 401 no token, or not one of
//! the station's; 403 a read-only token on a control request, or control off; 404 no such
//! network, a node-ID outside 1–127, no such pair; 409 the node aborted the transfer (with
//! `abort_code` and `abort`, the code's CiA 301 text), or this station's master of the network
//! is the standby one (the active master commands); 413 a body over [`MAX_BODY`] bytes; 429
//! over the control rate ([`access`](super::access)); 502 the network failed otherwise; 503
//! the network is closed; 504 the node did not answer in time (abort `0x05040000`), or no
//! device answered an LSS request.
//!
//! **Accountability.** Every control request taken is logged through `tracing` (target
//! `duocan::station::control`: network, role, client address, what and the outcome) and, with
//! an audit trail, appended to the network's file as an `operator` line
//! ([`audit`]) before the answer goes out.

pub mod lss;
pub mod value;

use super::access::{error, unauthorized};
use super::audit;
use super::http::{Shared, Watched};
use crate::args::{parse_index, parse_int, parse_sub};
use crate::cmd::nmt::Action;
use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, QueryRejection};
use axum::extract::{ConnectInfo, DefaultBodyLimit, Path, Query, State};
use axum::http::{HeaderMap, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::Router;
use duocan::net::NetError;
use duocan_redundancy::Member;
use serde::Deserialize;
use serde_json::{json, Value};
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::Arc;

/// The largest request body taken.
pub const MAX_BODY: usize = 4096;

/// The REST routes, over the station's shared state.
pub(super) fn routes() -> Router<Arc<Shared>> {
    Router::new()
        .route(
            "/api/networks/{net}/nodes/{id}/sdo/{index}/{sub}",
            get(sdo_read).put(sdo_write),
        )
        .route(
            "/api/networks/{net}/nodes/{id}/sdo/{name}",
            get(sdo_read_named).put(sdo_write_named),
        )
        .route("/api/networks/{net}/nmt", post(nmt))
        .route("/api/networks/{net}/pairs/{id}/switch", post(switch))
        .route("/api/networks/{net}/lss", post(lss::lss))
        .layer(DefaultBodyLimit::max(MAX_BODY))
}

type Reply = Result<Response, Response>;

fn bad(why: impl std::fmt::Display) -> Response {
    error(StatusCode::BAD_REQUEST, &why.to_string())
}

/// The network named `net` (its name, else its index).
fn network<'a>(s: &'a Shared, net: &str) -> Result<&'a Arc<Watched>, Response> {
    s.networks
        .iter()
        .find(|w| w.name == net)
        .or_else(|| net.parse::<usize>().ok().and_then(|i| s.networks.get(i)))
        .ok_or_else(|| {
            let names: Vec<String> = s.networks.iter().map(|w| format!("{:?}", w.name)).collect();
            let why = format!(
                "no network {net:?}: the station has {} (or their index from 0)",
                names.join(", ")
            );
            error(StatusCode::NOT_FOUND, &why)
        })
}

/// A node-ID (1–127; 0 too where `all` allows it).
fn node_id(text: &str, all: bool) -> Result<u8, Response> {
    let v = parse_int(text.trim(), false).map_err(|why| bad(format!("node: {why}")))?;
    let lo = i128::from(!all);
    if (lo..=127).contains(&v) {
        Ok(v as u8)
    } else {
        let range = if all {
            "0 (all) or 1 to 127"
        } else {
            "1 to 127"
        };
        Err(error(
            StatusCode::NOT_FOUND,
            &format!("no node {v}: a node-ID is {range}"),
        ))
    }
}

/// The answer to a network's error.
fn net_error(e: &NetError) -> Response {
    let text = e.to_string();
    if let Some(code) = e.abort_code() {
        let status = if e.is_no_answer() {
            StatusCode::GATEWAY_TIMEOUT
        } else {
            StatusCode::CONFLICT
        };
        let body = json!({
            "error": text,
            "abort_code": format!("0x{:08X}", code.0),
            "abort": code.description().unwrap_or("not a CiA 301 abort code"),
        });
        return (status, axum::Json(body)).into_response();
    }
    let status = match e {
        NetError::Timeout { .. } | NetError::Lss(duocan::cia305::LssError::Timeout(_)) => {
            StatusCode::GATEWAY_TIMEOUT
        }
        NetError::Standby { .. } => StatusCode::CONFLICT,
        NetError::NoSuchNode(_) => StatusCode::NOT_FOUND,
        NetError::Closed => StatusCode::SERVICE_UNAVAILABLE,
        _ => StatusCode::BAD_GATEWAY,
    };
    error(status, &text)
}

/// The body as JSON of type `T`, or the answer that refuses it.
fn body<T: serde::de::DeserializeOwned>(b: Result<Bytes, BytesRejection>) -> Result<T, Response> {
    let b = b.map_err(|e| error(e.status(), &format!("body: {}", e.body_text())))?;
    serde_json::from_slice(&b).map_err(|e| bad(format!("body: {e}")))
}

/// Logs a control action taken and records it in the network's audit trail, if any.
fn record(w: &Watched, who: &str, peer: SocketAddr, what: &str) {
    tracing::info!(target: "duocan::station::control", network = %w.name, role = %who,
        client = %peer, "{what}");
    if let Some(a) = &w.audit {
        let line = format!(
            "{} run={} operator role={who} client={peer}: {what}",
            audit::wall(),
            a.run
        );
        let mut log = a
            .log
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if let Err(e) = log.append(&line) {
            tracing::error!(target: "duocan::station::audit", network = %w.name,
                "cannot write the operator record: {e}");
        }
    }
}

/// The outcome's words for the log.
fn outcome<T>(r: &Result<T, NetError>) -> String {
    match r {
        Ok(_) => "done".into(),
        Err(e) => format!("failed: {e}"),
    }
}

/// An SDO request's address: network, node, index, sub-index.
type SdoPath = Path<(String, String, String, String)>;

/// Checks an SDO request's address.
fn sdo_target<'a>(
    s: &'a Shared,
    (net, id, index, sub): &(String, String, String, String),
) -> Result<(&'a Arc<Watched>, u8, u16, u8), Response> {
    let index = parse_index(index).map_err(|why| bad(format!("index: {why}")))?;
    let sub = parse_sub(sub).map_err(|why| bad(format!("sub-index: {why}")))?;
    let id = node_id(id, false)?;
    Ok((network(s, net)?, id, index, sub))
}

fn sdo_json(w: &Watched, id: u8, index: u16, sub: u8, ty: &str, v: Value) -> Value {
    json!({
        "network": w.name, "node": id, "index": format!("0x{index:04X}"), "sub": sub,
        "type": ty, "value": v,
    })
}

async fn sdo_read(
    State(s): State<Arc<Shared>>,
    headers: HeaderMap,
    Path(p): SdoPath,
    q: Result<Query<HashMap<String, String>>, QueryRejection>,
) -> Reply {
    if !s.access.may_read(&headers) {
        return Err(unauthorized());
    }
    let Query(q) = q.map_err(|e| bad(format!("query: {}", e.body_text())))?;
    let (w, id, index, sub) = sdo_target(&s, &p)?;
    let described = described_type(w, id, index, sub);
    read(&s, w, id, (index, sub), q.get("type"), described, None).await
}

/// A read of an entry named by the node's description.
async fn sdo_read_named(
    State(s): State<Arc<Shared>>,
    headers: HeaderMap,
    Path((net, id, name)): Path<(String, String, String)>,
    q: Result<Query<HashMap<String, String>>, QueryRejection>,
) -> Reply {
    if !s.access.may_read(&headers) {
        return Err(unauthorized());
    }
    let Query(q) = q.map_err(|e| bad(format!("query: {}", e.body_text())))?;
    let id = node_id(&id, false)?;
    let w = network(&s, &net)?;
    let (index, sub, ty, entry) = named(w, id, &name)?;
    read(
        &s,
        w,
        id,
        (index, sub),
        q.get("type"),
        Some(ty),
        Some(entry),
    )
    .await
}

/// Reads (`index`, `sub`) of node `id` as the type asked for, else the described one, else
/// as bytes.
async fn read(
    s: &Shared,
    w: &Watched,
    id: u8,
    (index, sub): (u16, u8),
    asked: Option<&String>,
    described: Option<String>,
    entry: Option<String>,
) -> Reply {
    let name = asked
        .cloned()
        .or(described)
        .unwrap_or_else(|| "hex".into())
        .to_ascii_lowercase();
    let ty = value::data_type(&name).map_err(bad)?;
    let _turn = s.turns.acquire().await;
    let data = w
        .net
        .node(id)
        .sdo()
        .read_bytes(index, sub)
        .await
        .map_err(|e| net_error(&e))?;
    let (shown, v) = value::from_bytes(ty, &data);
    let mut answer = sdo_json(w, id, index, sub, shown.unwrap_or(&name), v);
    if let Some(e) = entry {
        answer["name"] = Value::String(e);
    }
    Ok(axum::Json(answer).into_response())
}

/// The CiA 309 name of the data type node `id`'s description gives (`index`, `sub`), if the
/// node has one and it describes the entry.
fn described_type(w: &Watched, id: u8, index: u16, sub: u8) -> Option<String> {
    let node = w.net.node(id);
    let e = node.description()?.entry_at(index, sub)?;
    Some(value::type_of(e.data_type).to_string())
}

/// The entry `name` of node `id`'s description: index, sub-index, its type's CiA 309 name
/// and the entry's own name.
fn named(w: &Watched, id: u8, name: &str) -> Result<(u16, u8, String, String), Response> {
    let node = w.net.node(id);
    let Some(desc) = node.description() else {
        let why = format!(
            "node {id:#04x} of network {:?} has no description: give INDEX/SUB \
             (…/sdo/0x1017/0), or name its EDS or DCF in the station file (boards)",
            w.name
        );
        return Err(error(StatusCode::NOT_FOUND, &why));
    };
    let e = desc
        .entry(name)
        .map_err(|e| error(StatusCode::NOT_FOUND, &format!("node {id:#04x}: {e}")))?;
    Ok((
        e.index,
        e.sub,
        value::type_of(e.data_type).to_string(),
        e.name.clone(),
    ))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SdoWrite {
    /// The CiA 309 type; may be left out for an entry the node's description gives.
    #[serde(rename = "type")]
    ty: Option<String>,
    value: Value,
}

async fn sdo_write(
    State(s): State<Arc<Shared>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    Path(p): SdoPath,
    b: Result<Bytes, BytesRejection>,
) -> Reply {
    let who = s.access.control(&headers)?;
    let req: SdoWrite = body(b)?;
    let (w, id, index, sub) = sdo_target(&s, &p)?;
    let described = described_type(w, id, index, sub);
    write(&s, who, peer, w, id, (index, sub), req, described, None).await
}

/// A write of an entry named by the node's description.
async fn sdo_write_named(
    State(s): State<Arc<Shared>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    Path((net, id, name)): Path<(String, String, String)>,
    b: Result<Bytes, BytesRejection>,
) -> Reply {
    let who = s.access.control(&headers)?;
    let req: SdoWrite = body(b)?;
    let id = node_id(&id, false)?;
    let w = network(&s, &net)?;
    let (index, sub, ty, entry) = named(w, id, &name)?;
    write(
        &s,
        who,
        peer,
        w,
        id,
        (index, sub),
        req,
        Some(ty),
        Some(entry),
    )
    .await
}

/// Writes the request's value to (`index`, `sub`) of node `id`, as its type, else the
/// described one.
#[allow(clippy::too_many_arguments)]
async fn write(
    s: &Shared,
    who: &str,
    peer: SocketAddr,
    w: &Watched,
    id: u8,
    (index, sub): (u16, u8),
    req: SdoWrite,
    described: Option<String>,
    entry: Option<String>,
) -> Reply {
    let Some(name) = req.ty.or(described).map(|t| t.to_ascii_lowercase()) else {
        return Err(bad(
            "type: missing: give the CiA 309 type (\"type\":\"u32\"), or name the node's EDS \
             or DCF in the station file (boards) for its entries' types",
        ));
    };
    let ty = value::data_type(&name).map_err(bad)?;
    let data = value::to_bytes(ty, &req.value).map_err(bad)?;
    let _turn = s.turns.acquire().await;
    let r = w.net.node(id).sdo().write_bytes(index, sub, data).await;
    let what = format!(
        "sdo write node {id:#04x} {index:#06x}:{sub} {name} {}: {}",
        req.value,
        outcome(&r)
    );
    record(w, who, peer, &what);
    r.map_err(|e| net_error(&e))?;
    let mut answer = sdo_json(w, id, index, sub, &name, req.value);
    if let Some(e) = entry {
        answer["name"] = Value::String(e);
    }
    Ok(axum::Json(answer).into_response())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Nmt {
    command: String,
    node: Value,
}

async fn nmt(
    State(s): State<Arc<Shared>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    Path(net): Path<String>,
    b: Result<Bytes, BytesRejection>,
) -> Reply {
    let who = s.access.control(&headers)?;
    let req: Nmt = body(b)?;
    let action = <Action as clap::ValueEnum>::from_str(&req.command, false).map_err(|_| {
        bad(format!(
            "command: {:?} is not an NMT command: start, stop, preop, reset or reset-comm",
            req.command
        ))
    })?;
    let id = match &req.node {
        Value::Number(n) => node_id(&n.to_string(), true)?,
        Value::String(t) => node_id(t, true)?,
        _ => return Err(bad("node: a node-ID (1 to 127, or 0 for all) as a number")),
    };
    let w = network(&s, &net)?;
    let _turn = s.turns.acquire().await;
    let r = if id == 0 {
        w.net.nmt_all(action.command()).await
    } else {
        w.net.node(id).send_nmt(action.command()).await
    };
    let target = if id == 0 {
        "all nodes".to_string()
    } else {
        format!("node {id:#04x}")
    };
    let what = format!("nmt {} {target}: {}", req.command, outcome(&r));
    record(w, who, peer, &what);
    r.map_err(|e| net_error(&e))?;
    Ok(
        axum::Json(json!({ "network": w.name, "node": id, "command": req.command }))
            .into_response(),
    )
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct Switch {
    to: Option<String>,
}

async fn switch(
    State(s): State<Arc<Shared>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    headers: HeaderMap,
    Path((net, id)): Path<(String, String)>,
    b: Result<Bytes, BytesRejection>,
) -> Reply {
    let who = s.access.control(&headers)?;
    // No body at all: to the member not running.
    let req: Switch = match &b {
        Ok(x) if x.iter().all(u8::is_ascii_whitespace) => Switch::default(),
        _ => body(b)?,
    };
    let to = match req.to.as_deref().map(str::trim) {
        None => None,
        Some("A" | "a") => Some(Member::A),
        Some("B" | "b") => Some(Member::B),
        Some(other) => return Err(bad(format!("to: {other:?} is not a member: A or B"))),
    };
    let id = node_id(&id, false)?;
    let w = network(&s, &net)?;
    let _turn = s.turns.acquire().await;
    let found = w
        .net
        .with(move |n, _| {
            n.pairs()
                .find(|(_, p)| {
                    [Member::A, Member::B]
                        .iter()
                        .any(|m| p.spec.node(*m).raw() == id)
                })
                .map(|(pair, p)| {
                    let (a, b) = (p.spec.node(Member::A).raw(), p.spec.node(Member::B).raw());
                    (pair, p.active, format!("{a:#04x}/{b:#04x}"))
                })
        })
        .await
        .map_err(|e| error(StatusCode::SERVICE_UNAVAILABLE, &e.to_string()))?;
    let Some((pair, active, label)) = found else {
        return Err(error(
            StatusCode::NOT_FOUND,
            &format!("no pair of network {:?} has node {id:#04x}", w.name),
        ));
    };
    let to = to.unwrap_or(match active {
        Some(Member::A) => Member::B,
        _ => Member::A,
    });
    let r = w.net.switch_over(pair, to).await;
    let m = if to == Member::A { "A" } else { "B" };
    let what = match &r {
        Ok(()) => format!("switch pair {label} to {m}: done"),
        Err(e) => format!("switch pair {label} to {m}: failed: {e}"),
    };
    record(w, who, peer, &what);
    r.map_err(|e| error(StatusCode::CONFLICT, &e.to_string()))?;
    Ok(axum::Json(json!({ "network": w.name, "pair": label, "active": m })).into_response())
}
