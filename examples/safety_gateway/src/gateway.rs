//! The gateway: a railway board on the interlocking's dual bus that mirrors the track circuits
//! of a field bus.
//!
//! ```text
//!   field bus (CAN 3)                     interlocking network, bus 1 (CAN 1) + bus 2 (CAN 2)
//!   track-circuit board ──SRDO 0x101/0x102─▶ [mirrors] ──TPDO 1..4──▶ DualBus ══▶ interlocking
//!     0x55/0xAA + inverse, SCT, SRVT  checked,   │                        ▲
//!                             safe side on doubt ├── 0x6000 sub k ── SDO ─┘  heartbeat, NMT
//!                                                └── SRDO 1 (0x6000 + inverse 0x6001) ──▶
//! ```
//!
//! The interlocking side is the standard stack, unchanged: a [`Node`] with a static dictionary
//! over the railway 29-bit profile, on a [`DualBus`] in active-active mode, driven by duocan's
//! [`EmbeddedDriver`]. The field side is a third controller the gateway reads itself.

use crate::dictionary::{
    self, Od, FIELD_TIMEOUT, IMAGE, IMAGE_LEN, TRACK_STATES, TRACK_STATES_INVERTED,
};
use crate::mirror::{self, Changes, TrackChange, Tracks, Verdict};
use crate::{ADDRESS, FIELD_SRVT, MERGE_SLOTS, NODE_ID, TRACKS};
use core::fmt;
use duocan::cia304::srdo::consumer::SrdoFault;
use duocan::frame::instant::earliest;
use duocan::machine::StationEvent;
use duocan::node::{NodeEventKind, StateCause};
use duocan::od::{BuildError, ObjectDictionary};
use duocan::port::embedded::{status_of, EmbeddedDriver, EmbeddedPortStats, RX_BURST};
use duocan::profile::railway::safety::{FieldState, SafetyCode, TrackCircuit};
use duocan::profile::railway::{DeviceAddress, RailwayProfile};
use duocan::{
    CobId, Duration, Frame, Instant, NmtState, Node, NodeConfig, NodeEvent, NodeId, Station,
};
use duocan_redundancy_core::{Capacity, DualBus, DualBusConfig, LinkEvent, LinkMode};
use embedded_can::nb::Can;
use embedded_can::Error as _;
use heapless::Deque;
use static_cell::{ConstStaticCell, StaticCell};

/// The dual-bus layer of the interlocking side, classifying by the shared railway profile. The
/// gateway supervises no A/B pairs, so its same-function table is the smallest there is.
pub type Link = DualBus<&'static RailwayProfile, Capacity<MERGE_SLOTS, FUNCTIONS>>;
/// Room of the same-function table: the least there is, no pair being supervised.
pub const FUNCTIONS: usize = 2;
/// The slave node: its static dictionary (lent: a `static`, see [`Gateway::unstarted`]),
/// railway profile, no node guarding of others, one TPDO per track circuit, no RPDO.
pub type Board = Node<&'static mut Od, &'static RailwayProfile, GUARDED, TPDOS, RPDOS>;
/// Nodes the board guards: none (it is a slave).
pub const GUARDED: usize = 0;
/// TPDOs of the board: one per track circuit.
pub const TPDOS: usize = TRACKS as usize;
/// RPDOs of the board: none.
pub const RPDOS: usize = 0;
/// CAN controllers of the interlocking side: the two buses.
pub const PORTS: usize = 2;
/// What the embedded driver runs: the node on the dual-bus layer.
pub type GatewayDevice = Station<Link, Board>;
/// What the interlocking side reports.
pub type DeviceEvent = StationEvent<LinkEvent, NodeEvent>;

/// The dual-bus layer's configuration on `embedded-can` controllers: active-active, the
/// silence limit 3 heartbeat periods of the network. (`nb::Can` never confirms a frame as
/// acknowledged, so the layer's transmit-stall rule never arms here.)
pub fn link_config() -> DualBusConfig {
    DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        Duration::from_millis(dictionary::HEARTBEAT_MS as u64),
    )
}

