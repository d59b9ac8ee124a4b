//! Opening a network by name, and the simulated nodes behind the name `sim-nodes`: what lets a
//! user try the front door without hardware.
//!
//! Each simulated network has a name that says what it holds, the same in every door and in
//! the tool: `sim-nodes` here (one bus, plain nodes), `sim-pairs` (a redundant network's own
//! pairs and peer masters) and `sim-station` (a whole redundant station) in duocan-redundancy.
//! A bare `sim` is none of them and says so ([`SIM_NAMES`]).
//!
//! **CAN FD.** A name with `:fd` after it opens a CANopen FD network (CiA 1301) there:
//! `sim-nodes:fd` (the same nodes, on an FD bus, serving USDO instead of SDO), `can0:fd` (the
//! interface opened for CAN FD, its MTU checked), `udp:fd` and `udp:N:fd` (python-can's bus
//! with `fd=True`). The network's USDO client is [`FD_CLIENT`] unless the options name
//! another ([`NetOptions::with_fd`]); options with FD open the port for CAN FD whatever the
//! name. So a program that opens the name it is given (the starter examples) runs unchanged
//! on an FD network: the typed reads and writes go over USDO, PDOs up to 64 bytes.

use super::{NetError, NetOptions, Network};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Instant;
use crate::machine::{SinglePort, Station};
use crate::node::NodeConfig;
use crate::od::{comm, Access, DataType, DefaultValue, ObjectDef, ObjectDictionary};
use crate::port::mem::MemBus;
use crate::runtime::{Handle, Runtime};

/// The vendor-ID (0x1018 sub 1) of every simulated node.
pub const SIM_VENDOR: u32 = 0x00D0_CA00;
/// The device name (0x1008) of every simulated node.
pub const SIM_DEVICE_NAME: &str = "duocan simulated node";
/// The heartbeat period of every simulated node, in milliseconds.
pub const SIM_HEARTBEAT_MS: u16 = 100;

type SimNode = Station<SinglePort, crate::node::Node<crate::od::DynamicDictionary>>;

/// What a name that looks simulated but is not one of the door's names is told: the simulated
/// networks there are, what each holds and where it opens.
pub const SIM_NAMES: &str = "the simulated networks are sim-nodes and sim-nodes:fd (one bus \
with nodes 1 to 10, classic or CANopen FD: duocan::net::Network::open_named), sim-pairs, sim-pairs:quiet and sim-pairs:failover (two buses \
with a redundant network's own pairs and peer masters: failing then closing, never failing, or \
failing then running on: the redundant builder's open_named) and sim-station or sim-station:faults (a redundant station on two buses: \
duocan_redundancy::net::open_dual_named, the tool's --bus)";

/// The simulated nodes a network opened on `sim-nodes` keeps running.
#[derive(Default)]
pub(super) struct SimNodes(Vec<Handle<SimNode>>);

impl SimNodes {
    /// Stops every simulated node.
    pub(super) async fn shutdown(&self) {
        for h in &self.0 {
            h.shutdown().await;
        }
    }
}

/// The USDO client node-ID of a CANopen FD network a name opens (`sim-nodes:fd`, `can0:fd`)
/// when the options name none: 127, the node-ID the door uses internally anyway.
pub const FD_CLIENT: NodeId = NodeId::must(127);

/// A duocan slave `id` as the simulated nodes are ([`sim_dictionary`]), booted (its boot-up
/// goes out when its runtime starts); on a CANopen FD network (`fd`) it serves USDO and sends
/// and receives its PDOs in CAN FD frames.
fn sim_node(id: NodeId, fd: bool) -> SimNode {
    let cfg = NodeConfig::slave(id).with_fd(fd);
    let mut node = crate::node::Node::new(cfg, sim_dictionary(id));
    node.boot(Instant::ZERO);
    if fd {
        Station::new(SinglePort::fd(), node)
    } else {
        Station::single(node)
    }
}

/// `name` without a trailing `:fd`, and whether it had one.
fn fd_suffix(name: &str) -> (&str, bool) {
    match name.strip_suffix(":fd") {
        Some(base) => (base, true),
        None => (name, false),
    }
}

