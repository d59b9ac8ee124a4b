//! A supervised dual-bus network on the simulator: a strong master (node 1, priority 0) and a
//! weak master (node 2, priority 1), each a `SupervisedStation`, and `pairs` A/B slave pairs
//! (A = 0x10 + i, B = 0x50 + i), every device on both 1 Mbit/s buses. Slaves are standard nodes
//! that boot at 0 with no heartbeat; the active master configures 0x1017.
#![allow(dead_code)]

use crate::stepped::{ClockJump, ClockStep, Stepped};
use duocan::machine::StationEvent;
use duocan::master::{objects, Master, MasterConfig};
use duocan::od::{comm, DynamicDictionary};
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
pub type MasterDev = Stepped<SupervisedStation<DynamicDictionary>>;
pub type SlaveDev = Station<DualBus, Node<DynamicDictionary>>;

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
    DualBus::new(DualBusConfig::with_guard_period(
        LinkMode::ActiveActive,
        p.slave_hb,
    ))
}

/// A master built at simulated time `now` (at its clock's reading then).
pub fn master_station(p: &Params, id: u8, now: Instant) -> MasterDev {
    let step = p.clock_step.filter(|s| now < s.at);
    let jump = p
        .clock_jump
        .filter(|j| j.0 == id && now < j.1.at)
        .map(|j| j.1);
    let now = Stepped::<SupervisedStation<DynamicDictionary>>::reading(step, now);
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
    let station = SupervisedStation::new(link(p), sup).unwrap();
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
    Station::new(link(p), node)
}

impl SupNet {
    pub fn new(p: Params) -> SupNet {
        let mut sim = SimNetwork::new(p.seed);
        let buses = [
            sim.add_bus(BusConfig::new("can1", p.bitrate)),
            sim.add_bus(BusConfig::new("can2", p.bitrate)),
        ];
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
}