/// Events the application can hold before it drains them.
pub const EVENT_QUEUE: usize = 32;

/// What the gateway reports.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// A mirrored track circuit changed.
    Track(TrackChange),
    /// The interlocking side: port health, NMT, heartbeats seen.
    Device(DeviceEvent),
}

/// Counters of the field side.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FieldStats {
    /// Frames received.
    pub frames: u32,
    /// Intact pairs of the field board's SRDO.
    pub pairs: u32,
    /// Frames that are not the field SRDO's (the board's heartbeat, other nodes).
    pub foreign: u32,
    /// Codes in intact pairs that are not track-circuit codes.
    pub invalid_codes: u32,
    /// Violations of the SRDO rules (each made every track circuit occupied).
    pub trips: u32,
    /// The last of them: its cause, instant and measured time.
    pub last_trip: Option<SrdoFault>,
    /// Controller errors.
    pub errors: u32,
}

/// Why the gateway could not be set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetupError {
    /// The profile table has no or another address for the gateway's node-ID.
    NotInProfile {
        /// The gateway's node-ID.
        node: NodeId,
        /// The address it must have.
        address: DeviceAddress,
    },
    /// The network table does not fit the profile (duplicate address, I/O port ≠ 0).
    Table(duocan::profile::railway::TableError),
    /// The dictionary tables do not fit [`Od`].
    Dictionary(BuildError),
    /// [`Storage::install`] was called before: there is one gateway per storage.
    AlreadyInstalled,
    /// [`Gateway::start`] was called before: the gateway runs already.
    AlreadyStarted,
}

impl fmt::Display for SetupError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SetupError::NotInProfile { node, address } => write!(
                f,
                "the network table must put the gateway ({node}) at {address}: add that entry"
            ),
            SetupError::Table(e) => write!(f, "network table: {e}"),
            SetupError::Dictionary(e) => {
                write!(f, "gateway dictionary: {e:?}: raise OD_ENTRIES or OD_BYTES")
            }
            SetupError::AlreadyInstalled => {
                f.write_str("the gateway storage is in use: install once, keep the reference")
            }
            SetupError::AlreadyStarted => {
                f.write_str("the gateway was started before: start it once")
            }
        }
    }
}

impl core::error::Error for SetupError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            SetupError::Table(e) => Some(e),
            SetupError::Dictionary(e) => Some(e),
            _ => None,
        }
    }
}

/// The gateway: interlocking-side driver (two controllers), field controller, mirrors.
pub struct Gateway<C: Can> {
    driver: EmbeddedDriver<GatewayDevice, C, PORTS>,
    field: C,
    tracks: Tracks,
    events: Deque<Event, EVENT_QUEUE>,
    events_dropped: u32,
    field_stats: FieldStats,
}

impl<C: Can> Gateway<C> {
    /// Builds the gateway on `cans` = [bus 1, bus 2, field bus] with the empty dictionary `od`
    /// and boots its node at `now`. `profile` is the interlocking network's table; it must
    /// hold the gateway at [`ADDRESS`].
    pub fn new(
        profile: &'static RailwayProfile,
        od: &'static mut Od,
        cans: [C; 3],
        now: Instant,
    ) -> Result<Self, SetupError> {
        let mut gw = Self::unstarted(profile, od, cans, now);
        gw.start(now)?;
        Ok(gw)
    }

