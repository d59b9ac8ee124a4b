//! The simulated redundant station behind [`open_dual_named`](super::open_dual_named)`("sim-station")`,
//! what a commissioning tool's `--bus sim-station` talks to (what it holds and the fault script of
//! `"sim-station:faults"` are tabled in the [`net`](super) module's docs).
//!
//! Its devices are members of one [`Backplane`](backplane): two buses, `sim-bus1` and
//! `sim-bus2`, each carrying its frames in turn at [`SIM_BIT_RATE`], every device on both
//! through its own dual-bus layer. The backplane is the network's link ([`link`]): the network
//! opened on the station runs it in its own task, under its own lock, with its own dual-bus
//! layer on both buses and its port to bus 1 one that the script can cut. Nothing between two
//! devices is carried by a task of its own, so the two copies of a frame cannot drift apart on
//! a loaded machine, and, time being the network's clock, under tokio's paused clock every run
//! is the same. The station runs until the network is closed.

use super::dual_link::DualLink;
mod backplane;
mod link;
#[cfg(test)]
mod tests;

use super::sim_pairs::{board, Board};
use super::Net;
use crate::link::config::DualBusConfig;
use crate::link::dual_bus::DualBus;
use crate::logical::{NetProfile, RedundantError, RedundantNetworkBuilder};
use alloc::boxed::Box;
use alloc::string::ToString;
use backplane::Backplane;
use duocan::cia302::program::{ProgramDictionary, RamStore};
use duocan::cia305::{LssAddress, LssSlave, NoMedium};
use duocan::net::{sim_dictionary, NetOptions, Network, SIM_VENDOR};
use duocan::node::LssNode;
use duocan::od::{comm, Access, DataType, DynamicDictionary, ObjectDef, ObjectDictionary};
use duocan::profile::Predefined;
use duocan::sdo::SdoServerConfig;
use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
use link::{Script, SimLink, StationPort};

/// The bit rate of the station's buses: frames go no faster than on a 1 Mbit/s CAN bus, each
/// taking its exact wire time, so a long transfer takes the time it would on one.
pub const SIM_BIT_RATE: u32 = 1_000_000;
/// The station's A/B board pairs (A, B).
pub const SIM_PAIRS: [(u8, u8); 2] = [(0x10, 0x50), (0x11, 0x51)];
/// The station's plain slaves.
pub const SIM_SLAVES: [u8; 3] = [0x05, 0x06, 0x07];
/// The plain slaves' read-write DOMAIN object (sub 0).
pub const SIM_DOMAIN: u16 = 0x2002;
/// The largest value the plain slaves' DOMAIN, SDO servers and program store take: 1 MiB.
pub const SIM_DOMAIN_SIZE: usize = 1 << 20;
/// The plain slave that takes program download.
pub const SIM_PROGRAM_NODE: u8 = 0x05;
/// The product code of the station's boards that arrive without a node-ID (LSS, CiA 305).
pub const SIM_LSS_PRODUCT: u32 = 0x0305;
/// Their revision number.
pub const SIM_LSS_REVISION: u32 = 1;
/// Their serial numbers: one board each, non-configured (node-ID 0xFF) until an LSS master
/// gives it a node-ID; then it boots as the simulated node with that node-ID.
pub const SIM_LSS_SERIALS: [u32; 2] = [0x0001, 0x0002];
/// The period of the `"sim-station:faults"` script.
pub const SIM_FAULT_PERIOD: Duration = Duration::from_millis(10_000);
/// Into each period: the network's connection to bus 1 is cut.
pub const SIM_FAULT_BUS_CUT: Duration = Duration::from_millis(2_000);
/// Into each period: bus 1 is connected again.
pub const SIM_FAULT_BUS_BACK: Duration = Duration::from_millis(4_000);
/// Into each period: the active member of the first pair stops.
pub const SIM_FAULT_MEMBER_STOPS: Duration = Duration::from_millis(5_000);
/// Into each period: that member is powered again.
pub const SIM_FAULT_MEMBER_BACK: Duration = Duration::from_millis(7_000);
/// Into each period: the active master stops.
pub const SIM_FAULT_MASTER_STOPS: Duration = Duration::from_millis(8_000);
/// Into each period: that master is powered again.
pub const SIM_FAULT_MASTER_BACK: Duration = Duration::from_millis(9_000);

