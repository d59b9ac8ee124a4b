//! Opening `--bus`: one interface, two as one logical bus, python-can's UDP bus, or the
//! built-in simulated station; and attaching the device descriptions of `--eds`/`--dcf`.
//!
//! Every command talks to the network through [`duocan::net::Network`], the library's front
//! door: the tool is a client on the bus (NMT commands, SDO requests and, for `lss`, the
//! LSS master's requests, nothing else; with `listen_only` not a single frame), never a node or
//! a CANopen master of it.

use crate::fail::Fail;
use crate::{ports, Global};
use duocan::eds::Description;
use duocan::net::{NetOptions, Network};
use duocan_redundancy::net::{open_dual, open_dual_named, SIM_SLAVES};
use std::collections::BTreeMap;
use std::sync::Arc;

/// The network a command runs on.
pub struct Bus {
    /// The front door.
    pub net: Network,
    /// The interfaces, as `--bus` named them.
    pub names: Vec<String>,
    /// The descriptions attached, by node-ID.
    pub descs: BTreeMap<u8, Arc<Description>>,
}

impl Bus {
    /// The description attached to `node`, if any.
    pub fn desc(&self, node: u8) -> Option<&Arc<Description>> {
        self.descs.get(&node)
    }
    /// Stops the network (and the simulated nodes or station behind it).
    pub async fn close(self) {
        self.net.close().await;
    }
}

/// The options every network of the tool opens with.
pub fn options(g: &Global, listen_only: bool) -> NetOptions {
    let opts = NetOptions::default()
        .with_sdo_timeout(std::time::Duration::from_millis(g.timeout))
        .with_listen_only(listen_only);
    match g.fd {
        Some(client) => opts.with_fd(client),
        None => opts,
    }
}

/// Opens the bus `--bus` names, with the descriptions attached.
pub fn open(g: &Global, listen_only: bool) -> Result<Bus, Fail> {
    open_with(g, options(g, listen_only))
}

/// [`open`] with `tap` told of every frame each port receives and sends.
pub fn open_tapped(
    g: &Global,
    listen_only: bool,
    tap: Option<Arc<dyn duocan::capture::recorder::Tap>>,
) -> Result<Bus, Fail> {
    let mut opts = options(g, listen_only);
    if let Some(tap) = tap {
        opts = opts.with_tap(tap);
    }
    open_with(g, opts)
}

/// True when `--bus` names the built-in simulated station (`sim-station`, `sim-station:faults`).
pub fn is_sim_station(names: &[String]) -> bool {
    matches!(names, [one] if one == "sim-station" || one == "sim-station:faults")
}

/// True when `--bus` names a built-in simulated network (the station, or `sim-nodes`: one bus
/// with nodes 1 to 10, `sim-nodes:fd` on a CANopen FD bus), whose nodes carry the simulated
/// description by themselves.
pub fn is_simulated(names: &[String]) -> bool {
    is_sim_station(names) || matches!(names, [one] if one == "sim-nodes" || one == "sim-nodes:fd")
}

/// [`open`] with `opts` (a tap, for the commands that watch the wire).
pub fn open_with(g: &Global, opts: NetOptions) -> Result<Bus, Fail> {
    let names = g.bus.clone().ok_or_else(|| {
        Fail::usage("no bus: give --bus can0 (or can0,can1, udp, sim-station), or set DUOCAN_BUS")
    })?;
    let station = is_sim_station(&names.0);
    if g.fd.is_some() && station {
        return Err(Fail::usage(
            "--fd: a CANopen FD network runs on real interfaces (can0, udp:N, or two of them) \
             or on sim-nodes, not on the simulated station",
        ));
    }
    let fd = opts.fd.is_some();
    let net = match names.0.as_slice() {
        [one] if station => open_dual_named(one, opts).map_err(|e| Fail::bus(e.to_string()))?,
        // `sim-nodes`, or a name that looks simulated and is told which ones there are.
        [one] if one == "sim" || one.starts_with("sim-") || one.starts_with("sim:") => {
            Network::open_named_with(one, opts)?
        }
        [one] => open_one(g, one, opts)?,
        [a, b] => open_dual(
            ports::open_fd(a, g.udp_interface, fd)?,
            ports::open_fd(b, g.udp_interface, fd)?,
            opts,
        )
        .map_err(|e| Fail::bus(e.to_string()))?,
        _ => return Err(Fail::usage("--bus names one or two interfaces")),
    };
    let mut descs = BTreeMap::new();
    if is_simulated(&names.0) {
        // The station's plain slaves and the nodes of `sim-nodes` are duocan's simulated
        // nodes: their names work out of the box.
        let d = Arc::new(duocan::net::sim_description()?);
        let ids = if station {
            SIM_SLAVES.to_vec()
        } else {
            (1..=10).collect()
        };
        for id in ids {
            descs.insert(id, d.clone());
        }
    }
    descs.extend(descriptions(g)?);
    for (id, d) in &descs {
        let _ = net.add_node(*id, d.clone());
    }
    Ok(Bus {
        net,
        names: names.0,
        descs,
    })
}

/// The descriptions `--eds` and `--dcf` attach, by node-ID (without a bus: `dump FILE` names
/// PDO values with them).
pub fn descriptions(g: &Global) -> Result<BTreeMap<u8, Arc<Description>>, Fail> {
    let mut descs = BTreeMap::new();
    for (node, path) in g.eds.iter().chain(&g.dcf).map(|d| (&d.0, &d.1)) {
        let desc = Description::read(path).map_err(|e| Fail::usage(e.to_string()))?;
        let id = match (node, desc.commissioning.as_ref().and_then(|c| c.node_id)) {
            (Some(n), _) => n.raw(),
            (None, Some(n)) => n,
            (None, None) => {
                return Err(Fail::usage(format!(
                    "{}: which node is it for? give NODE={} (the file names no NodeID)",
                    path.display(),
                    path.display()
                )))
            }
        };
        descs.insert(id, Arc::new(desc));
    }
    Ok(descs)
}

fn open_one(g: &Global, name: &str, opts: NetOptions) -> Result<Network, Fail> {
    // Loopback unless told otherwise, as the library does.
    Ok(Network::open_with(
        ports::open_fd(name, g.udp_interface, opts.fd.is_some())?,
        opts,
    )?)
}