    /// The gateway on `cans` = [bus 1, bus 2, field bus] with the empty dictionary `od`, not
    /// started: its dictionary empty, its node not booted, nothing sent.
    /// [`start`](Self::start) it before polling it.
    ///
    /// This is how a microcontroller builds it without copies: `let mut gw =
    /// Gateway::unstarted(…)` in a function that never returns (the main loop's) has the
    /// gateway written straight into that function's frame, its parts straight into it (each
    /// constructor not inlined and given nothing large by value). Every move of the gateway's
    /// 30 kB on the way would be another copy on the stack, and a `static` cannot be written
    /// that way: the compiler copies into one through the stack. The dictionary is the
    /// exception: empty, it is a constant of zeros, so a `static` of it needs no writing at
    /// all (it lies in `.bss`), and the node borrows it; built inside the node, it was built
    /// in a temporary and copied.
    #[inline(never)]
    #[must_use]
    pub fn unstarted(
        profile: &'static RailwayProfile,
        od: &'static mut Od,
        cans: [C; 3],
        now: Instant,
    ) -> Self {
        let [bus1, bus2, field] = cans;
        Gateway {
            driver: new_driver(profile, od, [bus1, bus2]),
            field,
            tracks: Tracks::new(
                now,
                Duration::from_millis(u64::from(dictionary::FIELD_TIMEOUT_MS)),
                FIELD_SRVT,
            ),
            events: Deque::new(),
            events_dropped: 0,
            field_stats: FieldStats::default(),
        }
    }

    /// Starts an [`unstarted`](Self::unstarted) gateway at `now`: checks that its profile holds
    /// it at [`ADDRESS`], loads the dictionary, boots the node and sends the mirrors. A
    /// gateway that was started before stays as it is ([`SetupError::AlreadyStarted`]).
    pub fn start(&mut self, now: Instant) -> Result<(), SetupError> {
        if self.node().nmt_state() != NmtState::Initialising {
            return Err(SetupError::AlreadyStarted);
        }
        check_profile(self.node().profile())?;
        self.node_mut()
            .od_mut()
            .load(NODE_ID.raw(), &dictionary::TABLES)
            .map_err(SetupError::Dictionary)?;
        self.node_mut().boot(now);
        self.publish_all(now);
        Ok(())
    }

    /// One pass of the main loop: everything due at `now`. Returns when to call again at the
    /// latest (also call it when a controller has received a frame).
    pub fn poll(&mut self, now: Instant) -> Option<Instant> {
        self.receive_field(now);
        let (trip, changes) = self.tracks.handle_timeout(now, self.field_timeout());
        if let Some(f) = trip {
            self.field_tripped(f);
        }
        self.publish(now, &changes);
        let mut next = self.driver.poll(now);
        // The driver re-initialises ports the dual-bus layer asks for. A reboot (power-on or NMT
        // reset) restores the dictionary's defaults: put the mirrors back and send them.
        if self.drain_device() {
            self.publish_all(now);
            next = self.driver.poll(now);
        }
        earliest(next, self.tracks.deadline())
    }

