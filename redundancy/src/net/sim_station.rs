//! The simulated redundant station behind [`open_dual_named`](super::open_dual_named)`("sim")`,
//! what a commissioning tool's `--bus sim` talks to (what it holds and the fault script of
//! `"sim:faults"` are tabled in the [`net`](super) module's docs). Two in-memory buses,
//! `sim-bus1` and `sim-bus2`, paced at [`SIM_BIT_RATE`]; every device is on both through its own dual-bus layer, and the
//! network opened on the station attaches to both through [`DualLink`], its port to bus 1 one
//! that the script can cut. The station runs until the network is closed; under tokio's paused
//! clock every run is the same.

use super::dual_link::DualLink;
use super::sim::{board, spawn, until, Board};
use super::Net;
use crate::link::config::DualBusConfig;
use crate::link::dual_bus::DualBus;
use crate::network::{RedundantError, RedundantNetworkBuilder};
use alloc::boxed::Box;
use alloc::string::ToString;
use alloc::vec::Vec;
use duocan::cia302::program::{FlashError, ProgramDictionary, ProgramStore};
use duocan::cia305::{LssAddress, LssSlave, NoMedium};
use duocan::net::{sim_dictionary, NetOptions, Network, SIM_VENDOR};
use duocan::node::LssNode;
use duocan::od::{comm, Access, DataType, DynamicDictionary, ObjectDef, ObjectDictionary};
use duocan::port::mem::{Connector, MemBus};
use duocan::profile::Predefined;
use duocan::runtime::Handle;
use duocan::sdo::SdoServerConfig;
use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
use tokio::sync::watch;

/// The bit rate of the station's buses: frames go no faster than on a 1 Mbit/s CAN bus, so a
/// long transfer takes the time it would on one and the devices' receivers keep up with it.
pub const SIM_BIT_RATE: u32 = 1_000_000;
/// The merger slots of the network's link and of the plain slaves: 3,072 frames waiting for
/// their twins, 400 ms of a block transfer at the buses' rate, where the default's 768 hold
/// 100 ms (a block transfer on a loaded machine saw one bus's task 150 ms behind the other's).
pub const SIM_MERGE_SLOTS: usize = 4096;
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
/// The period of the `"sim:faults"` script.
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

/// The software identification the simulated program store reports for `image` once it runs
/// (0x1F56 sub 1): its 32-bit FNV-1a hash, so that a different image reads differently.
#[must_use]
pub fn sim_program_id(image: &[u8]) -> u32 {
    image.iter().fold(0x811C_9DC5, |h: u32, b| {
        (h ^ u32::from(*b)).wrapping_mul(0x0100_0193)
    })
}

/// Whether the station runs a fault script.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum StationScript {
    /// No faults: it runs until the network closes.
    Quiet,
    /// The fault script, repeating.
    Faults,
}

/// A program store in RAM: it keeps the identification of what it staged, not the image.
#[derive(Debug, Default)]
struct RamStore {
    running: u32,
    staged: Option<u32>,
}

impl ProgramStore for RamStore {
    fn capacity(&self) -> u32 {
        SIM_DOMAIN_SIZE as u32
    }
    fn stop(&mut self) {}
    fn run(&mut self) {}
    fn clear(&mut self) -> Result<(), FlashError> {
        self.staged = None;
        Ok(())
    }
    fn stage(&mut self, image: &[u8]) -> Result<(), FlashError> {
        self.staged = Some(sim_program_id(image));
        Ok(())
    }
    fn activate(&mut self) -> Result<(), FlashError> {
        self.running = self.staged.take().ok_or(FlashError::NoValidProgram)?;
        Ok(())
    }
    fn identification(&self) -> u32 {
        self.running
    }
}

type Slave<D> = Station<DualBus<Predefined, SIM_MERGE_SLOTS>, Node<D>>;
/// What builds an LSS board's node once it has a node-ID.
type Build = Box<dyn FnMut(NodeId, Instant) -> Node<DynamicDictionary> + Send>;
/// A board without a node-ID: LSS only until it has one.
type LssBoard = Station<DualBus, LssNode<Node<DynamicDictionary>, Build, NoMedium>>;
type Flasher = Slave<ProgramDictionary<DynamicDictionary, RamStore>>;

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

