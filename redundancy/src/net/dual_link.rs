//! The dual-bus layer under duocan's plain front door: [`DualLink`] makes a [`DualBus`] a
//! [`NetLink`], so that `duocan::net::Network` (an observer and an SDO client, which sends only
//! NMT commands and SDO requests and is no master) runs on two buses unchanged. Requests fan out
//! to both buses, answers are merged exactly, and the port health and per-node reach show through
//! [`Network::ports`] and [`Network::heard_on`].
//!
//! This is the network a commissioning tool wants on somebody else's redundant network: it
//! never becomes a master there (for that, see [`RedundantNetwork`](super::RedundantNetwork)).
//!
//! ```
//! use duocan::net::{NetError, NetOptions};
//! use duocan_redundancy::net::open_dual_named;
//!
//! # #[tokio::main(flavor = "current_thread", start_paused = true)]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! // "sim-station": a simulated redundant station on two simulated buses; or "can0,can1", "udp:1,udp:2".
//! let net = open_dual_named("sim-station", NetOptions::default())?;
//! let vendor: u32 = net.node(5).sdo().read(0x1018, 1).await?;
//! assert_eq!(vendor, duocan::net::SIM_VENDOR);
//! let ports = net.ports().await?;
//! assert_eq!(ports.len(), 2);
//! assert_eq!(ports[0].state, "ok");
//! net.close().await;
//! # Ok(()) }
//! ```

use super::core::link_event;
use super::events::RedundantEvent;
use super::sim_station::{self as station, StationScript};
use crate::link::capacity::{Capacity, MergeCapacity};
use crate::link::channel::ModeKind;
use crate::link::classify::FrameClassifier;
use crate::link::config::DualBusConfig;
use crate::link::dual_bus::{DualBus, DEFAULT_MERGE_SLOTS};
use crate::link::events::LinkEvent;
use crate::logical::typed;
use crate::logical::RedundantError;
use alloc::boxed::Box;
use alloc::string::{String, ToString};
use core::convert::Infallible;
use duocan::machine::{BusLink, LinkRequest, StationEvent};
use duocan::net::{ExtEvent, HeardOn, NetEvent, NetLink, NetOptions, Network};
use duocan::port::Port;
use duocan::profile::Predefined;
use duocan::NodeId;

/// A [`DualBus`] as the link of a `duocan::net::Network`: its port-health and reach changes
/// become [`NetEvent::PortState`] and [`NetEvent::Reach`], its other reports (discrepancies,
/// heartbeats suspected, babbling, a bus lagging, channel switches) [`RedundantEvent::Link`]
/// in [`NetEvent::Ext`].
///
/// `SLOTS` is the merger's slot count (see [`DualBus`]); the default suits real buses.
#[derive(Debug)]
pub struct DualLink<const SLOTS: usize = DEFAULT_MERGE_SLOTS> {
    bus: DualBus<Predefined, Capacity<SLOTS>>,
}

impl DualLink {
    /// A link of two ports with the layer configured by `cfg`.
    #[must_use]
    pub fn new(cfg: DualBusConfig) -> Self {
        DualLink::with_slots(cfg)
    }
}

impl<const SLOTS: usize> DualLink<SLOTS> {
    /// A link whose merger has `SLOTS` slots (a power of two), for buses whose two copies of a
    /// frame can arrive further apart than real buses carry them.
    #[must_use]
    pub fn with_slots(cfg: DualBusConfig) -> Self {
        DualLink {
            bus: DualBus::with_classifier(cfg, Predefined),
        }
    }
    /// The layer (health, reach, merger, counters).
    #[must_use]
    pub fn bus(&self) -> &DualBus<Predefined, Capacity<SLOTS>> {
        &self.bus
    }
    /// The link with both ports FD-capable: it carries the CAN FD frames of a
    /// CANopen FD network ([`NetOptions::with_fd`]), each sent on both buses and merged once
    /// received. Only where every node on both buses speaks CAN FD (see
    /// [`DualBus::set_port_fd`]).
    #[must_use]
    pub fn fd(mut self) -> Self {
        self.bus.set_port_fd(0, true);
        self.bus.set_port_fd(1, true);
        self
    }
}