    /// Next event.
    #[must_use]
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }
    /// State and cause of track circuit `track` (1-based).
    pub fn track(&self, track: u8) -> Option<(TrackCircuit, mirror::Cause)> {
        self.tracks.get(track)
    }
    /// Field-side counters.
    pub fn field_stats(&self) -> FieldStats {
        self.field_stats
    }
    /// Counters of an interlocking-side controller (0: bus 1, 1: bus 2).
    pub fn bus_stats(&self, port: usize) -> Option<EmbeddedPortStats> {
        self.driver.stats(port)
    }
    /// Events lost because the application did not drain them.
    pub fn events_dropped(&self) -> u32 {
        self.events_dropped
    }
    /// The interlocking-side device (node and dual-bus layer).
    pub fn device(&self) -> &GatewayDevice {
        self.driver.device()
    }
    /// The node.
    pub fn node(&self) -> &Board {
        &self.driver.device().machine
    }
    fn node_mut(&mut self) -> &mut Board {
        &mut self.driver.device_mut().machine
    }
    /// The field controller (to restart it).
    pub fn field_mut(&mut self) -> &mut C {
        &mut self.field
    }
    /// An interlocking-side controller (to restart it).
    pub fn bus_mut(&mut self, port: usize) -> Option<&mut C> {
        self.driver.port_mut(port)
    }

    fn field_timeout(&self) -> Duration {
        let ms = self
            .node()
            .od()
            .get_value::<u16>(FIELD_TIMEOUT, 0)
            .unwrap_or(dictionary::FIELD_TIMEOUT_MS);
        Duration::from_millis(ms as u64)
    }

    fn receive_field(&mut self, now: Instant) {
        let sct = self.field_timeout();
        for _ in 0..RX_BURST {
            let frame = match self.field.receive() {
                Ok(f) => f,
                Err(nb::Error::WouldBlock) => return,
                Err(nb::Error::Other(e)) => {
                    self.field_stats.errors += 1;
                    // A controller error is no pair: the consumer's SCT runs on.
                    let _ = status_of(e.kind());
                    continue;
                }
            };
            self.field_stats.frames += 1;
            let Ok(frame) = Frame::from_embedded(&frame) else {
                self.field_stats.foreign += 1;
                continue;
            };
            let (verdict, changes) = self.tracks.handle_frame(now, &frame, sct);
            match verdict {
                Verdict::Foreign => self.field_stats.foreign += 1,
                Verdict::Held => {}
                Verdict::Pair { invalid } => {
                    self.field_stats.pairs += 1;
                    self.field_stats.invalid_codes += u32::from(invalid);
                }
                Verdict::Trip(f) => self.field_tripped(f),
            }
            self.publish(now, &changes);
        }
    }

    fn field_tripped(&mut self, f: SrdoFault) {
        self.field_stats.trips += 1;
        self.field_stats.last_trip = Some(f);
    }

    fn publish(&mut self, now: Instant, changes: &Changes) {
        for c in changes {
            self.write_track(now, c.track, c.to);
            self.push(Event::Track(*c));
        }
    }

    fn publish_all(&mut self, now: Instant) {
        for track in 1..=TRACKS {
            let state = self
                .tracks
                .get(track)
                .map_or(TrackCircuit::Occupied, |s| s.0);
            self.write_track(now, track, state);
        }
    }

    /// 0x6000 sub `track` and the TPDO image (the write sends the TPDO when operational).
    fn write_track(&mut self, now: Instant, track: u8, state: TrackCircuit) {
        let node = self.node_mut();
        // The CRC covers the identifier the TPDO is configured with now.
        let id = node
            .od()
            .get_value::<u32>(0x1800 + u16::from(track) - 1, 1)
            .ok()
            .and_then(|v| CobId(v).can_id())
            .unwrap_or(dictionary::state_id(track));
        let image = FieldState::Track(state).payload(track).to_bytes(id);
        // Both entries exist by construction of the tables; a failure would leave the safe
        // default (occupied) in place.
        let _ = node.write(now, TRACK_STATES, track, &[state.code()]);
        // The inverted half of SRDO 1, written in the same call: the producer packs both at
        // its next refresh and sends them only if they are each other's inverse.
        let _ = node.write(now, TRACK_STATES_INVERTED, track, &[!state.code()]);
        let _ = node.write(now, IMAGE, track, &image[..IMAGE_LEN]);
    }

    /// Moves the device's events to the queue; true if the node (re)booted.
    fn drain_device(&mut self) -> bool {
        let mut booted = false;
        while let Some(e) = self.driver.poll_event() {
            if let StationEvent::Machine(NodeEvent {
                kind:
                    NodeEventKind::StateChanged {
                        cause: StateCause::Boot,
                        ..
                    },
                ..
            }) = e
            {
                booted = true;
            }
            self.push(Event::Device(e));
        }
        booted
    }

    fn push(&mut self, e: Event) {
        if self.events.push_back(e).is_err() {
            self.events_dropped = self.events_dropped.wrapping_add(1);
        }
    }
}

