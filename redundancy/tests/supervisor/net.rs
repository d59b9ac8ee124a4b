//! A supervised dual-bus network on the simulator: a strong master (node 1, priority 0) and a
//! weak master (node 2, priority 1), each a `SupervisedStation`, and `pairs` A/B slave pairs
//! (A = 0x10 + i, B = 0x50 + i), every device on both 1 Mbit/s buses. Slaves are standard nodes
//! that boot at 0 with no heartbeat; the active master configures 0x1017. With
//! [`Params::fd`] the buses are CAN FD (the same nominal bit rate, a data bit rate), every
//! device FD-capable, and the members of the first pairs send FD process data on every SYNC
//! (see `fd_rig.rs`).
#![allow(dead_code)]

use crate::fd_rig::{process_data, Board, FdMaster, SyncProducer};
use crate::stepped::{ClockJump, ClockStep, Stepped};
use duocan::frame::FdFrame;
use duocan::machine::StationEvent;
use duocan::master::{objects, Master, MasterConfig};
use duocan::od::{comm, DynamicDictionary};
use duocan::sim::timing::fd_frame_duration;
use duocan::sim::{BusConfig, BusId, DevId, SimNetwork, TraceRecord, TxOutcome};
use duocan::{Duration, Frame, Id, Instant, NmtCommand, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::supervisor::flying_master::{FlyingEvent, MasterRole, MasterRoleChange};
use duocan_redundancy::supervisor::pairs::{PairsEvent, RoleChange};
use duocan_redundancy::PairSpec;
use duocan_redundancy::{
    DualBus, DualBusConfig, LinkMode, Member, PairId, SupervisedStation, Supervisor,
    SupervisorConfig, SupervisorEvent,
};

/// A master station, on a clock that may step back ([`Params::clock_step`]) or jump ahead
/// ([`Params::clock_jump`]).
pub type MasterDev = Stepped<FdMaster>;
pub type SlaveDev = Board;

pub const STRONG: u8 = 1;
pub const WEAK: u8 = 2;

#[derive(Clone, Copy, Debug)]
pub struct Params {
    pub seed: u64,
    pub pairs: u8,
    pub slave_hb: Duration,
    pub consumer: Duration,
    pub master_hb: Duration,
    pub master_timeout: Duration,
    pub sync: Duration,
    pub revertive_pairs: bool,
    pub revertive_master: bool,
    pub bitrate: u32,
    /// Start the weak master this much later (it then finds the strong one active).
    pub weak_start: Duration,
    /// Both masters' clocks read ahead until then, and step back (none: they read the
    /// simulated time).
    pub clock_step: Option<ClockStep>,
    /// This master's clock (node-ID) jumps ahead then (none: it reads the simulated time).
    pub clock_jump: Option<(u8, ClockJump)>,
    /// CAN FD buses and process data (none: classic buses, no FD frames).
    pub fd: Option<FdNet>,
}

/// The FD network of [`Params::fd`].
#[derive(Clone, Copy, Debug)]
pub struct FdNet {
    /// The data phase's bit rate (the nominal one is [`Params::bitrate`]).
    pub data_bitrate: u32,
    /// The members of pairs `0..producers` send a 64-byte FD frame on every SYNC.
    pub producers: u8,
}

impl Params {
    /// These parameters on FD buses with a data phase of `data_bitrate`, the members of the
    /// first `producers` pairs sending FD process data.
    pub fn on_fd(self, data_bitrate: u32, producers: u8) -> Params {
        Params {
            fd: Some(FdNet {
                data_bitrate,
                producers,
            }),
            ..self
        }
    }

    /// How long the FD process data of one SYNC occupies a bus (zero on classic buses): a
    /// frame of lower priority (a heartbeat, a boot-up, 0x700 + node) queued at a SYNC waits
    /// that long at most behind it.
    pub fn fd_burst(&self) -> Duration {
        self.fd.map_or(Duration::ZERO, |fd| {
            let one = fd_frame_duration(
                &process_data(0x7F, Instant::ZERO),
                self.bitrate,
                fd.data_bitrate,
            );
            Duration::from_micros(one.as_micros() * 2 * fd.producers as u64)
        })
    }
}

impl Default for Params {
    fn default() -> Self {
        Params {
            seed: 1,
            pairs: 4,
            slave_hb: Duration::from_millis(20),
            consumer: Duration::from_millis(50),
            master_hb: Duration::from_millis(20),
            master_timeout: Duration::from_millis(50),
            sync: Duration::from_millis(10),
            revertive_pairs: false,
            revertive_master: false,
            bitrate: 1_000_000,
            weak_start: Duration::ZERO,
            clock_step: None,
            clock_jump: None,
            fd: None,
        }
    }
}

pub fn a(i: u8) -> u8 {
    0x10 + i
}
pub fn b(i: u8) -> u8 {
    0x50 + i
}

pub struct SupNet {
    pub p: Params,
    pub sim: SimNetwork,
    pub buses: [BusId; 2],
    pub masters: [DevId<MasterDev>; 2],
    pub slaves: Vec<(u8, DevId<SlaveDev>)>,
}

fn link(p: &Params) -> DualBus {
    let mut link = DualBus::new(DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        p.slave_hb,
    ));
    link.set_port_fd(0, p.fd.is_some());
    link.set_port_fd(1, p.fd.is_some());
    link
}