/// The dictionary of simulated node `id` (what [`Network::open_named`]`("sim-nodes")` runs, and
/// what other simulated stations build their plain slaves from): the standard communication
/// objects, identity (vendor [`SIM_VENDOR`], product code = node-ID), device name
/// [`SIM_DEVICE_NAME`] at 0x1008, heartbeat every [`SIM_HEARTBEAT_MS`] ms, inputs 0x6000 (Input 1,
/// Input 2, Status) sent by TPDO1 on request, outputs 0x6200 written by RPDO1, and TPDO2–4 and
/// RPDO2–4 disabled and unmapped, to be configured ([`sim_description`] describes it).
#[must_use]
pub fn sim_dictionary(id: NodeId) -> crate::od::DynamicDictionary {
    let ident = comm::Identity {
        vendor: SIM_VENDOR,
        product: u32::from(id.raw()),
        ..Default::default()
    };
    let mut od = comm::standard_dictionary(id.raw(), ident);
    // 0x1017 is in the standard dictionary and takes any u16.
    let _ = od.write_local(comm::HEARTBEAT_PRODUCER, 0, &SIM_HEARTBEAT_MS.to_le_bytes());
    od.upsert(
        ObjectDef::bytes(0x1008, 0, DataType::VisibleString, 32)
            .access(Access::Ro)
            .default(DefaultValue::Bytes(SIM_DEVICE_NAME.as_bytes()))
            .named("Manufacturer device name"),
    );
    add_process_data(&mut od);
    od
}

/// Sub-entries of the simulated nodes' input record 0x6000 (what their TPDOs carry).
const INPUTS: [(u8, DataType, &str); 3] = [
    (1, DataType::Unsigned16, "Input 1"),
    (2, DataType::Integer16, "Input 2"),
    (3, DataType::Unsigned8, "Status"),
];
/// Sub-entries of the output record 0x6200 (what their RPDOs write).
const OUTPUTS: [(u8, DataType, &str); 2] = [
    (1, DataType::Unsigned16, "Output 1"),
    (2, DataType::Integer8, "Output 2"),
];

/// The simulated nodes' process data and PDOs: inputs 0x6000 (TPDO1 maps Input 1 and Status,
/// sent on request, type 254), outputs 0x6200 (RPDO1 maps Output 1 and Output 2, applied at
/// once, type 255); TPDO2–4 and RPDO2–4 exist disabled and unmapped, to be configured.
fn add_process_data(od: &mut crate::od::DynamicDictionary) {
    use crate::cia301::pdo::params;
    use crate::od::ObjectType;
    let record = |index: u16, name: &'static str, entries: &[(u8, DataType, &'static str)]| {
        let mut defs = vec![ObjectDef::u8(index, 0, Access::Const, entries.len() as u8)
            .object_type(ObjectType::Record)
            .named(name)];
        defs.extend(entries.iter().map(|&(sub, t, n)| {
            ObjectDef::new(index, sub, t)
                .access(Access::Rw)
                .mappable()
                .object_type(ObjectType::Record)
                .named(n)
        }));
        defs
    };
    // Every key is distinct and new to the standard dictionary: the inserts cannot fail.
    let _ = od.insert_all(&record(0x6000, "Inputs", &INPUTS));
    let _ = od.insert_all(&record(0x6200, "Outputs", &OUTPUTS));
    for pdo in 1..=4u16 {
        let (tpdo_cob, rpdo_cob) = if pdo == 1 {
            (
                params::predefined_tpdo_cob(1),
                params::predefined_rpdo_cob(1),
            )
        } else {
            // Disabled, on their predefined identifiers.
            let base = 0x8000_0000 + (u32::from(pdo) - 1) * 0x100;
            (
                DefaultValue::NodeIdPlus(base + 0x180),
                DefaultValue::NodeIdPlus(base + 0x200),
            )
        };
        let (t_map, r_map): (&[u32], &[u32]) = if pdo == 1 {
            (&[0x6000_0110, 0x6000_0308], &[0x6200_0110, 0x6200_0208])
        } else {
            (&[], &[])
        };
        let _ = od.insert_all(&params::tpdo_comm(pdo, tpdo_cob, 254, 0, 0));
        let _ = od.insert_all(&params::tpdo_mapping::<9>(pdo, t_map));
        let _ = od.insert_all(&params::rpdo_comm(pdo, rpdo_cob, 255, 0));
        let _ = od.insert_all(&params::rpdo_mapping::<9>(pdo, r_map));
    }
}

