//! `duocan scan [--listen MS] [--no-probe]`: which nodes are on the network, and what they are.
//!
//! # How nodes are found
//!
//! Two ways at once, so that neither a silent node nor a node without an SDO server is missed:
//!
//! - **listening** for `--listen` milliseconds (1500 by default): every boot-up and heartbeat
//!   heard names a node and its NMT state (the network tracks them from the moment it opens);
//! - **probing** (unless `--no-probe`): an SDO upload of 0x1000 (device type) to every node-ID
//!   1–127, each with a short timeout (`--probe-timeout`, 100 ms). The requests to different
//!   nodes run at once through the one network handle (as many as it has client sessions), so
//!   127 IDs take about 127 / 8 × 100 ms ≈ 1.6 s when most are absent.
//!
//! Then each node found is asked for its identity (0x1018 sub 1–4: vendor-ID, product code,
//! revision, serial) and device name (0x1008), all nodes at once; what a node does not have is
//! `-`. A node only heard (no SDO answer) shows its state and nothing else.
//!
//! # The description column
//!
//! With descriptions attached (`--eds NODE=FILE`, `--dcf`), each node's identity is compared
//! with them: vendor number and product number, and the revision when the description gives
//! one. The description attached to the node itself is named when it matches, and shown as
//! `MISMATCH: …` (what differs) when it does not; a node with none of its own is matched
//! against every description attached (the first whose identity fits is named); `-` when none
//! fits. The description `--bus sim-station` attaches to every ID on its own is not compared (it
//! describes any simulated node, whatever its product code).
//!
//! # Output and time
//!
//! A table (node, state, identity, name, description, and on two ports the bus each node was
//! heard on), or `--json`: an array of objects. An empty network is exit 0 with "no nodes
//! answered". On `--bus sim-station` a full scan (listen 1500 ms, probe 1–127) takes about 1.6 s.

use crate::bus::{self, Bus};
use crate::fail::Fail;
use crate::out::{self, node_cell, Cell, Table};
use crate::Global;
use duocan::eds::Description;
use duocan::net::{NetError, RemoteNode};
use duocan::sdo::{SdoErrorKind, SdoOptions};
use duocan::Duration as CoDuration;
use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

/// The arguments of `duocan scan`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "Nodes are found by listening for boot-ups and heartbeats and, at the same \
time, by asking every node-ID 1-127 for 0x1000 over SDO (the requests run together, 100 ms each). \
A full scan takes about 1.6 s on --bus sim-station."
)]
pub struct Args {
    /// Listen for boot-ups and heartbeats this long, in milliseconds
    #[arg(long, value_name = "MS", default_value = "1500", value_parser = parse_listen)]
    listen: u64,
    /// Do not probe node-IDs 1-127 over SDO; find nodes only by listening
    #[arg(long = "no-probe", action = clap::ArgAction::SetFalse)]
    sdo_probe: bool,
    /// Probe node-IDs 1-127 over SDO (the default)
    #[arg(long = "sdo-probe", overrides_with = "sdo_probe", hide = true)]
    _probe_on: bool,
    /// How long each probe waits for an answer, in milliseconds
    #[arg(long, value_name = "MS", default_value = "100", value_parser = crate::args::parse_timeout_ms)]
    probe_timeout: u64,
}

/// `--listen`: 0 (probe only) to an hour.
fn parse_listen(s: &str) -> Result<u64, String> {
    let ms: u64 = crate::args::parse_unsigned(s, "a time in milliseconds")?;
    if ms > crate::args::MAX_TIMEOUT_MS {
        return Err(format!(
            "{ms} ms: give 0 to {} (an hour)",
            crate::args::MAX_TIMEOUT_MS
        ));
    }
    Ok(ms)
}

/// What was learnt of one node.
#[derive(Debug, Default)]
struct Found {
    state: Option<duocan::NmtState>,
    device_type: Option<u32>,
    vendor: Option<u32>,
    product: Option<u32>,
    revision: Option<u32>,
    serial: Option<u32>,
    name: Option<String>,
    /// On two ports: whether it was heard on bus 1 and on bus 2.
    heard_on: Option<duocan::net::HeardOn>,
}

