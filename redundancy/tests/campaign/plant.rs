//! The plant: a supervised dual-bus network with the cyclic traffic CANopen really carries.
//!
//! Two masters (strong 0x01, weak 0x02; heartbeat 20 ms, master timeout 50 ms, SYNC every
//! 10 ms and TIME every 100 ms from the active one), `pairs` A/B board pairs (A = 0x10 + i,
//! B = 0x50 + i; heartbeat 20 ms once configured, consumer time 50 ms), each board answering
//! every SYNC with TPDO1 and sending TPDO2 every 10 ms, both with data that never changes (only
//! the running board of a pair sends them), an observer node 0x7A on both buses, in no
//! pair, that checks what a plain slave receives, and (in runs with slow transmitters) a node
//! 0x7B that is not duocan ([`crate::foreign`]). The active master reads the slaves' dictionaries
//! by SDO meanwhile ([`crate::sdo`]). Every device's link is tapped for the oracle
//! ([`crate::tap`]); every device's clock can be stepped, jumped or run at a wrong rate
//! ([`Clocked`], [`DeviceClock`]).

use crate::foreign::{Foreign, FOREIGN};
use crate::oracle::Oracle;
use crate::sdo::{Ledger, Sdo, SEGMENTED, STRING};
use crate::tap::Tap;
use duocan::machine::PortRequest;
use duocan::master::{objects, Master, MasterConfig};
use duocan::od::{comm, Access, DataType, DefaultValue, DynamicDictionary, ObjectDef};
use duocan::pdo::params;
use duocan::sim::{BusConfig, BusId, DevId, SimNetwork};
use duocan::{Device, Duration, Frame, Instant, Node, NodeConfig, NodeId, PortStatus, Station};
use duocan_redundancy::{
    DualBus, DualBusConfig, LinkMode, PairSpec, SupervisedStation, Supervisor, SupervisorConfig,
};
use std::cell::RefCell;
use std::rc::Rc;

pub const STRONG: u8 = 1;
pub const WEAK: u8 = 2;
pub const OBSERVER: u8 = 0x7A;
pub const SLAVE_HB: Duration = Duration::from_millis(20);
pub const CONSUMER: Duration = Duration::from_millis(50);
pub const MASTER_HB: Duration = Duration::from_millis(20);
pub const MASTER_TIMEOUT: Duration = Duration::from_millis(50);
pub const SYNC: Duration = Duration::from_millis(10);
/// Masters' clocks read this far ahead of the simulated time from their start, so that the
/// campaign can step them back by hours.
pub const MASTER_CLOCK: Duration = Duration::from_secs(10 * 3600);
/// The application object the boards map into their TPDOs: values that never change.
const APP: u16 = 0x2000;

pub fn a(i: u8) -> u8 {
    0x10 + i
}
pub fn b(i: u8) -> u8 {
    0x50 + i
}

pub type MasterStation = Station<Tap, Supervisor<DynamicDictionary>>;
pub type SlaveStation = Station<Tap, Node<DynamicDictionary>>;
/// A master: its station on its clock, with the SDO application ([`crate::sdo`]).
pub type MasterDev = Sdo;
pub type SlaveDev = Clocked<SlaveStation>;

/// A device's timer clock: its reading of simulated time `t` is `t` plus an offset that was
/// `offset` µs at `since` and grows by `ppm` parts per million of the time since (a crystal off
/// its rate, a virtual machine whose clock is throttled). The device and the oracle hold
/// copies of it, changed together.
///
/// Before `since` it ran at `before` ppm: a frame received then and handed over after a rate
/// change (a port running behind) keeps the stamp the clock gave it when it arrived, not one
/// the new rate would have given (seed 8115: a master's clock went 10 % slow while its port ran
/// 67 ms behind; read at the new rate, its late copies' stamps moved 4.9 ms and missed their
/// twins). One segment back is enough: rate changes come seconds apart, lags under 0.1 s.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceClock {
    offset: i64,
    ppm: i32,
    before: i32,
    since: Instant,
}

