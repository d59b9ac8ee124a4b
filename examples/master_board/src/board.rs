//! The redundant master as the firmware runs it: the station (dual-bus layer, CiA 302-2
//! master, supervisor), built with capacities sized to the board's network, and the
//! [`MasterBoard`] that drives it over two `embedded-can` controllers.

use crate::dictionary::{self, Od};
use crate::{Computer, PAIRS};
use core::fmt;
use duocan::master::{Master, MasterConfig, MasterError, MasterSdoClient};
use duocan::node::NodeConfig;
use duocan::od::{BuildError, ObjectDictionary};
use duocan::port::embedded::{EmbeddedDriver, EmbeddedPortStats};
use duocan::profile::Predefined;
use duocan::sdo::DEFAULT_LIMIT;
use duocan::{Duration, Instant, NodeId};
use duocan_redundancy_core::link::same_function::PairError;
use duocan_redundancy_core::supervisor::flying_master::MasterRole;
use duocan_redundancy_core::{
    AddPairError, Capacity, DualBus, DualBusConfig, LinkMode, PairSpec, PortState, SupervisedLink,
    SupervisedStation, Supervisor, SupervisorConfig,
};
use embedded_can::nb::Can;

/// Merger slots of the dual-bus layer: while both buses work the merger holds a frame until its
/// twin arrives, within the skew window (5 ms); the network carries a few per window (eight
/// heartbeats every 50 ms, SYNC every 20 ms, the pair boards' PDOs), far below the 48 records
/// the slots take. With a bus dead, records wait for the horizon and the oldest are evicted
/// first (counted): harmless, their twins never come.
pub const MERGE_SLOTS: usize = 64;
/// (pair, function) values the same-function merge compares: four TPDOs per pair.
pub const FUNCTIONS: usize = 16;
/// The dual-bus layer of the board: the predefined connection set, [`MERGE_SLOTS`] merger slots
/// and room for [`FUNCTIONS`] same-function values.
pub type Link = DualBus<Predefined, Capacity<MERGE_SLOTS, FUNCTIONS>>;
/// The station the firmware runs: the supervisor and its master on the dual-bus layer. The
/// master's dictionary is lent to it ([`Od`] kept by the caller: in the firmware a local of
/// `main`): built where it lives, it never travels through the constructors.
pub type Station = SupervisedStation<&'static mut Od, Link>;
/// The CAN controllers of the dual bus.
pub const PORTS: usize = 2;

/// This master's heartbeat.
pub const HEARTBEAT: Duration = Duration::from_millis(50);
/// Silence of the active master after which the standby takes over.
pub const MASTER_TIMEOUT: Duration = Duration::from_millis(150);
/// The interlocking cycle: SYNC while active.
pub const SYNC_PERIOD: Duration = Duration::from_millis(20);
/// The heartbeat configured into every pair member.
pub const PAIR_HEARTBEAT: Duration = Duration::from_millis(50);
/// Silence of a pair member after which it has failed.
pub const PAIR_TIMEOUT: Duration = Duration::from_millis(150);

/// The master's own settings, sized for the board: slots for the pair members only (the
/// library's default keeps one for each of the 127 node-IDs, 31 KB), queues for a handful of
/// slaves rather than a station's (the library's defaults hold a thousand events), no PDOs of
/// its own, two SDO sessions (the members boot two at a time; the rest wait their turn).
pub fn network_config() -> MasterConfig {
    MasterConfig::new()
        .max_slaves(2 * PAIRS.len())
        .event_queue(32)
        .nmt_queue(16)
        .with_tpdos(0)
        .with_rpdos(0)
        .with_sdo_sessions(2)
}

/// The supervisor's settings for `computer`: the other computer is its peer, tables and
/// queues sized to [`PAIRS`].
pub fn supervisor_config(computer: Computer) -> SupervisorConfig {
    let other = computer.other();
    SupervisorConfig::new(0, computer.node(), HEARTBEAT, MASTER_TIMEOUT, SYNC_PERIOD)
        .with_peer(0, other.node())
        .with_event_queue(32)
        .with_pair_capacity(PAIRS.len())
        .with_pair_queue(16)
        .with_audit_capacity(32)
}