/// Runs `duocan scan`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    let bus = bus::open(g, false)?;
    let r = scan(g, &bus, &a).await;
    bus.close().await;
    r
}

async fn scan(g: &Global, bus: &Bus, a: &Args) -> Result<(), Fail> {
    let probe = SdoOptions::default().with_timeout(CoDuration::from_millis(a.probe_timeout));
    let listen = tokio::time::sleep(Duration::from_millis(a.listen));
    let probes = async {
        if !a.sdo_probe {
            return Ok(BTreeSet::new());
        }
        let all = (1..=127u8).map(|id| {
            let sdo = bus.net.node(id).sdo().with_options(probe);
            async move { (id, sdo.read::<u32>(0x1000, 0).await) }
        });
        let mut answered = BTreeSet::new();
        for (id, r) in join_all(all).await {
            match r {
                Ok(_) => {
                    answered.insert(id);
                }
                // An abort is an answer: the node is there (it has no 0x1000, or refuses it).
                Err(NetError::WrongSize { .. }) => {
                    answered.insert(id);
                }
                Err(NetError::Sdo(e)) if matches!(e.kind, SdoErrorKind::Server(_)) => {
                    answered.insert(id);
                }
                // No answer, or an answer this client could not follow: not a node's SDO
                // server (the node may still be heard).
                Err(NetError::Sdo(_)) => {}
                Err(e) => return Err(Fail::from(e)),
            }
        }
        Ok(answered)
    };
    let ((), answered) = tokio::join!(listen, probes);
    let answered = answered?;
    let mut found: BTreeMap<u8, Found> = BTreeMap::new();
    for id in 1..=127u8 {
        let state = bus.net.node(id).state().await?;
        if state.is_some() || answered.contains(&id) {
            found.insert(
                id,
                Found {
                    state,
                    ..Found::default()
                },
            );
        }
    }
    let opts = SdoOptions::default().with_timeout(CoDuration::from_millis(g.timeout));
    let reads = found.keys().map(|&id| {
        let node = bus.net.node(id);
        async move { (id, identity(&node, opts).await) }
    });
    for (id, ident) in join_all(reads).await {
        if let Some(f) = found.get_mut(&id) {
            *f = Found {
                state: f.state,
                ..ident
            };
        }
    }
    // Asked last: by now every node found has sent something on the buses it reaches.
    for (id, f) in &mut found {
        f.heard_on = bus.net.heard_on(*id).await?;
    }
    print(g, bus, &found);
    Ok(())
}

/// Runs one task per node at once and gives their results (a task's panic, which the library
/// does not have, would be a missing result, never the tool's).
async fn join_all<T: Send + 'static>(
    tasks: impl Iterator<Item = impl std::future::Future<Output = T> + Send + 'static>,
) -> Vec<T> {
    let mut set = tokio::task::JoinSet::new();
    for t in tasks {
        set.spawn(t);
    }
    let mut out = Vec::new();
    while let Some(r) = set.join_next().await {
        if let Ok(v) = r {
            out.push(v);
        }
    }
    out
}

/// Reads identity and device name; what the node does not have stays `None`.
async fn identity(node: &RemoteNode, opts: SdoOptions) -> Found {
    let sdo = node.sdo().with_options(opts);
    let mut f = Found::default();
    f.device_type = match sdo.read::<u32>(0x1000, 0).await {
        // Heard but without an SDO server: no further waits.
        Err(e) if e.is_no_answer() => return f,
        r => r.ok(),
    };
    f.vendor = sdo.read::<u32>(0x1018, 1).await.ok();
    f.product = sdo.read::<u32>(0x1018, 2).await.ok();
    f.revision = sdo.read::<u32>(0x1018, 3).await.ok();
    f.serial = sdo.read::<u32>(0x1018, 4).await.ok();
    f.name = sdo.read_string(0x1008, 0).await.ok();
    f
}

