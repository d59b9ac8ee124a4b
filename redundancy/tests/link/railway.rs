//! The railway 29-bit profile on the simulated dual bus: the standard stack (`Node`, SDO client
//! and server, TPDOs, heartbeat consumer, node guarding, SYNC) and the dual-bus layer run
//! unchanged over it, selected by the profile alone.
//!
//! One signal-interlocking slice: the master (R0 C0 L0 B1), a turnout pair A/B reporting point 1
//! on I/O port 2, a track-circuit board streaming numbered CRC-checked state changes, and a
//! signal board watched by node guarding instead of heartbeats. Bus 1 is cut for a second;
//! later B disagrees with A, and the track board dies.

use duocan::machine::{Composite, CompositeEvent, StationEvent};
use duocan::node::NodeEventKind;
use duocan::od::{comm, Access, DataType, DefaultValue, DynamicDictionary, ObjectDef};
use duocan::pdo::params;
use duocan::profile::railway::safety::{
    objects, FieldState, PointPosition, SafetyCode, TrackCircuit,
};
use duocan::profile::railway::{self, DeviceAddress, Payload, RailFunction, RailwayProfile};
use duocan::profile::IdProfile;
use duocan::sdo::{Direction, SdoClient, SdoEvent, SdoOptions};
use duocan::sim::{BusConfig, BusId, DevId, SimNetwork, TraceRecord, TxOutcome};
use duocan::{
    CobId, Duration, Frame, Id, Instant, Machine, NmtCommand, NmtState, NmtTarget, Node,
    NodeConfig, NodeEvent, NodeId, Station,
};
use duocan_redundancy::link::classify::state_function;
use duocan_redundancy::{
    DualBus, DualBusConfig, LinkEvent, LinkEventKind, LinkMode, Member, PortReason, PortState,
};

const MASTER: u8 = 1;
const TURNOUT_A: u8 = 2;
const TURNOUT_B: u8 = 3;
const TRACK: u8 = 4;
const SIGNAL: u8 = 5;

const ADDRESSES: [(u8, DeviceAddress); 5] = [
    (MASTER, DeviceAddress::board_at(0, 0, 0, 1)),
    (TURNOUT_A, DeviceAddress::board_at(1, 1, 1, 1)),
    (TURNOUT_B, DeviceAddress::board_at(1, 1, 1, 2)),
    (TRACK, DeviceAddress::board_at(1, 2, 1, 1)),
    (SIGNAL, DeviceAddress::board_at(1, 3, 1, 1)),
];

/// Heartbeat period of the boards; consumer time and silence limit are 3 periods.
const HB_MS: u64 = 20;
const CONSUMER: Duration = Duration::from_millis(3 * HB_MS);
/// The I/O port of point 1 on the turnout boards, and of track circuit 1 on the track board.
const POINT_PORT: u8 = 2;
const TRACK_PORT: u8 = 1;
/// The dictionary entry a TPDO maps: the whole railway payload, CRC included.
const IMAGE: u16 = 0x2100;
const SCRATCH: u16 = 0x2000;

const START: Instant = Instant::from_millis(50);
const STREAM_FROM: Instant = Instant::from_millis(100);
const STREAM_UNTIL: Instant = Instant::from_millis(2_700);
const CUT: Instant = Instant::from_millis(1_000);
const REPAIR: Instant = Instant::from_millis(2_000);
const DISAGREE: Instant = Instant::from_millis(2_300);
const KILL: Instant = Instant::from_millis(2_810);
const SYNC_OFF: Instant = Instant::from_millis(2_900);
const END: Instant = Instant::from_millis(3_000);

fn ms(v: u64) -> Instant {
    Instant::from_millis(v)
}
fn n(x: u8) -> NodeId {
    NodeId::must(x)
}
fn address(node: u8) -> DeviceAddress {
    ADDRESSES.iter().find(|(x, _)| *x == node).unwrap().1
}
fn profile() -> RailwayProfile {
    let entries: Vec<_> = ADDRESSES.iter().map(|(x, a)| (n(*x), *a)).collect();
    RailwayProfile::with(&entries).unwrap()
}