impl DeviceClock {
    /// A clock `by` ahead of the simulated time, at the right rate.
    pub fn ahead(by: Duration) -> Self {
        DeviceClock {
            offset: by.as_micros() as i64,
            ..DeviceClock::default()
        }
    }
    fn offset_at(&self, t: Instant) -> i64 {
        let run = t.as_micros() as i128 - self.since.as_micros() as i128;
        let ppm = if run < 0 { self.before } else { self.ppm };
        (self.offset as i128 + run * ppm as i128 / 1_000_000) as i64
    }
    /// Its reading at simulated time `t`.
    pub fn read(&self, t: Instant) -> Instant {
        Instant::from_micros(t.as_micros().saturating_add_signed(self.offset_at(t)))
    }
    /// The simulated time at which it reads `l` (0 if before the simulation began), at its
    /// current rate (asked for now and for deadlines, never for the past).
    pub fn back(&self, l: Instant) -> Instant {
        // l = t + offset + (t − since)·ppm/10⁶, so t − since = (l − offset − since)·10⁶/(10⁶ + ppm).
        let since = self.since.as_micros() as i128;
        let x = l.as_micros() as i128 - self.offset as i128 - since;
        let t = since + x * 1_000_000 / (1_000_000 + self.ppm as i128);
        Instant::from_micros(t.clamp(0, u64::MAX as i128) as u64)
    }
    /// Moved by `by` µs (negative: back) at simulated time `now`, its rate kept.
    pub fn shift(&mut self, now: Instant, by: i64) {
        self.offset = self.offset_at(now) + by;
        self.since = now;
        self.before = self.ppm;
    }
    /// Running `ppm` parts per million fast (negative: slow) from `now` on; zero: at the right
    /// rate again, keeping what it gained or lost.
    pub fn run_at(&mut self, now: Instant, ppm: i32) {
        self.offset = self.offset_at(now);
        self.since = now;
        self.before = self.ppm;
        self.ppm = ppm;
    }
}

#[test]
fn a_device_clock_reads_back_the_instant_it_read_and_runs_at_its_rate() {
    let t = Instant::from_secs;
    let mut c = DeviceClock::ahead(Duration::from_secs(10));
    c.run_at(t(2), -100_000);
    // 10 % slow: 10 s later it has lost 1 s.
    assert_eq!(c.read(t(12)), t(21));
    c.shift(t(12), -500_000);
    c.run_at(t(13), 0);
    assert_eq!(c.read(t(14)), Instant::from_millis(22_400));
    // A moment before the last change reads as the clock read it then (10 % slow).
    assert_eq!(
        c.read(Instant::from_millis(12_900)),
        Instant::from_millis(21_310)
    );
    for ppm in [-100_000, -100, 0, 100, 50_000] {
        let mut c = DeviceClock::ahead(Duration::from_secs(3));
        c.run_at(t(1), ppm);
        for us in [1_000_000, 1_234_567, 9_999_999, 60_000_000] {
            let s = Instant::from_micros(us);
            let back = c.back(c.read(s)).as_micros() as i64;
            assert!(
                (back - us as i64).abs() <= 1,
                "{ppm} ppm at {us} µs: {back}"
            );
        }
    }
}

/// A device on a [`DeviceClock`] the campaign may change: a step back (the offset falls), a
/// jump ahead (it rises), a wrong rate. For a step or a jump the device is told at once, with a
/// timeout at its new reading, as a driver that notices its clock changed does; a wrong rate
/// goes unnoticed, as it does in a device.
///
/// A frame that arrived before the change and is handed over after it keeps its timestamp as
/// the layer keeps its own times: moved back with a step back (the new clock's reading of that
/// moment), unmoved by a jump ahead (a jump is time that passed).
pub struct Clocked<T> {
    pub inner: T,
    clock: DeviceClock,
    /// The latest simulated time it was given.
    last: Instant,
    /// The last jump ahead: when (simulated time), and the clock before it.
    jumped: Option<(Instant, DeviceClock)>,
}