/// When the B members are powered: after the masters have settled which one is active and the
/// active one has configured and started the A members (a master taking the active role
/// resets the network, and a member that boots in that reset could be configured first), so
/// that A is the active member of every pair, every run.
const B_POWERED: Duration = Duration::from_millis(1_000);

/// Whether the station runs a fault script.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum StationScript {
    /// No faults: it runs until the network closes.
    Quiet,
    /// The fault script, repeating.
    Faults,
}

type Slave<D> = Station<DualBus<Predefined>, Node<D>>;
/// What builds an LSS board's node once it has a node-ID ([`sim_lss_board`]).
pub type SimLssBuild = Box<dyn FnMut(NodeId, Instant) -> Node<DynamicDictionary> + Send>;
/// A board of the station's that arrives without a node-ID ([`sim_lss_board`]).
pub type SimLssBoard = LssNode<Node<DynamicDictionary>, SimLssBuild, NoMedium>;
/// A board without a node-ID on its dual-bus layer: LSS only until it has one.
type LssBoard = Station<DualBus, SimLssBoard>;

/// A plain slave's dictionary: the simulated node's, with the DOMAIN.
fn slave_dictionary(id: NodeId) -> DynamicDictionary {
    let mut od = sim_dictionary(id);
    od.upsert(
        ObjectDef::bytes(SIM_DOMAIN, 0, DataType::Domain, SIM_DOMAIN_SIZE as u32)
            .access(Access::Rw)
            .named("Domain"),
    );
    od
}

/// A plain slave on its own dual-bus layer, taking values up to [`SIM_DOMAIN_SIZE`], booted.
// Not inlined, nor the other builders below: a device is some 100 kB, built on the stack and
// moved to the heap here, so that no caller's frame holds one (a debug build's frame keeps a
// slot per call site, and the test threads' stacks are 2 MiB).
#[inline(never)]
fn slave<D: ObjectDictionary>(id: NodeId, od: D) -> Box<Slave<D>> {
    let mut node = Node::new(NodeConfig::slave(id), od);
    node.sdo_server_mut()
        .set_config(SdoServerConfig::default().with_max_transfer(SIM_DOMAIN_SIZE));
    node.boot(Instant::ZERO);
    Box::new(Station::new(
        DualBus::with_classifier(DualBusConfig::default(), Predefined),
        node,
    ))
}

/// The LSS address of the station's non-configured board with `serial`.
#[must_use]
pub fn sim_lss_address(serial: u32) -> LssAddress {
    LssAddress {
        vendor: SIM_VENDOR,
        product: SIM_LSS_PRODUCT,
        revision: SIM_LSS_REVISION,
        serial,
    }
}

/// The station's board with `serial` that arrives without a node-ID (identity
/// [`sim_lss_address`]), for a rig of one's own: silent but for LSS until an LSS master gives
/// it a node-ID, then the simulated node with it (the board's identity in 0x1018), booted.
#[must_use]
pub fn sim_lss_board(serial: u32) -> SimLssBoard {
    let address = sim_lss_address(serial);
    let build: SimLssBuild = Box::new(move |id, now| {
        let mut od = sim_dictionary(id);
        let device_type = od.get_u32(comm::DEVICE_TYPE, 0).unwrap_or(0);
        let a = address;
        for def in comm::identity(device_type, a.vendor, a.product, a.revision, a.serial) {
            od.upsert(def);
        }
        let mut node = Node::new(NodeConfig::slave(id), od);
        node.boot(now);
        node
    });
    let lss = LssSlave::new(address, duocan::cia305::codec::UNCONFIGURED);
    LssNode::new(Instant::ZERO, lss, build)
}

