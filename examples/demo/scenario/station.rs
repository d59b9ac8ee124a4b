//! The station: four dual-bus racks, each with its strong and weak interlocking computer and
//! its A/B board pairs, on one simulated network.

use super::board::{board, spare, BoardDev, BoardEvent, Parts};
use super::field::{Kind, Shared};
use super::interlocking::{IlEvent, Interlocking, Route};
use super::scheme::Scheme;
use super::{BITRATE, BOARD_HB, CONSUMER, LSS_PERIOD, MASTER_HB, MASTER_TIMEOUT, SYNC};
use duocan::cia305::LssAddress;
use duocan::eds::Description;
use duocan::machine::StationEvent;
use duocan::master::{
    objects, ExpectedIdentity, Master, MasterConfig, MasterSdoClient, SlaveConfig,
};
use duocan::node::LssNodeEvent;
use duocan::od::{comm, ObjectDictionary};
use duocan::sdo::DEFAULT_LIMIT;
use duocan::sim::{BusConfig, BusId, DevId, DeviceRef, SimNetwork};
use duocan::{Id, Instant, NmtState, NodeConfig, NodeId};
use duocan_redundancy::supervisor::audit::AuditRecord;
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::PairSpec;
use duocan_redundancy::{
    DualBus, DualBusConfig, LinkMode, LogicalNetwork, Member, SupervisedStation, Supervisor,
    SupervisorConfig,
};
use std::rc::Rc;

/// The strong master (priority 0) and the weak one (priority 1).
pub const STRONG: usize = 0;
/// The weak master.
pub const WEAK: usize = 1;
/// Names of the two computers.
pub const MASTER_NAMES: [&str; 2] = ["strong master", "weak master"];

/// Node-ID of a master on every rack: 1 (strong), 2 (weak).
pub fn master_node(which: usize) -> NodeId {
    NodeId::must(which as u8 + 1)
}
/// Node-ID of a pair member: A boards 0x11…, B boards 0x21….
pub fn board_node(pair: usize, m: Member) -> NodeId {
    let base = match m {
        Member::A => 0x11,
        Member::B => 0x21,
    };
    NodeId::must(base + pair as u8)
}

/// What a rack is.
pub struct RackSpec<S: Scheme> {
    /// "turnout rack".
    pub name: &'static str,
    /// Bus name prefix: "turnout" gives buses turnout1 and turnout2.
    pub short: &'static str,
    /// The field devices of its pairs.
    pub kind: Kind,
    /// Its identifier scheme.
    pub scheme: S,
    /// Board pairs.
    pub pairs: usize,
    /// The interlocking's commands to this rack.
    pub schedule: Rc<Vec<Route>>,
    /// The boards' EDS: each board's dictionary.
    pub eds: Rc<Description>,
    /// The rack's DCF: how the masters configure each of its boards.
    pub dcf: Rc<Description>,
}

/// A rack built on the network.
pub struct Rack<S: Scheme> {
    spec: Rc<RackSpec<S>>,
    buses: [BusId; 2],
    masters: [DevId<Interlocking<S>>; 2],
    boards: Vec<[DevId<BoardDev<S>>; 2]>,
    /// What each pair's boards are made of (its field device; a spare's too).
    parts: Vec<Parts<S>>,
}