/// The master's application: every state change the logical bus delivers.
#[derive(Default)]
struct Interlocking {
    states: Vec<(Instant, Frame)>,
}

impl Machine for Interlocking {
    type Event = ();
    type LinkCommand = std::convert::Infallible;
    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        if railway::split(frame.id()).map(|x| x.0) == Some(RailFunction::StateChange.code()) {
            self.states.push((now, *frame));
        }
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

type RailNode = Node<DynamicDictionary, RailwayProfile>;
type Link = DualBus<RailwayProfile>;
type MasterDev = Station<Link, Composite<RailNode, Composite<SdoClient, Interlocking>>>;
type BoardDev = Station<Link, RailNode>;

/// A dictionary with the railway identifiers as defaults, an 8-byte image entry for a TPDO and
/// a scratch entry for SDO writes.
fn dictionary(node: u8) -> DynamicDictionary {
    let mut od = comm::standard_dictionary(node, comm::Identity::default());
    for def in RailwayProfile::comm_objects(address(node)) {
        od.upsert(def);
    }
    od.insert(
        ObjectDef::bytes(IMAGE, 0, DataType::OctetString, 8)
            .access(Access::Rw)
            .mappable(),
    )
    .unwrap();
    od.insert(ObjectDef::u32(SCRATCH, 0, Access::Rw, 0))
        .unwrap();
    od
}

/// TPDO1 of a board: the image (`bytes` long) as a state change on I/O `port`, sent when
/// written, and every `timer_ms` (0: only when written).
fn state_tpdo(node: u8, port: u8, bytes: u8, timer_ms: u16) -> Vec<ObjectDef> {
    let cob = CobId::from_id(railway::id(
        RailFunction::StateChange,
        address(node).with_port(port),
    ));
    let mut v =
        params::tpdo_comm(1, DefaultValue::Unsigned(cob.0 as u64), 254, 0, timer_ms).to_vec();
    v.extend(params::tpdo_mapping::<9>(
        1,
        &[((IMAGE as u32) << 16) | (bytes as u32 * 8)],
    ));
    v
}

fn state_id(node: u8, port: u8) -> Id {
    railway::id(RailFunction::StateChange, address(node).with_port(port))
}

/// The track board's state change number `seq`: occupancy alternating every ten reports.
fn track_payload(seq: u16) -> Payload {
    let state = if (seq / 10).is_multiple_of(2) {
        TrackCircuit::Clear
    } else {
        TrackCircuit::Occupied
    };
    let [lo, hi] = seq.to_le_bytes();
    Payload::new(objects::TRACK_CIRCUIT, 1, &[state.code(), lo, hi]).unwrap()
}

fn point(p: PointPosition) -> Payload {
    FieldState::Point(p).payload(1)
}

struct Net {
    sim: SimNetwork,
    buses: [BusId; 2],
    master: DevId<MasterDev>,
    boards: Vec<(u8, DevId<BoardDev>)>,
    stream_len: u16,
}

impl Net {
    fn board(&self, node: u8) -> DevId<BoardDev> {
        self.boards.iter().find(|(x, _)| *x == node).unwrap().1
    }
    fn master_node_events(&self) -> Vec<NodeEvent> {
        self.sim
            .events(self.master)
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Machine(CompositeEvent::A(e)) => Some(*e),
                _ => None,
            })
            .collect()
    }
    fn master_link_events(&self) -> Vec<LinkEvent> {
        self.sim
            .events(self.master)
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Link(e) => Some(*e),
                _ => None,
            })
            .collect()
    }
    fn sdo_events(&self) -> Vec<SdoEvent> {
        self.sim
            .events(self.master)
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Machine(CompositeEvent::B(CompositeEvent::A(e))) => Some(e.clone()),
                _ => None,
            })
            .collect()
    }
    /// Delivered transmissions on `bus` of `id`: (end, frame).
    fn wire(&self, bus: usize, id: Id) -> Vec<(Instant, Frame)> {
        self.sim
            .trace()
            .iter()
            .filter_map(|r| match r {
                TraceRecord::Tx(x)
                    if x.bus == self.buses[bus]
                        && x.frame.id() == id
                        && matches!(x.outcome, TxOutcome::Delivered { .. }) =>
                {
                    Some((x.end, x.frame))
                }
                _ => None,
            })
            .collect()
    }
}