impl<T: Device> Clocked<T> {
    /// `inner`, on a clock `ahead` of the simulated time.
    pub fn new(inner: T, ahead: Duration) -> Self {
        Clocked {
            inner,
            clock: DeviceClock::ahead(ahead),
            last: Instant::ZERO,
            jumped: None,
        }
    }
    /// Its clock's reading at simulated time `t`.
    pub fn read(&self, t: Instant) -> Instant {
        self.clock.read(t)
    }
    /// Its clock runs `ppm` parts per million off from simulated time `now` on.
    pub fn run_at(&mut self, now: Instant, ppm: i32) {
        self.clock.run_at(now, ppm);
    }
    /// The clock moves by `by` µs (negative: back) at simulated time `now`.
    pub fn shift(&mut self, now: Instant, by: i64) {
        // The old clock's reading of this instant first: the device measures a step back
        // from the latest time it was given, so it measures all of it, as the stamps of the
        // frames in flight are moved (by all of it). Told only after its last input, it would
        // take the time since then off the step, and those stamps would disagree with every
        // time it holds by that much.
        let before = self.read(now);
        self.inner.handle_timeout(before);
        if by > 0 {
            self.jumped = Some((now, self.clock));
        }
        self.clock.shift(now, by);
        self.last = now;
        let t = self.read(now);
        self.inner.handle_timeout(t);
    }
}

impl<T: Device> Device for Clocked<T> {
    type Event = T::Event;
    fn port_count(&self) -> usize {
        self.inner.port_count()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.last = now;
        let t = self.read(now);
        self.inner.handle_rx(t, port, frame);
    }
    fn handle_rx_at(&mut self, now: Instant, port: usize, frame: &Frame, at: Instant) {
        self.last = now;
        let clock = match self.jumped {
            Some((j, before)) if at < j => before,
            _ => self.clock,
        };
        let t = self.read(now);
        let at = clock.read(at).min(t);
        self.inner.handle_rx_at(t, port, frame, at);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.last = now;
        let t = self.read(now);
        self.inner.handle_port_status(t, port, status);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.last = now;
        let t = self.read(now);
        self.inner.handle_timeout(t);
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.inner.poll_transmit()
    }
    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.inner.poll_port_request()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        // A deadline its clock put before now (a step back) is due now.
        self.inner
            .poll_timeout()
            .map(|d| self.clock.back(d).max(self.last))
    }
    fn poll_event(&mut self) -> Option<T::Event> {
        self.inner.poll_event()
    }
}

/// The plant's settings.
#[derive(Clone, Copy, Debug)]
pub struct Params {
    pub seed: u64,
    pub pairs: u8,
    /// A quiet network: no SYNC, no TIME but at a takeover, no process data; heartbeats and
    /// the masters' SDO reads only (what the lag meter, the silence rules and the one-bus
    /// rule's idle witness must also work with).
    pub quiet: bool,
    /// With a node that is not duocan ([`crate::foreign`]).
    pub foreign: bool,
    /// The weak master and [`CROSSED_BOARD`] cabled crossed (an installation error: their
    /// connector for bus 1 on bus 2 and the other way round; see [`CROSSED`]).
    pub crossed: bool,
}

/// The board cabled crossed on a crossed plant (the B member of the first pair).
pub const CROSSED_BOARD: u8 = 0x50;
/// The devices cabled crossed on a crossed plant: the weak master and one board, so that a
/// crossed device talks to straight ones and to another crossed one.
pub const CROSSED: [u8; 2] = [WEAK, CROSSED_BOARD];

impl Default for Params {
    fn default() -> Self {
        Params {
            seed: 1,
            pairs: 3,
            quiet: false,
            foreign: false,
            crossed: false,
        }
    }
}

pub struct Plant {
    pub p: Params,
    pub sim: SimNetwork,
    pub buses: [BusId; 2],
    pub oracle: Rc<RefCell<Oracle>>,
    /// The masters' SDO transfers.
    pub sdo: Rc<RefCell<Ledger>>,
    pub masters: [DevId<MasterDev>; 2],
    /// (node-ID, device, oracle node).
    pub slaves: Vec<(u8, DevId<SlaveDev>, usize)>,
    pub master_nodes: [usize; 2],
    /// The node that is not duocan, if any: (device, oracle node).
    pub foreign: Option<(DevId<Foreign>, usize)>,
}

fn link() -> DualBus {
    let config = DualBusConfig::with_guard_period(LinkMode::ActiveActive, SLAVE_HB);
    // `CAMPAIGN_NO_STALL=1`: layers without the transmit stall rule, as behind drivers that
    // report no transmit outcomes (a diagnosis, not a promise: slow and drifting transmitters
    // then put copies further apart than the window).
    if std::env::var("CAMPAIGN_NO_STALL").is_ok_and(|v| v == "1") {
        let health = config.health.with_tx_stall(duocan::Duration::ZERO);
        return DualBus::new(config.with_health(health));
    }
    DualBus::new(config)
}