fn master<S: Scheme>(spec: &RackSpec<S>, which: usize, now: Instant) -> Interlocking<S> {
    let id = master_node(which);
    let identity = comm::Identity {
        device_type: 0x0001_0000 | 302,
        vendor: 0x0000_D0CA,
        product: 0x1C,
        revision: 1,
        serial: 0x100 + which as u32,
    };
    let mut od = objects::master_dictionary(id.raw(), identity);
    spec.scheme.fit_dictionary(&mut od, id);
    let sdo = MasterSdoClient::with_limit(DEFAULT_LIMIT).with_channels(spec.scheme.channels());
    let m = Master::with_parts(
        NodeConfig::master(id),
        od,
        spec.scheme.clone(),
        sdo,
        MasterConfig::new(),
    )
    .expect("the master dictionary has the CiA 302 objects");
    let other = master_node(1 - which);
    // Board replacement by LSS: the active master looks for a board without node-ID while a
    // pair slot is vacant.
    let cfg = SupervisorConfig::new(which as u8, id, MASTER_HB, MASTER_TIMEOUT, SYNC)
        .with_peer(1 - which as u8, other)
        .with_lss(LSS_PERIOD);
    let mut sup = Supervisor::new(m, cfg, now);
    let mut boards = vec![];
    // Every slot expects a board of the DCF's vendor, product and revision, any serial number
    // (a spare has its own); the master checks it at each boot-up, and LSS gives a board
    // without node-ID the slot whose identity it has.
    let info = &spec.dcf.device_info;
    let expected = ExpectedIdentity {
        vendor: info.vendor_number.unwrap_or(0),
        product: info.product_number.unwrap_or(0),
        revision: info.revision_number.unwrap_or(0),
        ..ExpectedIdentity::default()
    };
    for p in 0..spec.pairs {
        let (a, b) = (board_node(p, Member::A), board_node(p, Member::B));
        let cfg = |n| SlaveConfig::from_dcf(n, &spec.dcf).identity(expected);
        sup.add_pair_with(now, PairSpec::new(a, b, BOARD_HB, CONSUMER), cfg(a), cfg(b))
            .expect("room for the rack's pairs");
        boards.extend([a, b]);
    }
    let link = DualBus::with_classifier(
        DualBusConfig::with_guard_period(LinkMode::ActiveActive, BOARD_HB),
        spec.scheme.clone(),
    );
    let net = LogicalNetwork::new(
        SupervisedStation::new(link, sup).expect("the layer holds the rack's pairs"),
    );
    Interlocking::new(
        net,
        spec.scheme.clone(),
        spec.kind,
        &boards,
        spec.schedule.clone(),
        now,
    )
    .expect("the master has an RPDO for every mirrored board PDO")
}

impl<S: Scheme> Rack<S> {
    /// Builds the rack on `sim`: two buses, both masters and every board, powered on at zero.
    pub fn build(sim: &mut SimNetwork, spec: RackSpec<S>, fields: Vec<Shared>) -> Rc<Self> {
        let spec = Rc::new(spec);
        let buses =
            [1, 2].map(|i| sim.add_bus(BusConfig::new(format!("{}{i}", spec.short), BITRATE)));
        let t0 = Instant::ZERO;
        let masters = [STRONG, WEAK].map(|w| {
            sim.add_device(
                format!("{} {}", spec.short, MASTER_NAMES[w]),
                master(&spec, w, t0),
                &buses,
            )
            .expect("two ports")
        });
        let parts: Vec<Parts<S>> = fields
            .into_iter()
            .map(|field| Parts {
                scheme: spec.scheme.clone(),
                eds: spec.eds.clone(),
                field,
                guard: BOARD_HB,
            })
            .collect();
        let boards = (0..spec.pairs)
            .map(|p| {
                [Member::A, Member::B].map(|m| {
                    sim.add_device(
                        format!("{} {m}", spec.kind.label(p)),
                        board(&parts[p], board_node(p, m), t0),
                        &buses,
                    )
                    .expect("two ports")
                })
            })
            .collect();
        Rc::new(Rack {
            spec,
            buses,
            masters,
            boards,
            parts,
        })
    }

    fn board(&self, pair: usize, m: Member) -> DevId<BoardDev<S>> {
        self.boards[pair][m as usize]
    }
}