fn build() -> Net {
    let profile = profile();
    let mut sim = SimNetwork::new(9);
    let buses = [
        sim.add_bus(BusConfig::new("rail1", 1_000_000)),
        sim.add_bus(BusConfig::new("rail2", 1_000_000)),
    ];
    let link = || {
        DualBus::with_classifier(
            DualBusConfig::with_guard_period(LinkMode::ActiveActive, Duration::from_millis(HB_MS)),
            profile.clone(),
        )
    };

    // The master: heartbeat consumer for the turnout and track boards, node guarding for the
    // signal board, SYNC every 10 ms on the railway SYNC identifier.
    let mut m = Node::with_profile(
        NodeConfig::master(n(MASTER)),
        dictionary(MASTER),
        profile.clone(),
    );
    let t0 = Instant::ZERO;
    m.set(t0, comm::HEARTBEAT_PRODUCER, 0, HB_MS as u16)
        .unwrap();
    for (sub, node) in [TURNOUT_A, TURNOUT_B, TRACK].into_iter().enumerate() {
        let v = (node as u32) << 16 | CONSUMER.as_millis() as u32;
        m.set(t0, comm::HEARTBEAT_CONSUMER, sub as u8 + 1, v)
            .unwrap();
    }
    let sync = CobId::from_id(RailwayProfile::SYNC).with_bit30(true);
    m.set(t0, comm::SYNC_COB_ID, 0, sync.0).unwrap();
    m.set(t0, comm::SYNC_PERIOD, 0, 10_000u32).unwrap();
    m.boot(t0);
    assert!(m.guard_node(t0, n(SIGNAL), Duration::from_millis(50), 3));
    let mut mlink = link();
    let pair = mlink
        .add_pair(n(TURNOUT_A), n(TURNOUT_B), Some(Member::A))
        .unwrap();
    assert_eq!(pair.0, 0);
    let station = Station::new(
        mlink,
        Composite::new(
            m,
            Composite::new(SdoClient::new(1024), Interlocking::default()),
        ),
    );
    let master = sim.add_device("master", station, &buses).unwrap();

    // The boards. Each writes its first state before NMT start, so that the TPDO sent on
    // entering operational already carries a valid payload.
    let mut boards = vec![];
    for node in [TURNOUT_A, TURNOUT_B, TRACK, SIGNAL] {
        let mut od = dictionary(node);
        let first = match node {
            TURNOUT_A | TURNOUT_B => {
                od.insert_all(&state_tpdo(node, POINT_PORT, 6, 50)).unwrap();
                point(PointPosition::Normal).to_bytes(state_id(node, POINT_PORT))
            }
            TRACK => {
                od.insert_all(&state_tpdo(node, TRACK_PORT, 8, 0)).unwrap();
                track_payload(0).to_bytes(state_id(node, TRACK_PORT))
            }
            _ => [0; 8],
        };
        let mut b = Node::with_profile(NodeConfig::slave(n(node)), od, profile.clone());
        if node != SIGNAL {
            b.set(t0, comm::HEARTBEAT_PRODUCER, 0, HB_MS as u16)
                .unwrap();
        }
        let len = if node == TRACK { 8 } else { 6 };
        if node != SIGNAL {
            b.write(t0, IMAGE, 0, &first[..len]).unwrap();
        }
        b.boot(t0);
        let id = sim
            .add_device(format!("board{node}"), Station::new(link(), b), &buses)
            .unwrap();
        boards.push((node, id));
    }

    let mut net = Net {
        sim,
        buses,
        master,
        boards,
        stream_len: 0,
    };

    // NMT start of every board on the railway NMT identifier.
    net.sim.at(START, move |sim| {
        sim.device_mut(master)
            .machine
            .a
            .nmt_command(START, NmtCommand::Start, NmtTarget::All)
            .unwrap();
    });
    // The track board reports every 10 ms, numbered.
    let track = net.board(TRACK);
    let tid = state_id(TRACK, TRACK_PORT);
    let mut seq = 0;
    let mut t = STREAM_FROM;
    while t < STREAM_UNTIL {
        seq += 1;
        let bytes = track_payload(seq).to_bytes(tid);
        net.sim.at(t, move |sim| {
            sim.device_mut(track)
                .machine
                .write(t, IMAGE, 0, &bytes)
                .unwrap();
        });
        t += Duration::from_millis(10);
    }
    net.stream_len = seq + 1;
    // Bus 1 cut for a second.
    let b0 = buses[0];
    net.sim.at(CUT, move |sim| sim.bus_down(b0));
    net.sim.at(REPAIR, move |sim| sim.bus_up(b0));
    // B's point machine reports the point moving while A's says normal.
    let b = net.board(TURNOUT_B);
    let moving = point(PointPosition::Moving).to_bytes(state_id(TURNOUT_B, POINT_PORT));
    net.sim.at(DISAGREE, move |sim| {
        sim.device_mut(b)
            .machine
            .write(DISAGREE, IMAGE, 0, &moving[..6])
            .unwrap();
    });
    // The track board dies; SYNC stops before the end so that counts can be compared.
    net.sim.at(KILL, move |sim| sim.power_off(track.erased()));
    net.sim.at(SYNC_OFF, move |sim| {
        sim.device_mut(master)
            .machine
            .a
            .set(SYNC_OFF, comm::SYNC_PERIOD, 0, 0u32)
            .unwrap();
    });
    net
}