/// The dual-bus layer of every device of the station and of the network attached to it.
///
/// The station's two buses are in-memory channels, each frame's two copies carried by tasks
/// that share the machine's CPU with the tool and everything else running: under load the
/// copies arrive a hundred milliseconds apart and more (seen on a loaded two-core machine),
/// where two controllers on real buses see them microseconds apart. A twin later than the
/// merger's window is a new frame by the merger's rule, and to an SDO transfer a repeated
/// segment. The window is therefore wide here (250 ms, following a lagging bus up to 1 s): the
/// station is for trying things, and its failovers are timed by heartbeats, not by the window.
/// A wide window needs room for what it waits for: the devices that carry long transfers (the
/// network's link and the plain slaves) have [`SIM_MERGE_SLOTS`].
fn sim_link() -> DualBusConfig {
    DualBusConfig::default()
        .with_skew_window(Duration::from_millis(250))
        .with_max_skew_window(Duration::from_millis(1000))
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
        DualBus::with_classifier(sim_link(), Predefined),
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

/// A board with `serial` that arrives without a node-ID: its node (the simulated node, with
/// the board's identity in 0x1018) is built and boots when an LSS master gives it one.
#[inline(never)]
fn lss_board(serial: u32) -> Box<LssBoard> {
    let address = sim_lss_address(serial);
    let build: Build = Box::new(move |id, now| {
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
    Box::new(Station::new(
        DualBus::new(sim_link()),
        LssNode::new(Instant::ZERO, lss, build),
    ))
}

#[inline(never)]
fn new_board(id: u8) -> Box<Board> {
    let mut b = board(NodeId::must(id));
    b.link = DualBus::new(sim_link());
    Box::new(b)
}

#[inline(never)]
fn new_link() -> Box<DualLink<SIM_MERGE_SLOTS>> {
    Box::new(DualLink::with_slots(sim_link()))
}

/// The masters' settings: 0x01 with its peer 0x02 and the pairs.
fn masters() -> RedundantNetworkBuilder {
    let mut b = RedundantNetworkBuilder::default()
        .node_id(1)
        .peer_master(2)
        .link(sim_link());
    for (a, bb) in SIM_PAIRS {
        b = b.pair(a, bb);
    }
    b
}

fn master(id: u8) -> Result<Box<Net>, RedundantError> {
    let b = masters();
    if id == b.this_node() {
        b.build_boxed()
    } else {
        b.as_peer(id).build_boxed()
    }
}

fn sim_error(why: impl ToString) -> RedundantError {
    RedundantError::Port {
        port: 0,
        name: "sim".into(),
        why: why.to_string(),
    }
}

/// Opens a network on a new simulated station (see the module docs).
pub(super) fn open(opts: NetOptions, script: StationScript) -> Result<Network, RedundantError> {
    if tokio::runtime::Handle::try_current().is_err() {
        return Err(sim_error(
            "no tokio runtime: open the network from inside one (#[tokio::main])",
        ));
    }
    let buses = [
        MemBus::with_bit_rate("sim-bus1", SIM_BIT_RATE),
        MemBus::with_bit_rate("sim-bus2", SIM_BIT_RATE),
    ];
    // The network's ports first: a port hears only what is sent after it exists.
    let (port1, cut) = buses[0].plugged_port();
    let ports = (port1, buses[1].port());
    let net = Network::open_link(new_link(), ports, opts).map_err(sim_error)?;
    let mut masters = Vec::new();
    for id in [1, 2] {
        let h = spawn(master(id)?, &alloc::format!("sim master {id}"), &buses)?;
        masters.push((id, Some(h)));
    }
    let mut boards = Vec::new();
    for (a, _) in SIM_PAIRS {
        boards.push((a, Some(spawn(new_board(a), "sim board", &buses)?)));
    }
    let mut slaves = Vec::new();
    for id in SIM_SLAVES.into_iter().filter(|id| *id != SIM_PROGRAM_NODE) {
        let id = NodeId::must(id);
        slaves.push(spawn(slave(id, slave_dictionary(id)), "sim slave", &buses)?);
    }
    let id = NodeId::must(SIM_PROGRAM_NODE);
    let od = ProgramDictionary::new(slave_dictionary(id), RamStore::default());
    let flasher = spawn(slave(id, od), "sim slave", &buses)?;
    let mut lss = Vec::new();
    for serial in SIM_LSS_SERIALS {
        lss.push(spawn(lss_board(serial), "sim LSS board", &buses)?);
    }
    let (stop, stop_rx) = watch::channel(false);
    let station = Sim {
        buses,
        cut,
        masters,
        boards,
        slaves,
        flasher,
        lss,
        stop: stop_rx,
        start: tokio::time::Instant::now(),
    };
    let task = tokio::spawn(station.run(script));
    net.on_close(move || async move {
        stop.send_replace(true);
        let _ = task.await;
    });
    Ok(net)
}

/// Devices by node-ID; `None`: powered off by the script.
type Devices<D> = Vec<(u8, Option<Handle<D>>)>;

/// Stops device `id` of `devices`, if it runs.
async fn power_off<D>(devices: &mut Devices<D>, id: Option<u8>)
where
    D: duocan::Device + Send + 'static,
    D::Event: Clone + Send + 'static,
{
    let found = devices.iter_mut().find(|(d, _)| Some(*d) == id);
    if let Some(h) = found.and_then(|(_, h)| h.take()) {
        h.shutdown().await;
    }
}

/// Starts every device of `devices` that is off, anew (it boots).
fn power_on<D>(devices: &mut Devices<D>, start: impl Fn(u8) -> Result<Handle<D>, RedundantError>)
where
    D: duocan::Device + Send + 'static,
    D::Event: Clone + Send + 'static,
{
    for (id, h) in devices.iter_mut().filter(|(_, h)| h.is_none()) {
        *h = start(*id).ok();
    }
}

/// The station's devices and its script.
struct Sim {
    buses: [MemBus; 2],
    cut: Connector,
    masters: Devices<Net>,
    boards: Devices<Board>,
    slaves: Vec<Handle<Slave<DynamicDictionary>>>,
    flasher: Handle<Flasher>,
    lss: Vec<Handle<LssBoard>>,
    stop: watch::Receiver<bool>,
    start: tokio::time::Instant,
}

impl Sim {
    /// Waits until `t` after the start; false if asked to stop first.
    async fn until(&mut self, t: Duration) -> bool {
        until(self.start, t, &mut self.stop).await
    }

    async fn run(mut self, script: StationScript) {
        if self.until(B_POWERED).await {
            // B boots later than A, so that A is configured first and is the active member.
            for (_, b) in SIM_PAIRS {
                if let Ok(h) = spawn(new_board(b), "sim board", &self.buses) {
                    self.boards.push((b, Some(h)));
                }
            }
            match script {
                StationScript::Quiet => {
                    let _ = self.stop.wait_for(|s| *s).await;
                }
                StationScript::Faults => {
                    let mut base = Duration::ZERO;
                    while self.faults(base).await {
                        base = base + SIM_FAULT_PERIOD;
                    }
                }
            }
        }
        for (_, h) in self
            .masters
            .iter()
            .filter_map(|(i, h)| Some((i, h.as_ref()?)))
        {
            h.shutdown().await;
        }
        for (_, h) in self
            .boards
            .iter()
            .filter_map(|(i, h)| Some((i, h.as_ref()?)))
        {
            h.shutdown().await;
        }
        for h in &self.slaves {
            h.shutdown().await;
        }
        self.flasher.shutdown().await;
        for h in &self.lss {
            h.shutdown().await;
        }
    }

    /// One period of the fault script from `base`; false if asked to stop.
    async fn faults(&mut self, base: Duration) -> bool {
        if !self.until(base + SIM_FAULT_BUS_CUT).await {
            return false;
        }
        self.cut.pull();
        if !self.until(base + SIM_FAULT_BUS_BACK).await {
            return false;
        }
        self.cut.plug_in();
        if !self.until(base + SIM_FAULT_MEMBER_STOPS).await {
            return false;
        }
        let member = self.active_member().await;
        power_off(&mut self.boards, member).await;
        if !self.until(base + SIM_FAULT_MEMBER_BACK).await {
            return false;
        }
        let buses = self.buses.clone();
        power_on(&mut self.boards, |id| {
            spawn(new_board(id), "sim board", &buses)
        });
        if !self.until(base + SIM_FAULT_MASTER_STOPS).await {
            return false;
        }
        let active = self.active_master().await;
        power_off(&mut self.masters, active).await;
        if !self.until(base + SIM_FAULT_MASTER_BACK).await {
            return false;
        }
        power_on(&mut self.masters, |id| {
            spawn(master(id)?, &alloc::format!("sim master {id}"), &buses)
        });
        true
    }

    /// The running master that is active.
    async fn active_master(&self) -> Option<u8> {
        for (id, h) in &self.masters {
            if let Some(h) = h {
                if h.call(|n, _| n.role().is_active()).await.unwrap_or(false) {
                    return Some(*id);
                }
            }
        }
        None
    }

    /// The active member of the first pair, as the active master has it.
    async fn active_member(&self) -> Option<u8> {
        let m = self.active_master().await?;
        let (_, h) = self.masters.iter().find(|(id, _)| *id == m)?;
        h.as_ref()?
            .call(|n, _| {
                n.pairs()
                    .next()
                    .and_then(|(_, p)| p.active.map(|m| p.spec.node(m).raw()))
            })
            .await
            .ok()
            .flatten()
    }
}