/// A rack without its scheme type: what the scenario and the analysis need.
pub trait RackView {
    /// "turnout rack".
    fn name(&self) -> &'static str;
    /// Its scheme's name.
    fn scheme_name(&self) -> &'static str;
    /// Its field devices.
    fn kind(&self) -> Kind;
    /// Bus 1 and bus 2.
    fn buses(&self) -> [BusId; 2];
    /// Board pairs.
    fn pairs(&self) -> usize;
    /// The commands of the route schedule.
    fn schedule(&self) -> &[Route];
    /// A master's device.
    fn master_dev(&self, which: usize) -> DeviceRef;
    /// A board's device.
    fn board_dev(&self, pair: usize, m: Member) -> DeviceRef;
    /// What a master's interlocking did and heard.
    fn master_events<'a>(&self, sim: &'a SimNetwork, which: usize) -> &'a [(Instant, IlEvent)];
    /// What a board did.
    fn board_events(&self, sim: &SimNetwork, pair: usize, m: Member) -> Vec<(Instant, BoardEvent)>;
    /// A master's status table.
    fn status(&self, sim: &SimNetwork, which: usize, now: Instant) -> String;
    /// A master's role.
    fn role(&self, sim: &SimNetwork, which: usize) -> MasterRole;
    /// A master's audit trail.
    fn audit(&self, sim: &SimNetwork, which: usize) -> Vec<AuditRecord>;
    /// The active member of `pair` in a master's table.
    fn active_member(&self, sim: &SimNetwork, which: usize, pair: usize) -> Option<Member>;
    /// Commands a master has not seen answered.
    fn unanswered(&self, sim: &SimNetwork, which: usize) -> usize;
    /// A board's NMT state (what it last was if powered off; initialising while it has no
    /// node-ID).
    fn board_state(&self, sim: &SimNetwork, pair: usize, m: Member) -> NmtState;
    /// A board's identity as its LSS slave has it, and its node-ID (`None`: not configured).
    fn board_lss(&self, sim: &SimNetwork, pair: usize, m: Member) -> (LssAddress, Option<NodeId>);
    /// An unsigned entry (up to 32 bits) of a board's dictionary, as the board holds it now.
    fn board_value(
        &self,
        sim: &SimNetwork,
        pair: usize,
        m: Member,
        index: u16,
        sub: u8,
    ) -> Option<u32>;
    /// The node-ID of a board.
    fn board_node(&self, pair: usize, m: Member) -> NodeId;
    /// The boot-up / heartbeat identifier of `node`.
    fn heartbeat_id(&self, node: NodeId) -> Id;
    /// The identifier of the SDO requests to `node`.
    fn sdo_request_id(&self, node: NodeId) -> Id;
    /// The NMT identifier.
    fn nmt_id(&self) -> Id;
    /// The SYNC identifier.
    fn sync_id(&self) -> Id;
    /// Plans a change of a track circuit (a train) at `at`.
    fn field_set(&self, pair: usize, at: Instant, code: u8);
    /// Powers a master on again as a new computer (it boots and negotiates).
    fn revive_master(&self, sim: &mut SimNetwork, which: usize, now: Instant);
    /// A board stops running by itself: its application puts it in `state` (it announces it
    /// in a heartbeat at once and goes on beating).
    fn stop_board(
        &self,
        sim: &mut SimNetwork,
        pair: usize,
        m: Member,
        state: NmtState,
        now: Instant,
    );
    /// Puts a spare board with serial number `serial` in a board's place, powered on without
    /// node-ID (LSS gives it one, then it boots and is configured).
    fn plug_spare(&self, sim: &mut SimNetwork, pair: usize, m: Member, serial: u32, now: Instant);
}

