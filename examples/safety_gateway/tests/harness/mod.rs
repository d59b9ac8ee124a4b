//! A test bench for the gateway on the host: two mock buses to a duocan interlocking master
//! (std, dynamic dictionary, DualBus, SDO client) and a mock field bus to a scripted
//! track-circuit board that sends its track circuits as an SRDO. Time is simulated: each step jumps to the next deadline of anyone, and
//! frames cross the mock wires at once, so instants are exact.
#![allow(dead_code)]

use duocan::cia304::srdo::config::{SrdoConfig, SrdoMapping};
use duocan::cia304::srdo::objects as objects_srdo;
use duocan::machine::{Composite, CompositeEvent, StationEvent};
use duocan::od::{comm, Access, DynamicDictionary, ObjectDef, ObjectDictionary, ObjectType};
use duocan::pdo::MapEntry;
use duocan::port::embedded::EmbeddedDriver;
use duocan::profile::railway::safety::{FieldState, TrackCircuit};
use duocan::profile::railway::{self, DeviceAddress, Payload, RailFunction, RailwayProfile};
use duocan::sdo::{SdoClient, SdoError, SdoEvent, SdoOptions, TransferBuffer};
use duocan::{
    Frame, Instant, Machine, NmtCommand, NmtTarget, Node, NodeConfig, NodeEvent, NodeId, Station,
};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEvent, LinkMode};
use safety_gateway::mirror::field_pair;
use safety_gateway::mock::{MockCan, Wire};
use safety_gateway::{Event, Gateway, Storage, ADDRESS, NODE_ID, TRACKS};
use static_cell::StaticCell;
use std::collections::BTreeMap;

/// The interlocking master.
pub const MASTER: NodeId = NodeId::must(1);
/// Its board address.
pub const MASTER_ADDRESS: DeviceAddress = DeviceAddress::board_at(0, 0, 0, 1);
/// The interlocking network: the master and the gateway.
pub const NETWORK: [(NodeId, DeviceAddress); 2] = [(MASTER, MASTER_ADDRESS), (NODE_ID, ADDRESS)];
/// Heartbeat of the master (ms); it consumes the gateway's with 3 × the gateway's period.
pub const MASTER_HB_MS: u16 = 50;
pub const CONSUMER_MS: u16 = 150;
/// Cycle of the field board's SRDO.
pub const FIELD_CYCLE_MS: u64 = 100;

/// What the master's application sees of the gateway's state changes.
#[derive(Default)]
pub struct Interlocking {
    /// Every state change of the gateway: (when, track, decoded state or why it was refused).
    pub seen: Vec<(Instant, u8, Result<TrackCircuit, String>)>,
}

impl Interlocking {
    /// The latest state of `track` as the interlocking must read it: anything invalid is
    /// occupied.
    pub fn state(&self, track: u8) -> Option<TrackCircuit> {
        self.seen
            .iter()
            .rev()
            .find(|(_, t, _)| *t == track)
            .map(|(_, _, s)| s.clone().unwrap_or(TrackCircuit::Occupied))
    }
    /// When `track` last changed to `state` (the first frame of the latest run of it).
    pub fn since(&self, track: u8, state: TrackCircuit) -> Option<Instant> {
        let mut at = None;
        for (t, k, s) in &self.seen {
            if *k != track {
                continue;
            }
            let s = s.clone().unwrap_or(TrackCircuit::Occupied);
            match (s == state, at) {
                (true, None) => at = Some(*t),
                (false, _) => at = None,
                _ => {}
            }
        }
        at
    }
}