/// The dual-bus layer's settings: active-active, port silence judged on the heartbeat period,
/// the heartbeats of the pair members (and only theirs: the supervisor watches no one else)
/// judged for plausibility.
pub fn link_config() -> DualBusConfig {
    DualBusConfig::with_guard_period(LinkMode::ActiveActive, HEARTBEAT.min(PAIR_HEARTBEAT))
        .with_watch_capacity(2 * PAIRS.len())
}

/// Why the station could not be built (a table that does not fit the board's sizes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoardError {
    /// The dictionary tables do not fit [`Od`].
    Dictionary(BuildError),
    /// The master refused its dictionary or settings.
    Master(MasterError),
    /// The supervisor refused a pair.
    Pair(AddPairError),
    /// The dual-bus layer refused a pair.
    Link(PairError),
}

impl fmt::Display for BoardError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BoardError::Dictionary(e) => {
                write!(f, "master dictionary: {e:?}: raise OD_ENTRIES or OD_BYTES")
            }
            BoardError::Master(e) => write!(f, "master: {e}"),
            BoardError::Pair(e) => write!(f, "pair table: {e}"),
            BoardError::Link(e) => write!(f, "dual-bus layer: {e}"),
        }
    }
}

impl core::error::Error for BoardError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            BoardError::Dictionary(e) => Some(e),
            BoardError::Master(e) => Some(e),
            BoardError::Pair(e) => Some(e),
            BoardError::Link(e) => Some(e),
        }
    }
}

/// Builds the station of `computer` on the empty dictionary `od` and boots its master at
/// `now`: the dictionary's tables loaded, the master, the supervisor with [`PAIRS`] and the
/// other computer as peer, the dual-bus layer. Everything it allocates is allocated here, once
/// (the master's queues, SDO sessions and slave table; the supervisor's pair table, audit
/// trail and event queue). [`unstarted`] and [`start`] in one, the station returned by value:
/// for a host; the firmware builds it where it lives with those two.
pub fn build(computer: Computer, od: &'static mut Od, now: Instant) -> Result<Station, BoardError> {
    let mut station = unstarted(computer, od)?;
    start(&mut station, now)?;
    Ok(station)
}

/// The station of `computer` on the empty dictionary `od`, built and not started: the
/// dictionary's tables loaded, the master (its network configuration not yet written), the
/// supervisor and the dual-bus layer; nothing booted, no pair added. [`start`] it at once.
///
/// The values built here are tens of kilobytes, each move of one a copy on the stack. So the
/// dictionary is lent, not moved; this function is not inlined and its result is written by
/// the caller's call straight where the caller keeps it (a local of a function that never
/// returns, such as the firmware's `main`: a `static` the compiler fills through a copy on
/// the stack); and the parts are built by constructors that are not inlined either, each
/// straight into its place ([`SupervisedStation::unlinked`], [`Supervisor::unstarted`],
/// [`Master::unconfigured`]: [`Master::new`] would return the master in a `Result`, a copy of
/// 11 kB, so its fallible part, [`Master::configure`], waits for [`start`]).
#[inline(never)]
pub fn unstarted(computer: Computer, od: &'static mut Od) -> Result<Station, BoardError> {
    dictionary::load(od, computer.node().raw()).map_err(BoardError::Dictionary)?;
    Ok(SupervisedStation::unlinked(new_link, || {
        new_supervisor(computer, od)
    }))
}

/// Starts the station [`unstarted`] built at `now`: writes the master's network
/// configuration, boots it, adds [`PAIRS`] to the supervisor and configures them in the
/// dual-bus layer.
pub fn start(station: &mut Station, now: Instant) -> Result<(), BoardError> {
    let sup = station.sup_mut();
    sup.configure_master(network_config())
        .map_err(BoardError::Master)?;
    sup.start(now);
    for (a, b) in PAIRS {
        let spec = PairSpec::new(a, b, PAIR_HEARTBEAT, PAIR_TIMEOUT);
        sup.add_pair(now, spec).map_err(BoardError::Pair)?;
    }
    station.link_pairs().map_err(BoardError::Link)
}