/// A master built at simulated time `now` (at its clock's reading then).
pub fn master_station(p: &Params, id: u8, now: Instant) -> MasterDev {
    let step = p.clock_step.filter(|s| now < s.at);
    let jump = p
        .clock_jump
        .filter(|j| j.0 == id && now < j.1.at)
        .map(|j| j.1);
    let now = Stepped::<FdMaster>::reading(step, now);
    let nid = NodeId::must(id);
    let od = objects::master_dictionary(id, comm::Identity::default());
    let master = Master::new(nid, od, MasterConfig::new()).unwrap();
    let peer = if id == STRONG { WEAK } else { STRONG };
    let mut cfg = SupervisorConfig::new(id - 1, nid, p.master_hb, p.master_timeout, p.sync)
        .with_peer(peer - 1, NodeId::must(peer));
    cfg.pairs.revertive = p.revertive_pairs;
    cfg.flying.revertive = p.revertive_master;
    cfg.time_period = Duration::from_millis(100);
    let mut sup = Supervisor::new(master, cfg, now);
    for i in 0..p.pairs {
        sup.add_pair(
            now,
            PairSpec::new(
                NodeId::must(a(i)),
                NodeId::must(b(i)),
                p.slave_hb,
                p.consumer,
            ),
        )
        .unwrap();
    }
    if p.fd.is_some() {
        // Heartbeats only: CAN FD has no remote frames for node guarding.
        sup.check_fd().unwrap();
    }
    let station = FdMaster::new(SupervisedStation::new(link(p), sup).unwrap());
    match jump {
        Some(j) => Stepped::jumping(station, j),
        None => Stepped::new(station, step),
    }
}

pub fn slave_station(p: &Params, id: u8, now: Instant) -> SlaveDev {
    let mut node = Node::new(
        NodeConfig::slave(NodeId::must(id)),
        comm::standard_dictionary(id, comm::Identity::default()),
    );
    node.boot(now);
    let pair = (id - 0x10) % 0x40;
    let app = SyncProducer {
        id,
        produces: p.fd.is_some_and(|fd| pair < fd.producers),
    };
    Board::new(Station::new(link(p), node), app)
}

impl SupNet {
    pub fn new(p: Params) -> SupNet {
        let mut sim = SimNetwork::new(p.seed);
        let bus = |name| match p.fd {
            Some(fd) => BusConfig::new(name, p.bitrate).fd(fd.data_bitrate),
            None => BusConfig::new(name, p.bitrate),
        };
        let buses = [sim.add_bus(bus("can1")), sim.add_bus(bus("can2"))];
        let m1 = sim
            .add_device("strong", master_station(&p, STRONG, Instant::ZERO), &buses)
            .unwrap();
        let m2 = if p.weak_start.is_zero() {
            sim.add_device("weak", master_station(&p, WEAK, Instant::ZERO), &buses)
                .unwrap()
        } else {
            let d = sim
                .add_device("weak", master_station(&p, WEAK, Instant::ZERO), &buses)
                .unwrap();
            sim.power_off(d);
            let t = Instant::ZERO + p.weak_start;
            let pp = p;
            sim.at(t, move |sim| {
                sim.replace(d, master_station(&pp, WEAK, t)).unwrap();
            });
            d
        };
        let mut slaves = vec![];
        for i in 0..p.pairs {
            for id in [a(i), b(i)] {
                let d = sim
                    .add_device(
                        format!("s{id:#x}"),
                        slave_station(&p, id, Instant::ZERO),
                        &buses,
                    )
                    .unwrap();
                slaves.push((id, d));
            }
        }
        SupNet {
            p,
            sim,
            buses,
            masters: [m1, m2],
            slaves,
        }
    }

    pub fn slave(&self, id: u8) -> DevId<SlaveDev> {
        self.slaves.iter().find(|s| s.0 == id).unwrap().1
    }
    pub fn master(&self, id: u8) -> DevId<MasterDev> {
        self.masters[(id - 1) as usize]
    }
    pub fn sup(&self, id: u8) -> &Supervisor<DynamicDictionary> {
        self.sim.device(self.master(id)).sup()
    }