/// Static storage for one gateway: the network table and the gateway itself. Put it in a
/// `static` and [`install`](Storage::install) once at start-up; on a board `C` is the HAL's
/// CAN controller type and the main loop sleeps until the returned deadline or a CAN
/// interrupt. Here with the [mock](crate::mock) controllers:
///
/// ```
/// use duocan::Instant;
/// use safety_gateway::mock::{MockCan, Wire};
/// use safety_gateway::{Storage, ADDRESS, NODE_ID};
/// use static_cell::StaticCell;
///
/// static STORAGE: Storage<MockCan<'static>> = Storage::new();
/// static WIRES: StaticCell<[Wire; 3]> = StaticCell::new();
///
/// let wires: &'static [Wire; 3] = WIRES.init([Wire::new(), Wire::new(), Wire::new()]);
/// let [can1, _] = wires[0].ends();
/// let [can2, _] = wires[1].ends();
/// let [can3, _] = wires[2].ends();
/// let gw = STORAGE
///     .install(&[(NODE_ID, ADDRESS)], [can1, can2, can3], Instant::ZERO)
///     .unwrap();
/// let next = gw.poll(Instant::ZERO);
/// assert!(next.is_some(), "the heartbeat timer is armed");
/// assert_eq!(wires[0].in_flight(), 1, "boot-up message on bus 1");
/// ```
pub struct Storage<C: Can> {
    profile: StaticCell<RailwayProfile>,
    od: ConstStaticCell<Od>,
    gateway: StaticCell<Gateway<C>>,
}

impl<C: Can> Default for Storage<C> {
    fn default() -> Self {
        Self::new()
    }
}

impl<C: Can> Storage<C> {
    /// Empty storage (`const`: for a `static`).
    #[must_use]
    pub const fn new() -> Self {
        Storage {
            profile: StaticCell::new(),
            od: ConstStaticCell::new(Od::new()),
            gateway: StaticCell::new(),
        }
    }

    /// Builds the profile from `network` (`(node, board address)` of every node on the
    /// interlocking network, the gateway included) and the gateway in place; boots it at `now`.
    pub fn install(
        &'static self,
        network: &[(NodeId, DeviceAddress)],
        cans: [C; 3],
        now: Instant,
    ) -> Result<&'static mut Gateway<C>, SetupError> {
        let profile = RailwayProfile::with(network).map_err(SetupError::Table)?;
        check_profile(&profile)?;
        let profile: &'static RailwayProfile = self
            .profile
            .try_init(profile)
            .ok_or(SetupError::AlreadyInstalled)?;
        let od = self.od.try_take().ok_or(SetupError::AlreadyInstalled)?;
        let slot = self
            .gateway
            .try_uninit()
            .ok_or(SetupError::AlreadyInstalled)?;
        let gw = slot.write(Gateway::unstarted(profile, od, cans, now));
        gw.start(now)?;
        Ok(gw)
    }
}

/// The driver with its device, built where the caller wants it (not inlined: see
/// [`Gateway::unstarted`]).
#[inline(never)]
fn new_driver<C: Can>(
    profile: &'static RailwayProfile,
    od: &'static mut Od,
    ports: [C; PORTS],
) -> EmbeddedDriver<GatewayDevice, C, PORTS> {
    EmbeddedDriver::with_device(|| new_device(profile, od), ports)
}

/// The device (node on the dual-bus layer), built where the caller wants it (not inlined: see
/// [`Gateway::unstarted`]).
#[inline(never)]
fn new_device(profile: &'static RailwayProfile, od: &'static mut Od) -> GatewayDevice {
    Station::new(new_link(profile), new_board(profile, od))
}

/// The dual-bus layer, built where the caller wants it (not inlined: see
/// [`Gateway::unstarted`]).
#[inline(never)]
fn new_link(profile: &'static RailwayProfile) -> Link {
    DualBus::with_classifier(link_config(), profile)
}

/// The node on the empty dictionary `od`, built where the caller wants it (not inlined: see
/// [`Gateway::unstarted`]).
#[inline(never)]
fn new_board(profile: &'static RailwayProfile, od: &'static mut Od) -> Board {
    Node::with_profile(NodeConfig::slave(NODE_ID), od, profile)
}

/// The profile holds the gateway where it must be.
fn check_profile(profile: &RailwayProfile) -> Result<(), SetupError> {
    if profile.address(NODE_ID) == Some(ADDRESS) {
        Ok(())
    } else {
        Err(SetupError::NotInProfile {
            node: NODE_ID,
            address: ADDRESS,
        })
    }
}