/// The device description of the simulated nodes (the one [`Network::open_named`]`("sim-nodes")`
/// starts): attach it to name their entries (`"Input 1"`, `"Producer heartbeat time"`) and
/// the values of their PDOs.
///
/// ```
/// # #[tokio::main] async fn main() -> Result<(), duocan::net::NetError> {
/// use duocan::net::{sim_description, Network};
/// let net = Network::open_named("sim-nodes")?;
/// let node = net.add_node(5, sim_description()?);
/// let hb: u16 = node.sdo().read_named("Producer heartbeat time").await?;
/// assert_eq!(hb, duocan::net::SIM_HEARTBEAT_MS);
/// # Ok(()) }
/// ```
pub fn sim_description() -> Result<crate::eds::Description, NetError> {
    use crate::eds::{export_eds, Description, ExportOptions, ImportOptions};
    let node = sim_node(NodeId::must(1), false);
    let text = export_eds(node.machine.od(), &ExportOptions::default())
        .map_err(|e| NetError::Argument(format!("the simulated nodes' EDS: {e}")))?;
    Ok(Description::parse(
        text.as_bytes(),
        "duocan-sim.eds",
        &ImportOptions::lenient(),
    )?)
}

impl Network {
    /// Opens a network by port name, with default options:
    ///
    /// - `sim-nodes`: an in-memory bus with simulated duocan nodes 1 to 10 on it (identity with
    ///   vendor-ID [`SIM_VENDOR`] and product code = node-ID, device name at 0x1008, heartbeat
    ///   every [`SIM_HEARTBEAT_MS`] ms), for trying things without hardware;
    /// - `udp` or `udp:N`: python-can's `udp_multicast` bus (its default group, or test bus N;
    ///   feature `udp`);
    /// - anything else: a SocketCAN interface such as `can0` or `vcan0` (feature `socketcan`,
    ///   Linux).
    ///
    /// Each with `:fd` after it (`sim-nodes:fd`, `udp:3:fd`, `can0:fd`) is a CANopen FD network
    /// there: the port opened for CAN FD, the nodes read and written over USDO with the same
    /// calls (its client node-ID [`FD_CLIENT`] unless the options name one), and the simulated
    /// nodes serving USDO.
    ///
    /// ```
    /// # #[tokio::main] async fn main() -> Result<(), duocan::net::NetError> {
    /// let net = duocan::net::Network::open_named("sim-nodes:fd")?;
    /// let vendor: u32 = net.node(5).sdo().read(0x1018, 1).await?; // over USDO
    /// assert_eq!(vendor, duocan::net::SIM_VENDOR);
    /// # Ok(()) }
    /// ```
    pub fn open_named(name: &str) -> Result<Network, NetError> {
        Self::open_named_with(name, NetOptions::default())
    }

    /// [`Network::open_named`], listen-only ([`Network::monitor`]).
    pub fn monitor_named(name: &str) -> Result<Network, NetError> {
        Self::open_named_with(name, NetOptions::default().with_listen_only(true))
    }

    /// [`Network::open_named`] with options. Options with FD ([`NetOptions::with_fd`]) open the
    /// named port for CAN FD as `:fd` after the name does.
    pub fn open_named_with(name: &str, mut opts: NetOptions) -> Result<Network, NetError> {
        let (name, fd) = fd_suffix(name);
        if fd && opts.fd.is_none() {
            opts.fd = Some(FD_CLIENT);
        }
        if name == "sim-nodes" {
            return Self::simulated(1..=10, opts);
        }
        if name == "sim" || name.starts_with("sim-") || name.starts_with("sim:") {
            return Err(NetError::Port(format!(
                "{name:?} is not a port of one bus: {SIM_NAMES}"
            )));
        }
        if name == "udp" || name.starts_with("udp:") {
            return udp(name, opts);
        }
        socketcan(name, opts)
    }