/// The master, not configured yet ([`start`] does that), built where the caller wants it
/// (not inlined: see [`unstarted`]).
#[inline(never)]
fn new_master(computer: Computer, od: &'static mut Od) -> Master<&'static mut Od> {
    let config = network_config();
    let sdo = MasterSdoClient::with_sessions(DEFAULT_LIMIT, config.sdo_sessions);
    let node = NodeConfig::master(computer.node());
    Master::unconfigured(node, od, Predefined, sdo, &config)
}

/// The dual-bus layer, built where the caller wants it (not inlined: see [`unstarted`]).
#[inline(never)]
fn new_link() -> Link {
    DualBus::with_classifier(link_config(), Predefined)
}

/// The supervisor on `master`, not started, built where the caller wants it (not inlined:
/// see [`unstarted`]).
#[inline(never)]
fn new_supervisor(computer: Computer, od: &'static mut Od) -> Supervisor<&'static mut Od> {
    Supervisor::unstarted(|| new_master(computer, od), supervisor_config(computer))
}

/// What the board shows on its front panel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Indication {
    /// This computer is the active master (it commands the network).
    pub active: bool,
    /// Bus 1, bus 2 carry traffic (port health ok).
    pub bus_ok: [bool; PORTS],
    /// Pairs with a running (active) member.
    pub pairs_running: u8,
}

/// What the panel shows for `station` now.
pub fn indication<D: ObjectDictionary, L: SupervisedLink>(
    station: &SupervisedStation<D, L>,
) -> Indication {
    let sup = station.sup();
    Indication {
        active: sup.flying_master().role() == MasterRole::Active,
        bus_ok: core::array::from_fn(|p| station.link.dual_bus().port(p).state() == PortState::Ok),
        pairs_running: sup.pairs().filter(|(_, p)| p.active.is_some()).count() as u8,
    }
}

/// The board: the station on its two CAN controllers ([`EmbeddedDriver`]), and the count of
/// events the application drained (they are also in the supervisor's audit trail). The
/// station is borrowed for good: on the board it lives in the frame of `main`, which never
/// returns, built there by [`unstarted`], so that its tens of kilobytes never pass through the
/// stack again.
pub struct MasterBoard<C: Can> {
    driver: EmbeddedDriver<&'static mut Station, C, PORTS>,
    events: u32,
}

impl<C: Can> MasterBoard<C> {
    /// The board running `station` on `cans` = [bus 1, bus 2].
    pub fn new(station: &'static mut Station, cans: [C; PORTS]) -> Self {
        MasterBoard {
            driver: EmbeddedDriver::new(station, cans),
            events: 0,
        }
    }

    /// One pass of the main loop: everything due at `now`. Returns when to call again at the
    /// latest (call it also when a controller has received a frame or freed a mailbox).
    pub fn poll(&mut self, now: Instant) -> Option<Instant> {
        let next = self.driver.poll(now);
        while self.driver.poll_event().is_some() {
            self.events = self.events.wrapping_add(1);
        }
        next
    }

    /// What the front panel shows.
    pub fn indication(&self) -> Indication {
        indication(self.driver.device())
    }
    /// The station (supervisor, master, dual-bus layer).
    pub fn station(&self) -> &Station {
        self.driver.device()
    }
    /// Events drained so far.
    pub fn events(&self) -> u32 {
        self.events
    }
    /// Counters of controller `port` (0: bus 1, 1: bus 2).
    pub fn bus_stats(&self, port: usize) -> Option<EmbeddedPortStats> {
        self.driver.stats(port)
    }
    /// Controller `port`, to restart it.
    pub fn bus_mut(&mut self, port: usize) -> Option<&mut C> {
        self.driver.port_mut(port)
    }
}

/// The node-ID of `n` (the pair table's constants are valid node-IDs).
pub(crate) const fn node(n: u8) -> NodeId {
    NodeId::must(n)
}