impl Machine for Interlocking {
    type Event = ();
    type LinkCommand = std::convert::Infallible;
    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        let Some((code, address)) = railway::split(frame.id()) else {
            return;
        };
        if code != RailFunction::StateChange.code() || address.board_address() != ADDRESS {
            return;
        }
        let track = address.port();
        let state = Payload::decode(frame)
            .map_err(|e| e.to_string())
            .and_then(|p| FieldState::from_payload(&p).map_err(|e| e.to_string()))
            .and_then(|(sub, s)| match s {
                FieldState::Track(t) if sub == track => Ok(t),
                other => Err(format!("unexpected {other:?} sub {sub}")),
            });
        self.seen.push((now, track, state));
    }
    fn handle_timeout(&mut self, _: Instant) {}
    fn poll_transmit(&mut self) -> Option<Frame> {
        None
    }
    fn poll_timeout(&self) -> Option<Instant> {
        None
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

pub type MasterNode = Node<DynamicDictionary, RailwayProfile>;
pub type MasterDev =
    Station<DualBus<RailwayProfile>, Composite<MasterNode, Composite<SdoClient, Interlocking>>>;
pub type MasterEvent =
    StationEvent<LinkEvent, CompositeEvent<NodeEvent, CompositeEvent<SdoEvent, ()>>>;

fn profile() -> RailwayProfile {
    RailwayProfile::with(&NETWORK).expect("network table")
}

fn master_device() -> MasterDev {
    let mut od = comm::standard_dictionary(MASTER.raw(), comm::Identity::default());
    for def in RailwayProfile::comm_objects(MASTER_ADDRESS) {
        od.upsert(def);
    }
    od.write_local(comm::HEARTBEAT_PRODUCER, 0, &MASTER_HB_MS.to_le_bytes())
        .unwrap();
    let consumer = (u32::from(NODE_ID.raw()) << 16) | u32::from(CONSUMER_MS);
    od.write_local(comm::HEARTBEAT_CONSUMER, 1, &consumer.to_le_bytes())
        .unwrap();
    // The SRDO consumer side (configured by `Bench::watch_srdo`): the gateway's four codes and
    // their inverses land in 0x6000/0x6001 of the master.
    od.insert_all(&objects_srdo::srdo(
        1,
        safety_gateway::dictionary::SRDO_NORMAL,
    ))
    .unwrap();
    od.insert_all(&objects_srdo::shared::<4>()).unwrap();
    for index in [0x6000u16, 0x6001] {
        od.insert(ObjectDef::u8(index, 0, Access::Const, TRACKS).object_type(ObjectType::Array))
            .unwrap();
        for k in 1..=TRACKS {
            od.insert(
                ObjectDef::u8(index, k, Access::Rw, 0)
                    .mappable()
                    .object_type(ObjectType::Array),
            )
            .unwrap();
        }
    }
    let node = Node::with_profile(NodeConfig::master(MASTER), od, profile());
    let cfg = DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        duocan::Duration::from_millis(MASTER_HB_MS as u64),
    );
    Station::new(
        DualBus::with_classifier(cfg, profile()),
        Composite::new(
            node,
            Composite::new(SdoClient::new(256), Interlocking::default()),
        ),
    )
}

