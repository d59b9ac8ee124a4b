//! `duocan kit sim`: the same scenario against duocan's simulator, in simulated time.
//!
//! Each bus of the scenario is a simulated bus (1 Mbit/s unless `--bitrate`); each device
//! is the simulator's stand-in for it — a duocan device started with `{duocan} … device board|
//! master …` stands in as itself, built from the same arguments. A member is the port its
//! device has on that bus. The timeline applies the same faults by the same names
//! ([`duocan::sim::SimNetwork`]'s `bus_down`, `disconnect`, `partition`, `set_port_faults`,
//! `drop_every`, `set_port_latency`, `babble`, `power_off`); a device's start and `power_on` boot it afresh,
//! as a process start does. The wires are what the simulator's trace and the devices' receive
//! paths saw, and the expectations are measured on them exactly as on a real run's logs.
//!
//! Where the two differ, by nature: the simulator's babble is back-to-back (a controller stuck
//! retransmitting), whatever `period_ms` says; its members share one wire, so a member's detected
//! corruption is an error frame for the whole segment (the sender sends again), where the
//! bridge's member loses the frame alone; a bus wire in the simulator holds the frames its
//! members put on it that the bus carried, while the bridge logs every frame it took.

use super::expect::Wires;
use super::run::describe;
use super::scenario::{Fault, Rate, Scenario, Target};
use crate::cmd::device::{self, Board};
use crate::fail::Fail;
use crate::{Cli, Command};
use clap::Parser;
use duocan::sim::{
    BusConfig, BusId, DevId, FaultRates, PortRef, RxFault, SimNetwork, TraceRecord, TxOutcome,
};
use duocan::{Duration, Frame, Id, Instant};
use duocan_redundancy::RedundantNetworkBuilder;
use std::collections::BTreeMap;

type Master = duocan_redundancy::LogicalNetwork<duocan::od::DynamicDictionary>;

/// What stands in for a device, and how to build it again (a power-on is a fresh boot).
#[derive(Clone)]
enum StandIn {
    Board {
        node: duocan::NodeId,
        heartbeat_ms: u64,
    },
    Master(Box<RedundantNetworkBuilder>),
}

/// A stand-in in the simulation.
enum SimDev {
    Board(DevId<Board>),
    Master(DevId<Box<Master>>),
}

/// A member's place on its bus at some time: what decides which frames reach it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Place {
    connected: bool,
    /// Its partition group (= the segment that carries its frames while connected).
    group: u32,
    /// The fixed receive latency, µs.
    latency: u64,
}

/// The stand-in for a device: the duocan device its command line starts.
fn stand_in(name: &str, run: &[String]) -> Result<StandIn, Fail> {
    let no = || {
        Fail::usage(format!(
            "device {name:?}: the simulator stands in only for duocan devices \
             (run = [\"{{duocan}}\", \"--bus\", \"A,B\", \"device\", \"board\"|\"master\", …])"
        ))
    };
    if run.first().map(String::as_str) != Some("{duocan}") {
        return Err(no());
    }
    let cli =
        Cli::try_parse_from(std::iter::once("duocan").chain(run[1..].iter().map(String::as_str)))
            .map_err(|e| Fail::usage(format!("device {name:?}: {e}")))?;
    match cli.command {
        Command::Device(device::Device::Board {
            node, heartbeat_ms, ..
        }) => Ok(StandIn::Board { node, heartbeat_ms }),
        Command::Device(device::Device::Master {
            node,
            pair,
            peer,
            priority,
            heartbeat_ms,
            timeout_ms,
            ..
        }) => Ok(StandIn::Master(Box::new(device::master(
            node,
            &pair,
            &peer,
            priority,
            heartbeat_ms,
            timeout_ms,
        )))),
        _ => Err(no()),
    }
}

fn frame(id: u32, data: &[u8]) -> Option<Frame> {
    let id = match u16::try_from(id) {
        Ok(i) if i <= 0x7FF => Id::Standard(i),
        _ => Id::Extended(id),
    };
    Frame::new(id, data).ok()
}