/// SDO requests on the railway SDO identifiers: a segmented upload before the cut, a download
/// and an upload while bus 1 is down.
fn schedule_sdo(net: &mut Net) {
    let m = net.master;
    let p = profile();
    let opts = |node: u8| SdoOptions::default().with_channel(Some(p.sdo_channel(n(node)).unwrap()));
    let (o4, o5) = (opts(TRACK), opts(SIGNAL));
    net.sim.at(ms(400), move |sim| {
        let c = &mut sim.device_mut(m).machine.b.a;
        c.upload(ms(400), n(TRACK), 0x1008, 0, o4).unwrap();
    });
    net.sim.at(ms(1_400), move |sim| {
        let c = &mut sim.device_mut(m).machine.b.a;
        c.download(
            ms(1_400),
            n(SIGNAL),
            SCRATCH,
            0,
            &0xCAFE_F00Du32.to_le_bytes(),
            o5,
        )
        .unwrap();
    });
    net.sim.at(ms(1_500), move |sim| {
        let c = &mut sim.device_mut(m).machine.b.a;
        c.upload(ms(1_500), n(SIGNAL), SCRATCH, 0, o5).unwrap();
    });
}

#[test]
fn stack_and_dual_bus_run_unchanged_over_the_railway_profile() {
    let mut net = build();
    schedule_sdo(&mut net);
    net.sim.run_until(END);
    let p = profile();

    // Only 29-bit identifiers on both wires: every service went through the profile or the
    // dictionary's railway defaults.
    let mut on_wire = 0;
    for r in net.sim.trace() {
        if let TraceRecord::Tx(x) = r {
            assert!(x.frame.id().is_extended(), "11-bit frame {:?}", x.frame);
            on_wire += 1;
        }
    }
    assert!(on_wire > 2_000, "{on_wire} frames");

    // Boot-ups arrive twice (one per bus) and are reported once; NMT start reached every board.
    let events = net.master_node_events();
    for node in [TURNOUT_A, TURNOUT_B, TRACK, SIGNAL] {
        let boots = events
            .iter()
            .filter(|e| matches!(e.kind, NodeEventKind::BootUp { node: x } if x == n(node)))
            .count();
        assert_eq!(boots, 1, "boot-up of node {node}");
        let w = net.wire(1, p.heartbeat(n(node)));
        assert_eq!(
            w.first().map(|x| x.1.data()),
            Some(&[0u8][..]),
            "node {node}"
        );
    }
    for node in [TURNOUT_A, TURNOUT_B, SIGNAL] {
        assert_eq!(
            net.sim.device(net.board(node)).machine.nmt_state(),
            NmtState::Operational
        );
    }

    // Heartbeats: nothing lost through the cut; the dead track board timed out exactly
    // consumer time after the first copy of its last heartbeat reached the master.
    let timeouts: Vec<_> = events
        .iter()
        .filter_map(|e| match e.kind {
            NodeEventKind::HeartbeatTimeout { node, last } => Some((e.at, node, last)),
            _ => None,
        })
        .collect();
    let hb = p.heartbeat(n(TRACK));
    let last_on = |bus| {
        net.wire(bus, hb)
            .into_iter()
            .map(|x| x.0)
            .filter(|t| *t <= KILL)
            .max()
            .unwrap()
    };
    let (l0, l1) = (last_on(0), last_on(1));
    assert!(
        l0.max(l1) - l0.min(l1) < Duration::from_millis(1),
        "one occurrence"
    );
    let last = l0.min(l1);
    assert_eq!(timeouts, [(last + CONSUMER, n(TRACK), last)]);

    // Node guarding of the signal board on its 29-bit guarding identifier: answered
    // throughout, toggling, never timed out.
    assert!(!events.iter().any(|e| matches!(
        e.kind,
        NodeEventKind::GuardingTimeout { .. } | NodeEventKind::GuardToggleError { .. }
    )));
    let guard = p.guarding(n(SIGNAL));
    let (requests, answers): (Vec<_>, Vec<_>) = net
        .wire(1, guard)
        .into_iter()
        .partition(|x| x.1.is_remote());
    assert!(answers.len() >= 55, "{} guarding answers", answers.len());
    assert_eq!(answers.len(), requests.len());
    let toggles: Vec<u8> = answers.iter().map(|x| x.1.data()[0] & 0x80).collect();
    assert!(toggles.windows(2).all(|w| w[0] != w[1]));
    assert_eq!(
        net.sim
            .device(net.master)
            .machine
            .a
            .remote(n(SIGNAL))
            .map(|v| v.state),
        Some(NmtState::Operational)
    );

    // SDO on the railway SDO identifiers, before and during the cut.
    let sdo = net.sdo_events();
    assert_eq!(sdo.len(), 3, "{sdo:?}");
    assert_eq!((sdo[0].node, sdo[0].index), (n(TRACK), 0x1008));
    assert_eq!(sdo[0].data(), Some(&b"duocan"[..]));
    assert_eq!(
        (sdo[1].node, sdo[1].direction, sdo[1].result.is_ok()),
        (n(SIGNAL), Direction::Download, true)
    );
    assert!(sdo[1].at > CUT && sdo[2].at < REPAIR);
    assert_eq!(sdo[2].data(), Some(&0xCAFE_F00Du32.to_le_bytes()[..]));
    let (rq, rs) = p.sdo_cob_ids(n(SIGNAL)).unwrap();
    let req = CobId(rq).can_id().unwrap();
    assert!(!net.wire(1, req).is_empty() && net.wire(0, req).is_empty());
    assert!(!net.wire(1, CobId(rs).can_id().unwrap()).is_empty());

    // SYNC on the railway identifier, produced and received in equal numbers at every board.
    let sync_count = |evs: &[NodeEvent], produced: bool| {
        evs.iter()
            .filter(|e| matches!(e.kind, NodeEventKind::Sync { produced: x, .. } if x == produced))
            .count()
    };
    let produced = sync_count(&events, true);
    assert!(produced > 280, "{produced} SYNC");
    for node in [TURNOUT_A, TURNOUT_B, SIGNAL] {
        let evs: Vec<NodeEvent> = net
            .sim
            .events(net.board(node))
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Machine(e) => Some(*e),
                _ => None,
            })
            .collect();
        assert_eq!(sync_count(&evs, false), produced, "SYNC at node {node}");
    }

    // The track board's numbered, CRC-checked state changes: every one exactly once, in order,
    // through the cut.
    let app = &net.sim.device(net.master).machine.b.b;
    let tid = state_id(TRACK, TRACK_PORT);
    let track: Vec<u16> = app
        .states
        .iter()
        .filter(|(_, f)| f.id() == tid)
        .map(|(_, f)| {
            let pl = Payload::decode(f).expect("CRC-checked");
            assert_eq!(pl.index(), objects::TRACK_CIRCUIT);
            let seq = u16::from_le_bytes([pl.data()[1], pl.data()[2]]);
            let state = TrackCircuit::from_code(pl.data()[0]).unwrap();
            assert_eq!(state.code(), track_payload(seq).data()[0]);
            seq
        })
        .collect();
    assert_eq!(track, (0..net.stream_len).collect::<Vec<_>>());
    assert!(net.stream_len > 250);

    // The turnout pair: one stream, from A, each of A's reports once; B's not delivered. Until
    // B disagrees there is no discrepancy although A's and B's CRCs always differ.
    let aid = state_id(TURNOUT_A, POINT_PORT);
    let bid = state_id(TURNOUT_B, POINT_PORT);
    let from_a: Vec<_> = app.states.iter().filter(|(_, f)| f.id() == aid).collect();
    assert!(app.states.iter().all(|(_, f)| f.id() != bid));
    let a_sent = net.wire(1, aid);
    assert_eq!(from_a.len(), a_sent.len());
    assert!(from_a.len() > 55);
    for (_, f) in &from_a {
        assert_eq!(Payload::decode(f), Ok(point(PointPosition::Normal)));
    }
    let link_events = net.master_link_events();
    let disc: Vec<_> = link_events
        .iter()
        .filter_map(|e| match e.kind {
            LinkEventKind::Discrepancy {
                pair,
                function,
                a,
                b,
            } => Some((e.at, pair.0, function, a, b)),
            _ => None,
        })
        .collect();
    let moving = point(PointPosition::Moving).encode(bid);
    let first_moving = (0..2)
        .filter_map(|bus| net.wire(bus, bid).into_iter().find(|x| x.1 == moving))
        .map(|x| x.0)
        .min()
        .unwrap();
    let a_latest = from_a.iter().rfind(|(t, _)| *t <= first_moving).unwrap().1;
    assert_eq!(
        disc,
        [(
            first_moving + Duration::from_millis(100),
            0,
            state_function(POINT_PORT, objects::POINT, 1),
            a_latest,
            moving,
        )]
    );

    // Bus 1: the master's port failed at the silence limit and came back; bus 2 saw nothing.
    let port = |p: u8| -> Vec<(Instant, PortState, PortReason)> {
        link_events
            .iter()
            .filter_map(|e| match e.kind {
                LinkEventKind::Port {
                    port: x,
                    to,
                    reason,
                    ..
                } if x == p => Some((e.at, to, reason)),
                _ => None,
            })
            .collect()
    };
    let p0 = port(0);
    let failed = p0.iter().find(|e| e.1 == PortState::Failed).unwrap();
    assert!(failed.0 > CUT && failed.0 <= CUT + CONSUMER + Duration::from_millis(1));
    assert_eq!(p0.last().unwrap().1, PortState::Ok);
    assert!(p0.last().unwrap().0 > REPAIR);
    assert!(port(1).is_empty());
    // Reachability over the railway senders: each board heard on bus 2 only, then both.
    for node in [TURNOUT_A, TURNOUT_B, SIGNAL] {
        let reach: Vec<[bool; 2]> = link_events
            .iter()
            .filter_map(|e| match e.kind {
                LinkEventKind::Reach { node: x, heard } if x == n(node) => Some(heard),
                _ => None,
            })
            .collect();
        assert_eq!(
            reach,
            [[true, true], [false, true], [true, true]],
            "node {node}"
        );
    }
    let link = &net.sim.device(net.master).link;
    assert_eq!(link.merger().stats().evicted, 0);
}