impl Default for DualLink {
    fn default() -> Self {
        DualLink::new(DualBusConfig::default())
    }
}

/// The front door's event of a layer event: port health and reach as duocan's own events,
/// everything else the layer reports as [`RedundantEvent::Link`].
fn net_event(e: LinkEvent) -> NetEvent {
    typed(&StationEvent::Link(e))
        .and_then(|k| link_event(&k, e.at))
        .unwrap_or_else(|| NetEvent::Ext(ExtEvent::new(RedundantEvent::Link(e))))
}

impl<const SLOTS: usize> BusLink for DualLink<SLOTS> {
    type Event = NetEvent;
    type Command = Infallible;
    fn port_count(&self) -> usize {
        2
    }
    duocan::forward_bus_link!(bus;
        handle_rx, handle_rx_at, handle_port_status, send, poll_transmit, poll_port_request,
        handle_timeout, poll_timeout, fd
    );
    fn poll_event(&mut self) -> Option<NetEvent> {
        self.bus.poll_event().map(net_event)
    }
    fn poll_machine_request(&mut self) -> Option<LinkRequest> {
        // The layer's requests (enter pre-operational, status entries, suspect nodes) are for
        // a node or a master on it; the front door is neither, and its observer must stay
        // quiet: dropped.
        while self.bus.poll_machine_request().is_some() {}
        None
    }
}

impl<const SLOTS: usize> NetLink for DualLink<SLOTS> {
    fn port_state(&self, port: usize) -> Option<crate::PortState> {
        (port < 2).then(|| self.bus.port_state(port))
    }
    fn heard_on(&self, node: NodeId) -> Option<HeardOn> {
        heard_on(&self.bus, node)
    }
}

/// On which of the two buses `node` was heard lately, as the front door shows it (any core
/// on a dual bus): `[false, false]` for a node not heard lately, `None` on a toggling link,
/// which listens to one bus at a time (reach means nothing there).
pub(super) fn heard_on<C: FrameClassifier, K: MergeCapacity>(
    bus: &DualBus<C, K>,
    node: NodeId,
) -> Option<HeardOn> {
    if bus.mode() == ModeKind::EcssToggle {
        return None;
    }
    Some(bus.reach().heard(node).unwrap_or([false, false]).into())
}

fn port_error(port: u8, name: &str, why: impl ToString) -> RedundantError {
    RedundantError::Port {
        port,
        name: name.into(),
        why: why.to_string(),
    }
}

/// Opens duocan's front door (`duocan::net::Network`: NMT commands and SDO requests, no
/// master) on two ports merged by the dual-bus layer (default configuration: active-active).
/// Port 1 is bus 1. Must be called inside a tokio runtime.
pub fn open_dual<P1: Port, P2: Port>(
    bus1: P1,
    bus2: P2,
    opts: NetOptions,
) -> Result<Network, RedundantError> {
    open_dual_with(bus1, bus2, DualBusConfig::default(), opts)
}

/// [`open_dual`] with the layer configured by `cfg`.
///
/// With [`NetOptions::with_fd`], a CANopen FD network on two buses: the link
/// carries CAN FD ([`DualLink::fd`]), the typed reads and writes go over USDO, each request on
/// both buses and each answer taken once, so a transfer goes on while one bus is cut. Both
/// ports must be opened for CAN FD.
pub fn open_dual_with<P1: Port, P2: Port>(
    bus1: P1,
    bus2: P2,
    cfg: DualBusConfig,
    opts: NetOptions,
) -> Result<Network, RedundantError> {
    let name = String::from(bus1.name());
    let link = DualLink::new(cfg);
    let link = if opts.fd.is_some() { link.fd() } else { link };
    Network::open_link(Box::new(link), (bus1, bus2), opts).map_err(|e| port_error(0, &name, e))
}