/// The simulation of a scenario.
struct Run {
    sim: SimNetwork,
    buses: Vec<BusId>,
    /// Per device: its stand-in and its id.
    devices: BTreeMap<String, (StandIn, SimDev)>,
    /// Per member: its place from each instant on (µs), oldest first.
    places: BTreeMap<String, Vec<(u64, Place)>>,
    /// Member → port.
    ports: BTreeMap<String, PortRef>,
    /// Port → member.
    names: BTreeMap<PortRef, String>,
}

impl Run {
    fn bus(&self, s: &Scenario, name: &str) -> BusId {
        let i = s.buses.iter().position(|(n, _)| n == name).unwrap_or(0);
        self.buses[i]
    }

    /// Boots `device` afresh (a start or a power-on).
    fn boot(&mut self, name: &str) -> Result<(), Fail> {
        let now = self.sim.now();
        let Some((standin, dev)) = self.devices.get(name) else {
            return Ok(());
        };
        match (standin, dev) {
            (StandIn::Board { node, heartbeat_ms }, SimDev::Board(id)) => {
                let b = device::board(*node, *heartbeat_ms, now)?;
                self.sim
                    .replace(*id, b)
                    .map_err(|e| Fail::usage(e.to_string()))?;
            }
            (StandIn::Master(bld), SimDev::Master(id)) => {
                let m = bld.build_boxed().map_err(|e| Fail::usage(e.to_string()))?;
                self.sim
                    .replace(*id, m)
                    .map_err(|e| Fail::usage(e.to_string()))?;
            }
            _ => {}
        }
        Ok(())
    }

    fn dev_ref(&self, name: &str) -> Option<duocan::sim::DeviceRef> {
        self.devices.get(name).map(|(_, d)| match d {
            SimDev::Board(id) => (*id).into(),
            SimDev::Master(id) => (*id).into(),
        })
    }

    /// Changes member `m`'s place from now on.
    fn place(&mut self, m: &str, change: impl Fn(&mut Place)) {
        let now = self.sim.now().as_micros();
        if let Some(v) = self.places.get_mut(m) {
            let mut p = v.last().map_or(
                Place {
                    connected: true,
                    group: 0,
                    latency: 0,
                },
                |(_, p)| *p,
            );
            change(&mut p);
            v.push((now, p));
        }
    }

    /// Member `m`'s place at `t` µs.
    fn place_at(&self, m: &str, t: u64) -> Place {
        self.places
            .get(m)
            .and_then(|v| v.iter().rev().find(|(since, _)| *since <= t))
            .map_or(
                Place {
                    connected: true,
                    group: 0,
                    latency: 0,
                },
                |(_, p)| *p,
            )
    }