/// Allocates the three wires in static storage (one bench per process: the storage is static).
pub fn wires(cell: &'static StaticCell<[Wire; 3]>) -> &'static [Wire; 3] {
    cell.init([Wire::new(), Wire::new(), Wire::new()])
}

pub struct Bench {
    /// Bus 1, bus 2, field bus.
    pub wires: &'static [Wire; 3],
    pub gateway: &'static mut Gateway<MockCan<'static>>,
    pub master: Box<EmbeddedDriver<MasterDev, MockCan<'static>, 2>>,
    pub field: MockCan<'static>,
    pub now: Instant,
    /// Codes the field board sends every cycle (occupied until told otherwise).
    pub field_codes: [u8; TRACKS as usize],
    /// The field board runs (reports every cycle) while true.
    pub field_on: bool,
    field_next: Option<Instant>,
    next: [Option<Instant>; 2],
    pub gateway_events: Vec<Event>,
    pub master_events: Vec<(Instant, MasterEvent)>,
    /// The gateway runs (is polled) while true; false is a power loss.
    pub gateway_on: bool,
}

impl Bench {
    /// Installs the gateway in `storage` on `wires` and boots master and gateway at 0.
    pub fn new(storage: &'static Storage<MockCan<'static>>, wires: &'static [Wire; 3]) -> Bench {
        let [gw1, m1] = wires[0].ends();
        let [gw2, m2] = wires[1].ends();
        let [gwf, field] = wires[2].ends();
        let gateway = storage
            .install(&NETWORK, [gw1, gw2, gwf], Instant::ZERO)
            .expect("install the gateway");
        let mut master = Box::new(EmbeddedDriver::new(master_device(), [m1, m2]));
        master.device_mut().machine.a.boot(Instant::ZERO);
        let mut b = Bench {
            wires,
            gateway,
            master,
            field,
            now: Instant::ZERO,
            field_codes: [0xAA; TRACKS as usize],
            field_on: false,
            field_next: None,
            next: [None; 2],
            gateway_events: Vec::new(),
            master_events: Vec::new(),
            gateway_on: true,
        };
        b.settle();
        b
    }

    /// Polls everyone at `now` until no frame is in flight.
    pub fn settle(&mut self) {
        // A gateway without power: nothing polls it, and what is sent to it stays on the wire;
        // the master alone settles in a few rounds.
        if !self.gateway_on {
            self.next[0] = None;
            for _ in 0..4 {
                self.next[1] = self.master.poll(self.now);
                while let Some(e) = self.master.poll_event() {
                    self.master_events.push((self.now, e));
                }
            }
            return;
        }
        for _ in 0..64 {
            self.next[0] = self.gateway.poll(self.now);
            self.next[1] = self.master.poll(self.now);
            while let Some(e) = self.gateway.poll_event() {
                self.gateway_events.push(e);
            }
            while let Some(e) = self.master.poll_event() {
                self.master_events.push((self.now, e));
            }
            if self.wires.iter().all(|w| w.in_flight() == 0) {
                return;
            }
        }
        panic!("frames still in flight at {} after 64 rounds", self.now);
    }

    /// Runs until `until` (inclusive).
    pub fn run_until(&mut self, until: Instant) {
        loop {
            let next = [self.next[0], self.next[1], self.field_next]
                .into_iter()
                .flatten()
                .min()
                .filter(|t| *t <= until);
            let Some(t) = next else {
                self.now = self.now.max(until);
                self.settle();
                return;
            };
            self.now = self.now.max(t);
            if self.field_on && self.field_next.is_some_and(|f| f <= self.now) {
                self.field_cycle();
            }
            self.settle();
        }
    }

    /// Runs for `ms` milliseconds.
    pub fn run_ms(&mut self, ms: u64) {
        self.run_until(self.now.saturating_add(duocan::Duration::from_millis(ms)));
    }

    /// The field board sends `code` for `track` now (an SRDO pair with all its codes, as on a
    /// change) and every cycle after.
    pub fn field_set(&mut self, track: u8, code: u8) {
        self.field_codes[usize::from(track - 1)] = code;
        self.field_on = true;
        for f in field_pair(self.field_codes) {
            self.field_send(&f);
        }
        if self.field_next.is_none() {
            self.field_next = Some(
                self.now
                    .saturating_add(duocan::Duration::from_millis(FIELD_CYCLE_MS)),
            );
        }
        self.settle();
    }

    /// The field board stops reporting.
    pub fn field_stop(&mut self) {
        self.field_on = false;
        self.field_next = None;
    }

    /// Puts a raw frame on the field bus.
    pub fn field_send(&mut self, f: &Frame) {
        use embedded_can::nb::Can;
        self.field.transmit(f).expect("field bus accepts the frame");
    }

    fn field_cycle(&mut self) {
        for f in field_pair(self.field_codes) {
            self.field_send(&f);
        }
        self.field_next = Some(
            self.now
                .saturating_add(duocan::Duration::from_millis(FIELD_CYCLE_MS)),
        );
    }

    /// The master's application.
    pub fn interlocking(&self) -> &Interlocking {
        &self.master.device().machine.b.b
    }

    pub fn master_node(&mut self) -> &mut MasterNode {
        &mut self.master.device_mut().machine.a
    }

    /// The master consumes the gateway's SRDO 1 from now on (safety cycle time `sct_ms`): it
    /// leaves operational, configures its consumer over its own write path (checksum
    /// included), marks it valid and is operational again, its SCT running from now.
    pub fn watch_srdo(&mut self, sct_ms: u16) {
        let now = self.now;
        let pairs: Vec<_> = (1..=TRACKS)
            .map(|k| (MapEntry::new(0x6000, k, 8), MapEntry::new(0x6001, k, 8)))
            .collect();
        let srdo = SrdoConfig::new(
            false,
            sct_ms,
            safety_gateway::dictionary::SRDO_SRVT_MS,
            safety_gateway::dictionary::SRDO_NORMAL,
            SrdoMapping::pairs(&pairs),
        );
        let node = self.master_node();
        node.set_nmt_state(now, duocan::NmtState::PreOperational);
        node.configure_srdo(now, 1, &srdo)
            .expect("SRDO configuration");
        node.srdo_mark_valid(now)
            .expect("a valid SRDO configuration");
        node.set_nmt_state(now, duocan::NmtState::Operational);
        self.settle();
    }

    /// NMT start of the gateway by the master.
    pub fn start_gateway(&mut self) {
        let now = self.now;
        self.master_node()
            .nmt_command(now, NmtCommand::Start, NmtTarget::Node(NODE_ID))
            .expect("NMT queue");
        self.settle();
    }

    fn sdo(
        &mut self,
        start: impl FnOnce(
            &mut SdoClient,
            Instant,
            SdoOptions,
        ) -> Result<duocan::sdo::RequestId, SdoError>,
    ) -> Result<Vec<u8>, SdoError> {
        let opts = SdoOptions::default().with_channel(profile().sdo_channel(NODE_ID));
        let now = self.now;
        let id = start(&mut self.master.device_mut().machine.b.a, now, opts)?;
        self.settle();
        let deadline = self.now.saturating_add(duocan::Duration::from_secs(3));
        loop {
            let done = self.master_events.iter().find_map(|(_, e)| match e {
                StationEvent::Machine(CompositeEvent::B(CompositeEvent::A(ev)))
                    if ev.request == id =>
                {
                    Some(
                        ev.result
                            .as_ref()
                            .map(|b| b.as_slice().to_vec())
                            .map_err(|e| *e),
                    )
                }
                _ => None,
            });
            if let Some(r) = done {
                return r;
            }
            assert!(self.now < deadline, "SDO transfer {id:?} did not finish");
            let t = self.next.into_iter().flatten().min().unwrap_or(deadline);
            self.run_until(t.min(deadline));
        }
    }

    /// SDO upload from the gateway over the railway SDO channel.
    pub fn sdo_read(&mut self, index: u16, sub: u8) -> Result<Vec<u8>, SdoError> {
        self.sdo(|c, now, o| c.upload(now, NODE_ID, index, sub, o))
    }

    /// SDO download to the gateway.
    pub fn sdo_write(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoError> {
        self.sdo(|c, now, o| c.download(now, NODE_ID, index, sub, data, o))
            .map(|_| ())
    }

    /// Master node events with their instants.
    pub fn master_node_events(&self) -> Vec<(Instant, duocan::NodeEventKind)> {
        self.master_events
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Machine(CompositeEvent::A(n)) => Some((n.at, n.kind)),
                _ => None,
            })
            .collect()
    }

    /// Link events of the master's dual-bus layer.
    pub fn master_link_events(&self) -> Vec<LinkEvent> {
        self.master_events
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Link(l) => Some(*l),
                _ => None,
            })
            .collect()
    }
}

/// Counts per track of the interlocking's view, for messages.
pub fn view(b: &Bench) -> BTreeMap<u8, Option<TrackCircuit>> {
    (1..=TRACKS)
        .map(|k| (k, b.interlocking().state(k)))
        .collect()
}