    /// Kills a slave at `t`.
    pub fn kill_slave_at(&mut self, id: u8, t: Instant) {
        let d = self.slave(id);
        self.sim.at(t, move |sim| sim.power_off(d));
    }
    /// Restarts a slave (fresh, booting) at `t`.
    pub fn revive_slave_at(&mut self, id: u8, t: Instant) {
        let d = self.slave(id);
        let p = self.p;
        self.sim.at(t, move |sim| {
            sim.replace(d, slave_station(&p, id, t)).unwrap();
        });
    }
    pub fn kill_master_at(&mut self, id: u8, t: Instant) {
        let d = self.master(id);
        self.sim.at(t, move |sim| sim.power_off(d));
    }
    pub fn revive_master_at(&mut self, id: u8, t: Instant) {
        let d = self.master(id);
        let p = self.p;
        self.sim.at(t, move |sim| {
            sim.replace(d, master_station(&p, id, t)).unwrap();
        });
    }

    pub fn sup_events(&self, id: u8) -> Vec<SupervisorEvent> {
        self.sim
            .events(self.master(id))
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Machine(m) => Some(m.clone()),
                _ => None,
            })
            .collect()
    }
    pub fn master_roles(&self, id: u8) -> Vec<MasterRoleChange> {
        self.sup_events(id)
            .into_iter()
            .filter_map(|e| match e {
                SupervisorEvent::FlyingMaster(FlyingEvent::Role(r)) => Some(r),
                _ => None,
            })
            .collect()
    }
    pub fn pair_roles(&self, id: u8, pair: u8) -> Vec<RoleChange> {
        self.sup_events(id)
            .into_iter()
            .filter_map(|e| match e {
                SupervisorEvent::Pairs(PairsEvent::Role(r)) if r.pair == PairId(pair) => Some(r),
                _ => None,
            })
            .collect()
    }
    pub fn active_member(&self, id: u8, pair: u8) -> Option<Member> {
        self.sup(id)
            .pair_supervisor()
            .pair(PairId(pair))
            .and_then(|p| p.active)
    }
    pub fn role(&self, id: u8) -> MasterRole {
        self.sup(id).role()
    }

    fn sender_node(&self, x: &duocan::sim::TxRecord) -> u8 {
        let idx = x.sender.device.index();
        if idx == self.masters[0].index() {
            STRONG
        } else if idx == self.masters[1].index() {
            WEAK
        } else {
            self.slaves
                .iter()
                .find(|s| s.1.index() == idx)
                .map(|s| s.0)
                .unwrap_or(0)
        }
    }

    /// Every delivered frame: (end, bus index, sender node-ID, frame).
    pub fn delivered(&self) -> Vec<(Instant, usize, u8, Frame)> {
        self.sim
            .trace()
            .iter()
            .filter_map(|r| match r {
                TraceRecord::Tx(x) if matches!(x.outcome, TxOutcome::Delivered { .. }) => {
                    let bus = if x.bus == self.buses[0] { 0 } else { 1 };
                    Some((x.end, bus, self.sender_node(x), x.frame))
                }
                _ => None,
            })
            .collect()
    }
    /// NMT commands delivered: (end, bus, sender, command, target).
    pub fn nmt_on_wire(&self) -> Vec<(Instant, usize, u8, NmtCommand, u8)> {
        self.delivered()
            .into_iter()
            .filter(|(_, _, _, f)| f.id() == Id::Standard(0))
            .filter_map(|(t, bus, s, f)| {
                let (cmd, target) = duocan::nmt::parse_command(&f).ok()?;
                Some((t, bus, s, cmd, target))
            })
            .collect()
    }
    /// First copy (either bus) of each NMT command: (end, sender, command, target).
    pub fn nmt_first_copies(&self) -> Vec<(Instant, u8, NmtCommand, u8)> {
        let mut v: Vec<(Instant, u8, NmtCommand, u8)> = vec![];
        for (t, _, s, c, n) in self.nmt_on_wire() {
            if let Some(prev) = v.iter().rev().find(|x| x.1 == s && x.2 == c && x.3 == n) {
                if t.saturating_since(prev.0) < Duration::from_millis(5) {
                    continue;
                }
            }
            v.push((t, s, c, n));
        }
        v
    }
    /// Ends of the SYNC frames on the wire, first copies, with the sender.
    pub fn syncs(&self) -> Vec<(Instant, u8)> {
        let mut v: Vec<(Instant, u8)> = vec![];
        let mut all: Vec<_> = self
            .delivered()
            .into_iter()
            .filter(|(_, _, _, f)| f.id() == Id::Standard(0x80))
            .map(|(t, _, s, _)| (t, s))
            .collect();
        all.sort();
        for (t, s) in all {
            if let Some(last) = v.last() {
                if last.1 == s && t.saturating_since(last.0) < Duration::from_millis(2) {
                    continue;
                }
            }
            v.push((t, s));
        }
        v
    }
    /// The largest gap between consecutive SYNCs in `[from, to]`.
    pub fn max_sync_gap(&self, from: Instant, to: Instant) -> Duration {
        let s: Vec<Instant> = self
            .syncs()
            .into_iter()
            .map(|x| x.0)
            .filter(|t| *t >= from && *t <= to)
            .collect();
        s.windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(Duration::ZERO)
    }
    /// The end of the first copy of `node`'s last heartbeat delivered up to `t`.
    pub fn last_heartbeat(&self, node: u8, t: Instant) -> Instant {
        let hb: Vec<Instant> = self
            .delivered()
            .into_iter()
            .filter(|(e, _, s, f)| {
                *s == node && *e <= t && f.id() == Id::Standard(0x700 + node as u16)
            })
            .map(|x| x.0)
            .collect();
        let last = *hb.iter().max().expect("a heartbeat");
        // Its twin on the other bus may have ended a little earlier.
        hb.into_iter()
            .filter(|e| last.saturating_since(*e) < Duration::from_millis(2))
            .min()
            .unwrap()
    }
    /// Slaves that received a reset (node or communication) in `[from, to]`.
    pub fn resets_in(&self, from: Instant, to: Instant) -> Vec<u8> {
        self.nmt_first_copies()
            .into_iter()
            .filter(|(t, _, c, _)| {
                *t >= from
                    && *t <= to
                    && matches!(c, NmtCommand::ResetNode | NmtCommand::ResetCommunication)
            })
            .map(|x| x.3)
            .collect()
    }
    /// Boot-ups of slaves on the wire in `[from, to]`.
    pub fn boot_ups_in(&self, from: Instant, to: Instant) -> Vec<u8> {
        let mut v: Vec<u8> = self
            .delivered()
            .into_iter()
            .filter(|(t, _, s, f)| {
                *t >= from
                    && *t <= to
                    && *s >= 0x10
                    && f.id() == Id::Standard(0x700 + *s as u16)
                    && f.data() == [0]
            })
            .map(|x| x.2)
            .collect();
        v.dedup();
        v
    }

    /// The FD process data of pair `pair` delivered on either bus: (end of its first copy,
    /// sender, frame), once each, in order.
    pub fn fd_on_wire(&self, pair: u8) -> Vec<(Instant, u8, FdFrame)> {
        let mut v: Vec<(Instant, u8, FdFrame)> = vec![];
        for r in self.sim.trace() {
            let TraceRecord::Tx(x) = r else { continue };
            let (TxOutcome::Delivered { .. }, Some(f)) = (x.outcome, x.fd.as_deref()) else {
                continue;
            };
            let s = self.sender_node(x);
            if s != a(pair) && s != b(pair) {
                continue;
            }
            match v.iter_mut().find(|e| e.2 == *f) {
                Some(e) => e.0 = e.0.min(x.end),
                None => v.push((x.end, s, *f)),
            }
        }
        v.sort_by_key(|e| e.0);
        v
    }

    /// Checks master `m`'s FD process data of pair `pair` on the wire up to `until` (while it
    /// runs): none delivered twice, none that was not on the wire, and exactly the frames of
    /// the member active at the master when their first copy ended (the same-function merge;
    /// a frame within a millisecond of a role change may go either way). Returns how many of
    /// A's and of B's it delivered.
    pub fn assert_fd_exactly_once(&self, m: u8, pair: u8, until: Instant) -> [usize; 2] {
        let roles = self.pair_roles(m, pair);
        let ids = [a(pair), b(pair)].map(|n| Id::Standard(0x180 + n as u16));
        let got: Vec<FdFrame> = self
            .sim
            .device(self.master(m))
            .fd_got
            .iter()
            .map(|x| x.1)
            .filter(|f| ids.contains(&f.id()))
            .collect();
        let wire = self.fd_on_wire(pair);
        for (i, f) in got.iter().enumerate() {
            assert!(!got[..i].contains(f), "master {m}: {f:?} delivered twice");
            assert!(
                wire.iter().any(|w| w.2 == *f),
                "master {m}: {f:?} delivered, never on the wire"
            );
        }
        let mut counts = [0, 0];
        for (end, s, f) in wire.iter().filter(|w| w.0 <= until) {
            let member = if *s == a(pair) { Member::A } else { Member::B };
            let delivered = got.contains(f);
            if delivered {
                counts[(member == Member::B) as usize] += 1;
            }
            let near = |t: Instant| t.saturating_since(*end).max(end.saturating_since(t));
            if roles.iter().any(|r| near(r.at) <= Duration::from_millis(1)) {
                continue;
            }
            let active = roles.iter().rfind(|r| r.at <= *end).and_then(|r| r.to);
            assert_eq!(
                delivered,
                active == Some(member),
                "master {m}, pair {pair}: FD frame of {s:#x} ended at {end}, active {active:?}"
            );
        }
        counts
    }
}