/// A master station built at simulated time `at`.
pub fn master_station(
    p: &Params,
    id: u8,
    at: Instant,
    node: usize,
    oracle: &Rc<RefCell<Oracle>>,
    ledger: &Rc<RefCell<Ledger>>,
) -> MasterDev {
    let now = at + MASTER_CLOCK;
    oracle.borrow_mut().clock[node] = DeviceClock::ahead(MASTER_CLOCK);
    let nid = NodeId::must(id);
    let od = objects::master_dictionary(id, comm::Identity::default());
    let master = Master::new(nid, od, MasterConfig::new()).unwrap();
    let peer = if id == STRONG { WEAK } else { STRONG };
    let sync = if p.quiet { Duration::ZERO } else { SYNC };
    let mut cfg = SupervisorConfig::new(id - 1, nid, MASTER_HB, MASTER_TIMEOUT, sync)
        .with_peer(peer - 1, NodeId::must(peer));
    if !p.quiet {
        cfg.time_period = Duration::from_millis(100);
    }
    let mut sup = Supervisor::new(master, cfg, now);
    for i in 0..p.pairs {
        sup.add_pair(
            now,
            PairSpec::new(NodeId::must(a(i)), NodeId::must(b(i)), SLAVE_HB, CONSUMER),
        )
        .unwrap();
    }
    let st = SupervisedStation::new(link(), sup).unwrap().into_station();
    let dev = Clocked::new(
        Station::new(Tap::new(st.link, node, oracle.clone()), st.machine),
        MASTER_CLOCK,
    );
    let slaves = (0..p.pairs).flat_map(|i| [a(i), b(i)]).chain([OBSERVER]);
    Sdo::new(dev, id, slaves.collect(), at, ledger)
}

/// A board's dictionary: the standard one, two constants, TPDO1 on SYNC and TPDO2 every 10 ms
/// (no TPDO on a quiet network).
fn board_dictionary(id: u8, quiet: bool) -> DynamicDictionary {
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
    od.insert_all(&[
        ObjectDef::u8(APP, 0, Access::Const, 2),
        ObjectDef::u16(APP, 1, Access::Rw, 0x5AA5).mappable(),
        ObjectDef::u16(APP, 2, Access::Rw, 0x0FF0 + id as u16).mappable(),
        // Read by the masters' segmented SDO uploads.
        ObjectDef::bytes(SEGMENTED.0, SEGMENTED.1, DataType::VisibleString, 32)
            .access(Access::Const)
            .default(DefaultValue::Bytes(STRING)),
    ])
    .unwrap();
    if quiet {
        return od;
    }
    od.insert_all(&params::tpdo_comm(
        1,
        params::predefined_tpdo_cob(1),
        1,
        0,
        0,
    ))
    .unwrap();
    od.insert_all(&params::tpdo_mapping::<9>(1, &[0x2000_0110]))
        .unwrap();
    od.insert_all(&params::tpdo_comm(
        2,
        params::predefined_tpdo_cob(2),
        255,
        0,
        10,
    ))
    .unwrap();
    od.insert_all(&params::tpdo_mapping::<9>(2, &[0x2000_0210]))
        .unwrap();
    od
}

/// A board (or the observer) built and booted at `now`.
pub fn slave_station(
    p: &Params,
    id: u8,
    now: Instant,
    node: usize,
    oracle: &Rc<RefCell<Oracle>>,
) -> SlaveDev {
    let mut n = Node::new(
        NodeConfig::slave(NodeId::must(id)),
        board_dictionary(id, p.quiet),
    );
    if id == OBSERVER {
        // Not configured by the masters: it beats by itself.
        n.set(
            now,
            comm::HEARTBEAT_PRODUCER,
            0,
            SLAVE_HB.as_millis() as u16,
        )
        .unwrap();
    }
    n.boot(now);
    oracle.borrow_mut().clock[node] = DeviceClock::default();
    Clocked::new(
        Station::new(Tap::new(link(), node, oracle.clone()), n),
        Duration::ZERO,
    )
}

