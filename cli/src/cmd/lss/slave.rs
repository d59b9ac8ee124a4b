//! `duocan device lss-slave`: a duocan device with an LSS slave (CiA 305) on one bus or two,
//! until stopped — for commissioning drills and for testing LSS masters (python `canopen`'s,
//! `duocan lss`) against duocan without hardware.
//!
//! ```text
//! duocan --bus udp device lss-slave --serial 7            # no node-ID: LSS only
//! duocan --bus can0,can1 device lss-slave --serial 7 --medium lss.bin
//! ```
//!
//! It boots without a node-ID (0xFF) unless `--node` gives one or `--medium` holds a stored
//! one, and then says nothing but LSS answers. Once an LSS master has given it a node-ID and
//! switched it back to waiting (or reset its communication), it boots as a CiA 301 slave with
//! that node-ID: identity = the LSS address, heartbeat every `--heartbeat-ms`. Store
//! configuration writes the node-ID and bit rate to `--medium FILE` (in RAM without one).
//! Each LSS event is a line on standard output (`mode configuration`, `node-id configured
//! 0x20`, `boot node-id 0x20`, …), `--json`: one object per line.

use crate::args::{parse_node, parse_timeout_ms};
use crate::fail::Fail;
use crate::out;
use crate::{ports, Global};
use duocan::cia305::{LssAddress, LssSlave, LssSlaveEventKind};
use duocan::machine::{SinglePort, StationEvent};
use duocan::node::{LssNode, LssNodeEvent};
use duocan::od::parameters::{FileStorage, MemoryStorage, ParameterStorage};
use duocan::od::{comm, ObjectDictionary};
use duocan::runtime::{Runtime, RuntimeEvent};
use duocan::{Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::{DualBus, DualBusConfig};
use serde_json::json;
use std::path::PathBuf;

/// The arguments of `duocan device lss-slave`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Its serial number (0x1018 sub 4): what tells two boards of one product apart
    #[arg(long, value_parser = super::parse::parse_part)]
    serial: u32,
    /// Its vendor-ID (default: duocan's simulated devices')
    #[arg(long, value_parser = super::parse::parse_part, default_value_t = duocan::net::SIM_VENDOR)]
    vendor: u32,
    /// Its product code
    #[arg(long, value_parser = super::parse::parse_part, default_value = "0x305")]
    product: u32,
    /// Its revision number
    #[arg(long, value_parser = super::parse::parse_part, default_value = "1")]
    revision: u32,
    /// Boot with this node-ID (default: none, LSS only until a master gives one)
    #[arg(long, value_parser = parse_node)]
    node: Option<NodeId>,
    /// Store configuration writes here, and the stored node-ID is loaded at start
    #[arg(long, value_name = "FILE")]
    medium: Option<PathBuf>,
    /// The node's heartbeat period (0x1017), ms
    #[arg(long, default_value = "100", value_parser = parse_timeout_ms)]
    heartbeat_ms: u64,
    /// Stop after this long (default: run until interrupted)
    #[arg(long, value_parser = parse_timeout_ms)]
    duration_ms: Option<u64>,
}

/// Runs `duocan device lss-slave`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    match &a.medium {
        Some(p) => start(g, &a, FileStorage::new(p)).await,
        None => start(g, &a, MemoryStorage::<64>::new()).await,
    }
}