/// [`open_dual`] by name:
///
/// - `sim-station`: a simulated redundant station on two simulated buses (masters 0x01 and 0x02, the
///   pairs [`SIM_PAIRS`](super::SIM_PAIRS), the slaves [`SIM_SLAVES`](super::SIM_SLAVES); what
///   it holds is in the `net` module's docs), running until the network is closed;
/// - `sim-station:faults`: the same station with its fault script repeating every
///   [`SIM_FAULT_PERIOD`](super::SIM_FAULT_PERIOD);
/// - `udp:N,udp:M`: python-can's UDP test buses N and M (feature `udp`);
/// - `A,B`: SocketCAN interfaces A (bus 1) and B (bus 2), such as `can0,can1` (feature
///   `socketcan`, Linux).
pub fn open_dual_named(name: &str, opts: NetOptions) -> Result<Network, RedundantError> {
    match name {
        "sim-station" => return station::open(opts, StationScript::Quiet),
        "sim-station:faults" => return station::open(opts, StationScript::Faults),
        _ if name == "sim" || name.starts_with("sim-") || name.starts_with("sim:") => {
            return Err(port_error(
                0,
                name,
                alloc::format!(
                    "the simulated station on two buses is sim-station; {}",
                    duocan::net::SIM_NAMES
                ),
            ))
        }
        _ => {}
    }
    let Some((a, b)) = name.split_once(',') else {
        return Err(port_error(
            0,
            name,
            "two ports are needed: name them as can0,can1 or udp:1,udp:2 (or use \"sim-station\")",
        ));
    };
    let (a, b) = (a.trim(), b.trim());
    if a.starts_with("udp") && b.starts_with("udp") {
        return udp(a, b, opts);
    }
    socketcan(a, b, opts)
}

#[cfg(feature = "udp")]
fn udp(a: &str, b: &str, opts: NetOptions) -> Result<Network, RedundantError> {
    use duocan::port::udp::{UdpBusConfig, UdpPort};
    let open = |port: u8, name: &str| {
        let cfg = match name.strip_prefix("udp:").map(str::parse::<u8>) {
            Some(Ok(n)) => UdpBusConfig::numbered(n),
            _ => {
                return Err(port_error(
                    port,
                    name,
                    "a UDP bus of a dual network is numbered, 0 to 255, as in udp:1,udp:2",
                ))
            }
        };
        UdpPort::open(cfg).map_err(|e| port_error(port, name, e))
    };
    if a == b {
        return Err(port_error(1, b, "the two buses must differ"));
    }
    open_dual(open(0, a)?, open(1, b)?, opts)
}

#[cfg(not(feature = "udp"))]
fn udp(a: &str, _: &str, _: NetOptions) -> Result<Network, RedundantError> {
    Err(port_error(
        0,
        a,
        "this build has no UDP ports: enable the `udp` feature of duocan-redundancy",
    ))
}

#[cfg(all(feature = "socketcan", target_os = "linux"))]
fn socketcan(a: &str, b: &str, opts: NetOptions) -> Result<Network, RedundantError> {
    use duocan::port::socketcan::SocketCanPort;
    let open =
        |port: u8, name: &str| SocketCanPort::open(name).map_err(|e| port_error(port, name, e));
    open_dual(open(0, a)?, open(1, b)?, opts)
}

#[cfg(not(all(feature = "socketcan", target_os = "linux")))]
fn socketcan(a: &str, _: &str, _: NetOptions) -> Result<Network, RedundantError> {
    Err(port_error(
        0,
        a,
        "this build has no SocketCAN: use \"sim-station\", or enable the `socketcan` feature of duocan-redundancy (Linux)",
    ))
}