    /// Opens a network on a new in-memory bus with simulated nodes `ids` on it (as for
    /// [`Network::open_named`]`("sim-nodes")`); node-IDs outside 1–127 are skipped. With FD
    /// options ([`NetOptions::with_fd`]) the bus is a CANopen FD one and the nodes serve USDO
    /// (a node with the client's node-ID is skipped then).
    pub fn simulated(
        ids: impl IntoIterator<Item = u8>,
        opts: NetOptions,
    ) -> Result<Network, NetError> {
        Self::simulated_on(&MemBus::new("sim-nodes"), ids, opts)
    }

    /// [`Network::simulated`] on the in-memory bus `bus`: a port taken from it before the
    /// call sees every frame (the nodes' boot-ups included), to watch the wire.
    pub fn simulated_on(
        bus: &MemBus,
        ids: impl IntoIterator<Item = u8>,
        opts: NetOptions,
    ) -> Result<Network, NetError> {
        // The network's port first: a port hears only what is sent after it exists, and the
        // nodes' boot-ups go out as soon as they start.
        let port = bus.port();
        let mut nodes = Vec::new();
        if tokio::runtime::Handle::try_current().is_ok() {
            let ids = ids.into_iter().filter_map(NodeId::new);
            for id in ids.filter(|&id| Some(id) != opts.fd) {
                let h = Runtime::new(sim_node(id, opts.fd.is_some()))
                    .name(format!("sim node {}", id.raw()))
                    .port(bus.port())
                    .spawn()
                    .map_err(|e| NetError::Port(e.to_string()))?;
                nodes.push(h);
            }
        }
        Self::start(
            Box::new(super::link::OnePort::for_options(&opts)),
            port,
            opts,
            SimNodes(nodes),
        )
    }
}

#[cfg(feature = "udp")]
fn udp(name: &str, opts: NetOptions) -> Result<Network, NetError> {
    use crate::port::udp::{UdpBusConfig, UdpPort};
    let cfg = match name.strip_prefix("udp:") {
        None => UdpBusConfig::python_can_default(),
        Some(n) => match n.parse::<u8>() {
            Ok(n) => UdpBusConfig::numbered(n),
            Err(_) => {
                return Err(NetError::Port(format!(
                    "{name:?}: the UDP bus number must be 0 to 255, as in udp:3"
                )))
            }
        },
    };
    let cfg = if opts.fd.is_some() {
        cfg.with_fd()
    } else {
        cfg
    };
    let port = UdpPort::open(cfg).map_err(|e| NetError::Port(e.to_string()))?;
    Network::open_with(port, opts)
}

#[cfg(not(feature = "udp"))]
fn udp(name: &str, _: NetOptions) -> Result<Network, NetError> {
    Err(NetError::Port(format!(
        "{name:?}: this build has no UDP ports: enable the `udp` feature"
    )))
}

#[cfg(all(feature = "socketcan", target_os = "linux"))]
fn socketcan(name: &str, opts: NetOptions) -> Result<Network, NetError> {
    use crate::port::socketcan::SocketCanPort;
    // On a CANopen FD network the interface is opened for CAN FD: one whose MTU is not the
    // CAN FD MTU says so here.
    let port = if opts.fd.is_some() {
        SocketCanPort::open_fd(name)
    } else {
        SocketCanPort::open(name)
    }
    .map_err(|e| NetError::Port(e.to_string()))?;
    Network::open_with(port, opts)
}

#[cfg(not(all(feature = "socketcan", target_os = "linux")))]
fn socketcan(name: &str, _: NetOptions) -> Result<Network, NetError> {
    Err(NetError::Port(format!(
        "{name:?}: this build has no SocketCAN: use \"sim-nodes\", or enable the `socketcan` feature (Linux)"
    )))
}