async fn start<S: ParameterStorage + Send + 'static>(
    g: &Global,
    a: &Args,
    medium: S,
) -> Result<(), Fail> {
    let names = g
        .bus
        .as_ref()
        .map(|b| b.0.clone())
        .ok_or_else(|| Fail::usage("no bus: give --bus udp (or can0, can0,can1)"))?;
    let address = LssAddress {
        vendor: a.vendor,
        product: a.product,
        revision: a.revision,
        serial: a.serial,
    };
    let hb =
        u16::try_from(a.heartbeat_ms).map_err(|_| Fail::usage("--heartbeat-ms: at most 65535"))?;
    let initial = a
        .node
        .map_or(duocan::cia305::codec::UNCONFIGURED, NodeId::raw);
    let mut slave = LssSlave::new(address, initial).with_storage(medium);
    if a.medium.is_some() {
        slave
            .load_stored()
            .map_err(|e| Fail::usage(format!("--medium: {e}")))?;
    }
    let build = move |id: NodeId, now: Instant| {
        let ident = comm::Identity {
            vendor: address.vendor,
            product: address.product,
            revision: address.revision,
            serial: address.serial,
            ..Default::default()
        };
        let mut od = comm::standard_dictionary(id.raw(), ident);
        let _ = od.write_local(comm::HEARTBEAT_PRODUCER, 0, &hb.to_le_bytes());
        let mut n = Node::new(NodeConfig::slave(id), od);
        n.boot(now);
        n
    };
    let dev = LssNode::new(Instant::ZERO, slave, build);
    let label = format!("LSS slave {address}");
    match names.as_slice() {
        [one] => {
            let port = ports::open(one, g.udp_interface)?;
            let rt = Runtime::boxed(Box::new(Station::new(SinglePort::default(), dev)))
                .name(label.clone())
                .port(port);
            serve(g, a, rt, &label, one).await
        }
        [x, y] => {
            let rt = Runtime::boxed(Box::new(Station::new(
                DualBus::new(DualBusConfig::default()),
                dev,
            )))
            .name(label.clone())
            .port(ports::open(x, g.udp_interface)?)
            .port(ports::open(y, g.udp_interface)?);
            serve(g, a, rt, &label, &format!("{x},{y}")).await
        }
        _ => Err(Fail::usage("--bus names one or two interfaces")),
    }
}

/// Starts the runtime and prints the slave's events until stopped.
async fn serve<D, L, N>(
    g: &Global,
    a: &Args,
    rt: Runtime<D>,
    label: &str,
    on: &str,
) -> Result<(), Fail>
where
    D: duocan::Device<Event = StationEvent<L, LssNodeEvent<N>>> + Send + 'static,
    L: Clone + Send + core::fmt::Debug + 'static,
    N: Clone + Send + core::fmt::Debug + 'static,
{
    let h = rt.spawn().map_err(|e| Fail::usage(e.to_string()))?;
    let mut events = h.subscribe();
    eprintln!("{label} on {on}");
    let json = g.json;
    let printing = async move {
        while let Ok(e) = events.recv().await {
            let RuntimeEvent::Device(StationEvent::Machine(LssNodeEvent::Lss(e))) = e else {
                continue;
            };
            if let Some((text, value)) = describe(e.kind) {
                out::result(json, &text, value);
            }
        }
    };
    tokio::select! {
        () = printing => {}
        r = super::super::device::until_stopped(a.duration_ms) => r?,
    }
    h.shutdown().await;
    Ok(())
}

/// An event as a line and as JSON.
fn describe(k: LssSlaveEventKind) -> Option<(String, serde_json::Value)> {
    let node = |n: Option<NodeId>| n.map_or("none".to_string(), |n| format!("{:#04x}", n.raw()));
    Some(match k {
        LssSlaveEventKind::Mode(m) => {
            let m = match m {
                duocan::cia305::LssMode::Waiting => "waiting",
                duocan::cia305::LssMode::Configuration => "configuration",
            };
            (format!("mode {m}"), json!({"event": "mode", "mode": m}))
        }
        LssSlaveEventKind::NodeIdConfigured(n) => (
            format!("node-id configured {}", node(NodeId::new(n))),
            json!({"event": "node_id_configured", "node_id": NodeId::new(n).map(NodeId::raw)}),
        ),
        LssSlaveEventKind::BitTimingConfigured(t) => (
            format!("bit rate configured {} kbit/s", t.kbit().unwrap_or(0)),
            json!({"event": "bit_rate_configured", "kbit": t.kbit()}),
        ),
        LssSlaveEventKind::SwitchBitRate(t) => (
            format!("bit rate switch {} kbit/s", t.kbit().unwrap_or(0)),
            json!({"event": "bit_rate_switch", "kbit": t.kbit()}),
        ),
        LssSlaveEventKind::NodeIdActivated(n) => (
            format!("boot node-id {}", node(n)),
            json!({"event": "boot", "node_id": n.map(NodeId::raw)}),
        ),
        LssSlaveEventKind::ResetCommunication(n) => (
            format!("boot node-id {}", node(Some(n))),
            json!({"event": "boot", "node_id": n.raw()}),
        ),
        LssSlaveEventKind::Stored => ("stored".into(), json!({"event": "stored"})),
        LssSlaveEventKind::StoreFailed(e) => (
            format!("store failed: {e}"),
            json!({"event": "store_failed", "why": e.to_string()}),
        ),
        _ => return None,
    })
}