/// [`sim_lss_board`] on its own dual-bus layer.
#[inline(never)]
fn lss_board(serial: u32) -> Box<LssBoard> {
    Box::new(Station::new(
        DualBus::new(DualBusConfig::default()),
        sim_lss_board(serial),
    ))
}

#[inline(never)]
fn new_board(id: u8) -> Box<Board> {
    Box::new(board(NodeId::must(id), &NetProfile::predefined(), false))
}

/// The masters' settings: 0x01 with its peer 0x02 and the pairs.
fn masters() -> RedundantNetworkBuilder {
    let mut b = RedundantNetworkBuilder::default().node_id(1).peer_master(2);
    for (a, bb) in SIM_PAIRS {
        b = b.pair(a, bb);
    }
    b
}

fn master(id: u8) -> Result<Box<Net>, RedundantError> {
    let b = masters();
    if id == b.this_node() {
        b.build_profiled()
    } else {
        b.as_peer(id).build_profiled()
    }
}

fn sim_error(why: impl ToString) -> RedundantError {
    RedundantError::Port {
        port: 0,
        name: "sim-station".into(),
        why: why.to_string(),
    }
}

/// Stack for building the station: some thirty devices with a dual-bus layer each (about a
/// hundred kilobytes), each built and then boxed, which in a debug build passes through more
/// stack than a thread of the caller's may have (tokio's workers have 2 MiB).
const BUILD_STACK: usize = 16 << 20;

/// Opens a network on a new simulated station (see the module docs).
pub(super) fn open(opts: NetOptions, script: StationScript) -> Result<Network, RedundantError> {
    let ports = [StationPort::new("sim-bus1"), StationPort::new("sim-bus2")];
    let tap = opts.tap.clone();
    let link = std::thread::scope(|scope| {
        std::thread::Builder::new()
            .name("duocan-sim-build".into())
            .stack_size(BUILD_STACK)
            .spawn_scoped(scope, || build(script, &ports, tap))
            .map_err(sim_error)?
            .join()
            .map_err(|_| sim_error("building the simulated station failed"))?
    })?;
    let [bus1, bus2] = ports;
    Network::open_link(link, (bus1, bus2), opts).map_err(sim_error)
}

/// The station's devices on their backplane, and the network's link to it.
fn build(
    script: StationScript,
    ports: &[StationPort; 2],
    tap: Option<std::sync::Arc<dyn duocan::capture::recorder::Tap>>,
) -> Result<Box<SimLink>, RedundantError> {
    let mut station = Backplane::new(SIM_BIT_RATE);
    for id in [1, 2] {
        station.power_on(id, master(id)?);
    }
    for (a, _) in SIM_PAIRS {
        station.power_on(a, new_board(a));
    }
    for id in SIM_SLAVES.into_iter().filter(|id| *id != SIM_PROGRAM_NODE) {
        let node = NodeId::must(id);
        station.power_on(id, slave(node, slave_dictionary(node)));
    }
    let node = NodeId::must(SIM_PROGRAM_NODE);
    let od = ProgramDictionary::new(
        slave_dictionary(node),
        RamStore::new(SIM_DOMAIN_SIZE as u32),
    );
    station.power_on(SIM_PROGRAM_NODE, slave(node, od));
    for serial in SIM_LSS_SERIALS {
        station.power_on(NO_NODE_ID, lss_board(serial));
    }
    let script = Script::new(script == StationScript::Faults);
    Ok(Box::new(SimLink::new(
        DualLink::default(),
        station,
        script,
        ports,
        tap,
    )))
}

/// The tag on the backplane of the boards that arrive without a node-ID.
const NO_NODE_ID: u8 = 0;

/// The active member of the first pair, as the active master has it.
fn active_member(station: &mut Backplane) -> Option<u8> {
    let master = *station.find::<Net>(|n| n.role().is_active()).first()?;
    station
        .with::<Net, _>(master, |n| {
            n.pairs()
                .next()
                .and_then(|(_, p)| p.active.map(|m| p.spec.node(m).raw()))
        })
        .flatten()
}