    fn apply(&mut self, s: &Scenario, f: &Fault) -> Result<(), Fail> {
        let port = |r: &Run, m: &str| {
            r.ports
                .get(m)
                .copied()
                .ok_or_else(|| Fail::usage(format!("member {m:?} has no device in the simulation")))
        };
        match f {
            Fault::BusDown(b) => {
                let b = self.bus(s, b);
                self.sim.bus_down(b);
            }
            Fault::BusUp(b) => {
                let b = self.bus(s, b);
                self.sim.bus_up(b);
            }
            Fault::Disconnect(m) => {
                let p = port(self, m)?;
                self.sim.disconnect(p);
                self.place(m, |p| p.connected = false);
            }
            Fault::Reconnect(m) => {
                let p = port(self, m)?;
                self.sim.reconnect(p);
                self.place(m, |p| p.connected = true);
            }
            Fault::Partition(b, groups) => {
                let g: Vec<Vec<PortRef>> = groups
                    .iter()
                    .map(|g| g.iter().map(|m| port(self, m)).collect::<Result<_, _>>())
                    .collect::<Result<_, _>>()?;
                let g: Vec<&[PortRef]> = g.iter().map(Vec::as_slice).collect();
                let bus = self.bus(s, b);
                self.sim.partition(bus, &g);
                let members = s.buses.iter().find(|(n, _)| n == b).map(|(_, m)| m.clone());
                for m in members.unwrap_or_default() {
                    let k = groups
                        .iter()
                        .position(|g| g.contains(&m))
                        .map_or(0, |k| k as u32 + 1);
                    self.place(&m, |p| p.group = k);
                }
            }
            Fault::Heal(b) => {
                let bus = self.bus(s, b);
                self.sim.heal(bus);
                let members = s.buses.iter().find(|(n, _)| n == b).map(|(_, m)| m.clone());
                for m in members.unwrap_or_default() {
                    self.place(&m, |p| p.group = 0);
                }
            }
            Fault::Rate(t, r) => {
                let set = |old: FaultRates| match *r {
                    Rate::Drop(p) => old.with_drop(p),
                    Rate::Duplicate(p) => old.with_duplicate(p),
                    Rate::Delay(p, max) => old.with_delay(p, Duration::from_millis(max)),
                    Rate::CorruptDetected(p) => old.with_corrupt_detected(p),
                    Rate::CorruptUndetected(p) => old.with_corrupt_undetected(p),
                };
                match t {
                    Target::Bus(b) => {
                        let b = self.bus(s, b);
                        let old = self.sim.bus_faults(b);
                        self.sim.set_bus_faults(b, set(old));
                    }
                    Target::Member(m) => {
                        let p = port(self, m)?;
                        let old = self.sim.port_faults(p);
                        self.sim.set_port_faults(p, set(old));
                    }
                }
            }
            Fault::DropEvery(Target::Bus(b), n) => {
                let b = self.bus(s, b);
                self.sim.drop_every_on_bus(b, *n);
            }
            Fault::DropEvery(Target::Member(m), n) => {
                let p = port(self, m)?;
                self.sim.drop_every(p, *n);
            }
            Fault::Latency(m, ms) => {
                let p = port(self, m)?;
                self.sim.set_port_latency(p, Duration::from_millis(*ms));
                let us = ms.saturating_mul(1000);
                self.place(m, |p| p.latency = us);
            }
            Fault::Babble(m, id, data, _) => {
                let p = port(self, m)?;
                self.sim.babble(p, frame(*id, data));
            }
            Fault::BabbleStop(m) => {
                let p = port(self, m)?;
                self.sim.babble(p, None);
            }
            Fault::PowerOff(d) => {
                if let Some(r) = self.dev_ref(d) {
                    self.sim.power_off(r);
                }
            }
            Fault::PowerOn(d) => {
                if let Some(r) = self.dev_ref(d) {
                    self.sim.power_on(r);
                }
                self.boot(d)?;
            }
        }
        Ok(())
    }
}