impl<S: Scheme> RackView for Rack<S> {
    fn name(&self) -> &'static str {
        self.spec.name
    }
    fn scheme_name(&self) -> &'static str {
        S::NAME
    }
    fn kind(&self) -> Kind {
        self.spec.kind
    }
    fn buses(&self) -> [BusId; 2] {
        self.buses
    }
    fn pairs(&self) -> usize {
        self.spec.pairs
    }
    fn schedule(&self) -> &[Route] {
        &self.spec.schedule
    }
    fn master_dev(&self, which: usize) -> DeviceRef {
        self.masters[which].erased()
    }
    fn board_dev(&self, pair: usize, m: Member) -> DeviceRef {
        self.board(pair, m).erased()
    }
    fn master_events<'a>(&self, sim: &'a SimNetwork, which: usize) -> &'a [(Instant, IlEvent)] {
        sim.events(self.masters[which])
    }
    fn board_events(&self, sim: &SimNetwork, pair: usize, m: Member) -> Vec<(Instant, BoardEvent)> {
        sim.events(self.board(pair, m))
            .iter()
            .filter_map(|(at, e)| match e {
                StationEvent::Machine(LssNodeEvent::Node(b)) => Some((*at, *b)),
                _ => None,
            })
            .collect()
    }
    fn status(&self, sim: &SimNetwork, which: usize, now: Instant) -> String {
        sim.device(self.masters[which]).net.status(now).to_string()
    }
    fn role(&self, sim: &SimNetwork, which: usize) -> MasterRole {
        sim.device(self.masters[which]).net.role()
    }
    fn audit(&self, sim: &SimNetwork, which: usize) -> Vec<AuditRecord> {
        let net = &sim.device(self.masters[which]).net;
        net.supervisor().audit().iter().copied().collect()
    }
    fn active_member(&self, sim: &SimNetwork, which: usize, pair: usize) -> Option<Member> {
        let net = &sim.device(self.masters[which]).net;
        net.pairs().nth(pair).and_then(|(_, p)| p.active)
    }
    fn unanswered(&self, sim: &SimNetwork, which: usize) -> usize {
        sim.device(self.masters[which]).unanswered()
    }
    fn board_state(&self, sim: &SimNetwork, pair: usize, m: Member) -> NmtState {
        let c = &sim.device(self.board(pair, m)).machine;
        c.node().map_or(NmtState::Initialising, |b| b.state())
    }
    fn board_lss(&self, sim: &SimNetwork, pair: usize, m: Member) -> (LssAddress, Option<NodeId>) {
        let lss = sim.device(self.board(pair, m)).machine.lss();
        (lss.address(), lss.node_id())
    }
    fn board_value(
        &self,
        sim: &SimNetwork,
        pair: usize,
        m: Member,
        index: u16,
        sub: u8,
    ) -> Option<u32> {
        let c = &sim.device(self.board(pair, m)).machine;
        c.node()?.od().get_u32(index, sub)
    }
    fn board_node(&self, pair: usize, m: Member) -> NodeId {
        board_node(pair, m)
    }
    fn heartbeat_id(&self, node: NodeId) -> Id {
        self.spec.scheme.heartbeat(node)
    }
    fn sdo_request_id(&self, node: NodeId) -> Id {
        (self.spec.scheme.channels())(node).request
    }
    fn nmt_id(&self) -> Id {
        self.spec.scheme.nmt()
    }
    fn sync_id(&self) -> Id {
        self.spec.scheme.sync_id()
    }
    fn field_set(&self, pair: usize, at: Instant, code: u8) {
        self.parts[pair].field.borrow_mut().set(at, code);
    }
    fn revive_master(&self, sim: &mut SimNetwork, which: usize, now: Instant) {
        let dev = master(&self.spec, which, now);
        sim.replace(self.masters[which], dev).expect("same ports");
    }
    fn stop_board(
        &self,
        sim: &mut SimNetwork,
        pair: usize,
        m: Member,
        state: NmtState,
        now: Instant,
    ) {
        if let Some(b) = sim.device_mut(self.board(pair, m)).machine.node_mut() {
            b.set_state(now, state);
        }
    }
    fn plug_spare(&self, sim: &mut SimNetwork, pair: usize, m: Member, serial: u32, now: Instant) {
        let dev = spare(&self.parts[pair], serial, now);
        sim.replace(self.board(pair, m), dev).expect("same ports");
    }
}