impl Plant {
    pub fn new(p: Params) -> Plant {
        let mut sim = SimNetwork::new(p.seed);
        sim.set_recording(false);
        let buses = [
            sim.add_bus(BusConfig::new("can1", 1_000_000)),
            sim.add_bus(BusConfig::new("can2", 1_000_000)),
        ];
        let oracle = Rc::new(RefCell::new(Oracle::default()));
        // A device's ports in order: bus 1 and bus 2, or the other way round if it is
        // cabled crossed (its oracle node says so, to map its ports to the buses).
        let crossed = [buses[1], buses[0]];
        let wires = |id: u8, node: usize| {
            if p.crossed && CROSSED.contains(&id) {
                oracle.borrow_mut().nodes[node].swapped = true;
                &crossed
            } else {
                &buses
            }
        };
        let sdo = Rc::new(RefCell::new(Ledger::default()));
        let mut masters = vec![];
        let mut master_nodes = [0; 2];
        for (k, id) in [STRONG, WEAK].into_iter().enumerate() {
            let dev_index = sim.device_count();
            let node = oracle.borrow_mut().add(&format!("m{id}"), dev_index, true);
            master_nodes[k] = node;
            let d = sim
                .add_device(
                    format!("m{id}"),
                    master_station(&p, id, Instant::ZERO, node, &oracle, &sdo),
                    wires(id, node),
                )
                .unwrap();
            masters.push(d);
        }
        let mut slaves = vec![];
        let ids: Vec<u8> = (0..p.pairs)
            .flat_map(|i| [a(i), b(i)])
            .chain([OBSERVER])
            .collect();
        for id in ids {
            let dev_index = sim.device_count();
            let node = oracle
                .borrow_mut()
                .add(&format!("s{id:#x}"), dev_index, false);
            if id != OBSERVER {
                oracle.borrow_mut().members.push(id);
            }
            let d = sim
                .add_device(
                    format!("s{id:#x}"),
                    slave_station(&p, id, Instant::ZERO, node, &oracle),
                    wires(id, node),
                )
                .unwrap();
            slaves.push((id, d, node));
        }
        let foreign = p.foreign.then(|| {
            let name = format!("f{FOREIGN:#x}");
            let node = oracle.borrow_mut().add_foreign(&name, sim.device_count());
            let f = Foreign::new(Instant::ZERO, node, oracle.clone(), !p.quiet);
            (sim.add_device(name, f, &buses).unwrap(), node)
        });
        let o = oracle.clone();
        sim.set_rx_hook(Some(Box::new(move |note| {
            // A bridge's copy is a copy of the frame it copied (the oracle judges it so).
            let (sender, serial) = match note.bridged {
                Some(b) => (b.sender.device.index(), b.serial),
                None => (note.sender.device.index(), note.serial),
            };
            o.borrow_mut().arriving(
                note.receiver.device.index(),
                sender,
                serial,
                note.receiver.port,
                note.wire,
                &note.frame,
                note.bridged.is_some(),
            );
        })));
        Plant {
            p,
            sim,
            buses,
            oracle,
            sdo,
            masters: [masters[0], masters[1]],
            slaves,
            master_nodes,
            foreign,
        }
    }

    pub fn slave(&self, id: u8) -> (DevId<SlaveDev>, usize) {
        let s = self.slaves.iter().find(|s| s.0 == id).expect("a slave");
        (s.1, s.2)
    }
    pub fn master(&self, id: u8) -> DevId<MasterDev> {
        self.masters[(id - 1) as usize]
    }
    pub fn sup(&self, id: u8) -> &Supervisor<DynamicDictionary> {
        &self.sim.device(self.master(id)).inner.machine
    }

    /// Rebuilds (reboots) master `id` at the current instant.
    pub fn reboot_master(&mut self, id: u8) {
        let d = self.master(id);
        let node = self.master_nodes[(id - 1) as usize];
        let now = self.sim.now();
        self.oracle
            .borrow_mut()
            .rebuilt(node, self.sim.frames_taken(d));
        self.sdo.borrow_mut().lives[(id - 1) as usize] += 1;
        let st = master_station(&self.p, id, now, node, &self.oracle, &self.sdo);
        self.sim.replace(d, st).unwrap();
    }
    /// Rebuilds (reboots) slave `id` at the current instant.
    pub fn reboot_slave(&mut self, id: u8) {
        let (d, node) = self.slave(id);
        let now = self.sim.now();
        self.oracle
            .borrow_mut()
            .rebuilt(node, self.sim.frames_taken(d));
        let st = slave_station(&self.p, id, now, node, &self.oracle);
        self.sim.replace(d, st).unwrap();
    }
}