/// Runs `s` in the simulator; returns the wires and the end (µs).
pub fn run(s: &Scenario, bitrate: u32, quiet: bool) -> Result<(Wires, u64), Fail> {
    let mut sim = SimNetwork::new(s.seed);
    sim.set_recording(true);
    let buses: Vec<BusId> = s
        .buses
        .iter()
        .map(|(n, _)| sim.add_bus(BusConfig::new(n.clone(), bitrate)))
        .collect();
    let bus_of = |m: &str| {
        s.buses
            .iter()
            .position(|(_, ms)| ms.iter().any(|x| x == m))
            .map(|i| buses[i])
    };
    let mut run = Run {
        sim,
        buses: buses.clone(),
        devices: BTreeMap::new(),
        places: s.members().map(|m| (m.to_string(), Vec::new())).collect(),
        ports: BTreeMap::new(),
        names: BTreeMap::new(),
    };
    for d in &s.devices {
        let standin = stand_in(&d.name, &d.run)?;
        let on: Vec<BusId> = d.ports.iter().filter_map(|m| bus_of(m)).collect();
        let dev = match &standin {
            StandIn::Board { node, heartbeat_ms } => {
                let b = device::board(*node, *heartbeat_ms, Instant::ZERO)?;
                let id = run
                    .sim
                    .add_device(d.name.clone(), b, &on)
                    .map_err(|e| Fail::usage(format!("device {:?}: {e}", d.name)))?;
                SimDev::Board(id)
            }
            StandIn::Master(bld) => {
                let m = bld.build_boxed().map_err(|e| Fail::usage(e.to_string()))?;
                let id = run
                    .sim
                    .add_device(d.name.clone(), m, &on)
                    .map_err(|e| Fail::usage(format!("device {:?}: {e}", d.name)))?;
                SimDev::Master(id)
            }
        };
        let dref: duocan::sim::DeviceRef = match &dev {
            SimDev::Board(id) => (*id).into(),
            SimDev::Master(id) => (*id).into(),
        };
        // Off until its start.
        run.sim.power_off(dref);
        for (i, m) in d.ports.iter().enumerate() {
            let p = PortRef {
                device: dref,
                port: i,
            };
            run.ports.insert(m.clone(), p);
            run.names.insert(p, m.clone());
        }
        run.devices.insert(d.name.clone(), (standin, dev));
    }
    let mut timeline: Vec<(u64, Fault)> = s
        .devices
        .iter()
        .map(|d| (d.start_ms, Fault::PowerOn(d.name.clone())))
        .collect();
    timeline.extend(s.timeline.iter().cloned());
    timeline.sort_by_key(|(t, _)| *t);
    for (at, f) in &timeline {
        run.sim.run_until(Instant::from_millis(*at));
        run.apply(s, f)?;
        if !quiet {
            println!("{at:>7} ms  {}", describe(f));
        }
    }
    let end = s.duration_ms.saturating_mul(1000);
    run.sim.run_until(Instant::from_micros(end));
    if !quiet {
        println!("{:>7} ms  end (simulated)", s.duration_ms);
    }

    // The wires, as the bridge logs them: what each member sent, and what its bus carried to
    // it (whether its device was powered or not), after the faults at its port; what each bus
    // carried.
    let mut wires = Wires::new();
    for (name, _) in &s.buses {
        wires.insert(name.clone(), Vec::new());
    }
    for m in s.members() {
        wires.insert(m.to_string(), Vec::new());
    }
    let mut faults: BTreeMap<(PortRef, u64), Vec<(Frame, RxFault)>> = BTreeMap::new();
    for r in run.sim.trace() {
        if let TraceRecord::Rx(x) = r {
            faults
                .entry((x.port, x.at.as_micros()))
                .or_default()
                .push((x.frame, x.fault));
        }
    }
    for r in run.sim.trace() {
        let TraceRecord::Tx(t) = r else { continue };
        if !matches!(t.outcome, TxOutcome::Delivered { .. }) {
            continue;
        }
        let at = t.end.as_micros();
        let Some(b) = buses.iter().position(|b| *b == t.bus) else {
            continue;
        };
        let (bus_name, members) = &s.buses[b];
        if let Some(w) = wires.get_mut(bus_name) {
            w.push((at, t.frame));
        }
        for m in members {
            let Some(&p) = run.ports.get(m) else { continue };
            let here = run.place_at(m, at);
            let mut got = vec![(at, t.frame)];
            if p != t.sender {
                if !here.connected || here.group != t.segment {
                    continue;
                }
                let here_faults = faults.get(&(p, at)).into_iter().flatten();
                for (_, f) in here_faults.filter(|(fr, _)| *fr == t.frame) {
                    match f {
                        RxFault::Dropped => got.clear(),
                        RxFault::Duplicated => got.push((at, t.frame)),
                        RxFault::Delayed { until } => {
                            got.iter_mut().for_each(|g| g.0 = until.as_micros())
                        }
                        RxFault::Corrupted { delivered } => {
                            got.iter_mut().for_each(|g| g.1 = *delivered)
                        }
                        // The kit's buses are classic: no CAN FD frame reaches them.
                        RxFault::CorruptedFd { .. } => {}
                    }
                }
                got.iter_mut().for_each(|g| g.0 += here.latency);
            }
            if let Some(w) = wires.get_mut(m) {
                w.extend(got);
            }
        }
    }
    for w in wires.values_mut() {
        w.sort_by_key(|(t, _)| *t);
    }
    Ok((wires, end))
}