fn hex32(v: Option<u32>) -> Cell {
    match v {
        Some(v) => Cell::new(format!("{v:#010x}"), v),
        None => Cell::none(),
    }
}

/// The description column: which attached description fits the node's identity.
fn matched(bus: &Bus, id: u8, f: &Found) -> Cell {
    let own = bus.desc(id).filter(|d| !is_sim_own(bus, d));
    if let Some(d) = own {
        return match mismatch(d, f) {
            None => Cell::from(file_name(d)),
            Some(why) => Cell::from(format!("MISMATCH: {why}")),
        };
    }
    bus.descs
        .values()
        .filter(|d| !is_sim_own(bus, d))
        .find(|d| f.vendor.is_some() && mismatch(d, f).is_none())
        .map_or_else(Cell::none, |d| Cell::from(file_name(d)))
}

/// The description a simulated `--bus` attaches to its nodes by itself.
fn is_sim_own(bus: &Bus, d: &Description) -> bool {
    crate::bus::is_simulated(&bus.names) && d.source == "duocan-sim.eds"
}

fn file_name(d: &Description) -> String {
    std::path::Path::new(&d.source)
        .file_name()
        .map_or_else(|| d.source.clone(), |n| n.to_string_lossy().into_owned())
}

/// What differs between the description's identity and the node's, if anything.
fn mismatch(d: &Description, f: &Found) -> Option<String> {
    let info = &d.device_info;
    let mut why = Vec::new();
    for (what, want, got) in [
        ("vendor", info.vendor_number, f.vendor),
        ("product", info.product_number, f.product),
        ("revision", info.revision_number, f.revision),
    ] {
        if let Some(want) = want {
            match got {
                Some(got) if got == want => {}
                Some(got) => why.push(format!("{what} {got:#x}, file says {want:#x}")),
                None => why.push(format!("{what} not read, file says {want:#x}")),
            }
        }
    }
    (!why.is_empty()).then(|| why.join("; "))
}

fn print(g: &Global, bus: &Bus, found: &BTreeMap<u8, Found>) {
    if found.is_empty() {
        out::result(g.json, "no nodes answered", serde_json::json!([]));
        return;
    }
    let mut cols = vec![
        "node",
        "state",
        "device type",
        "vendor",
        "product",
        "revision",
        "serial",
        "name",
        "description",
    ];
    // A column per bus where the link tells which buses a node is heard on.
    let buses = found
        .values()
        .filter_map(|f| f.heard_on)
        .map(|h| h.buses())
        .max()
        .unwrap_or(0);
    let bus_cols: Vec<String> = (1..=buses).map(|b| format!("bus {b}")).collect();
    cols.extend(bus_cols.iter().map(String::as_str));
    let mut t = Table::new(&cols);
    for (id, f) in found {
        let state = match f.state {
            Some(s) => Cell::from(s.to_string()),
            None => Cell::new("(not heard)", serde_json::Value::Null),
        };
        let mut row = vec![
            node_cell(*id),
            state,
            hex32(f.device_type),
            hex32(f.vendor),
            hex32(f.product),
            hex32(f.revision),
            hex32(f.serial),
            Cell::from(f.name.clone()),
            matched(bus, *id, f),
        ];
        if let Some(h) = f.heard_on {
            row.extend((0..buses).map(|b| Cell::from(h.on(b))));
        }
        t.row(row);
    }
    t.print(g.json);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn listen_takes_zero_to_an_hour() {
        assert_eq!(parse_listen("0"), Ok(0));
        assert_eq!(parse_listen("3600000"), Ok(3_600_000));
        for bad in ["3600001", "-1", "1.5", "", "1s"] {
            assert!(parse_listen(bad).is_err(), "{bad:?}");
        }
    }

    proptest::proptest! {
        #[test]
        fn listen_never_panics(s in ".*") {
            let _ = parse_listen(&s);
        }
    }
}
