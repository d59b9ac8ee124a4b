//! Opening a network by name, and the simulated nodes behind the name `sim`: what lets a user
//! try the front door without hardware.

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

/// The simulated nodes a network opened on `sim` keeps running.
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

/// A duocan slave `id` as the simulated nodes are: identity (vendor [`SIM_VENDOR`], product
/// = node-ID), device name [`SIM_DEVICE_NAME`] at 0x1008, heartbeat every
/// [`SIM_HEARTBEAT_MS`] ms, booted (its boot-up goes out when its runtime starts).
fn sim_node(id: NodeId) -> SimNode {
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
    let mut node = crate::node::Node::new(NodeConfig::slave(id), od);
    node.boot(Instant::ZERO);
    Station::single(node)
}

impl Network {
    /// Opens a network by port name, with default options:
    ///
    /// - `sim`: an in-memory bus with simulated duocan nodes 1 to 10 on it (identity with
    ///   vendor-ID [`SIM_VENDOR`] and product code = node-ID, device name at 0x1008, heartbeat
    ///   every [`SIM_HEARTBEAT_MS`] ms), for trying things without hardware;
    /// - `udp` or `udp:N`: python-can's `udp_multicast` bus (its default group, or test bus N;
    ///   feature `udp`);
    /// - anything else: a SocketCAN interface such as `can0` or `vcan0` (feature `socketcan`,
    ///   Linux).
    pub fn open_named(name: &str) -> Result<Network, NetError> {
        Self::open_named_with(name, NetOptions::default())
    }

    /// [`Network::open_named`], listen-only ([`Network::monitor`]).
    pub fn monitor_named(name: &str) -> Result<Network, NetError> {
        Self::open_named_with(name, NetOptions::default().with_listen_only(true))
    }

    /// [`Network::open_named`] with options.
    pub fn open_named_with(name: &str, opts: NetOptions) -> Result<Network, NetError> {
        if name == "sim" {
            return Self::simulated(1..=10, opts);
        }
        if name == "udp" || name.starts_with("udp:") {
            return udp(name, opts);
        }
        socketcan(name, opts)
    }

    /// Opens a network on a new in-memory bus with simulated nodes `ids` on it (as for
    /// [`Network::open_named`]`("sim")`); node-IDs outside 1–127 are skipped.
    pub fn simulated(
        ids: impl IntoIterator<Item = u8>,
        opts: NetOptions,
    ) -> Result<Network, NetError> {
        let bus = MemBus::new("sim");
        // The network's port first: a port hears only what is sent after it exists, and the
        // nodes' boot-ups go out as soon as they start.
        let port = bus.port();
        let mut nodes = Vec::new();
        if tokio::runtime::Handle::try_current().is_ok() {
            for id in ids.into_iter().filter_map(NodeId::new) {
                let h = Runtime::new(sim_node(id))
                    .name(format!("sim node {}", id.raw()))
                    .port(bus.port())
                    .spawn()
                    .map_err(|e| NetError::Port(e.to_string()))?;
                nodes.push(h);
            }
        }
        Self::start(port, opts, SimNodes(nodes))
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
    let port = crate::port::socketcan::SocketCanPort::open(name)
        .map_err(|e| NetError::Port(e.to_string()))?;
    Network::open_with(port, opts)
}

#[cfg(not(all(feature = "socketcan", target_os = "linux")))]
fn socketcan(name: &str, _: NetOptions) -> Result<Network, NetError> {
    Err(NetError::Port(format!(
        "{name:?}: this build has no SocketCAN: use \"sim\", or enable the `socketcan` feature (Linux)"
    )))
}
