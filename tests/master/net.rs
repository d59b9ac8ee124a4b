//! A CiA 302-2 master and duocan slaves on the simulated bus: what every master test shares.
#![allow(dead_code)]

use duocan::machine::{SinglePort, StationEvent};
use duocan::master::{
    objects, ExpectedIdentity, Master, MasterConfig, MasterEvent, MasterEventKind,
};
use duocan::od::{comm, Access, DynamicDictionary, ObjectDef, WriteHook};
use duocan::pdo::params;
use duocan::sim::{timing, BusConfig, BusId, DevId, SimNetwork, TraceRecord, TxOutcome};
use duocan::{Duration, Frame, Id, Instant, Node, NodeConfig, NodeId, Station};
use std::convert::Infallible;

pub type MasterDev = Station<SinglePort, Master<DynamicDictionary>>;
pub type SlaveDev = Station<SinglePort, Node<DynamicDictionary>>;
/// A configuration tool: a node with an SDO client.
pub type Tool = Station<
    SinglePort,
    duocan::machine::Composite<Node<DynamicDictionary>, duocan::sdo::SdoClient>,
>;
/// The tool's node-ID.
pub const TOOL: NodeId = NodeId::must(0x7E);

pub const MASTER_ID: NodeId = NodeId::must(1);
pub const VENDOR: u32 = 0x0000_0A5E;
pub const DEVICE_TYPE: u32 = 0x0001_0191;
/// Application entries every test slave has: 0x2000 sub 1–3, UNSIGNED16 rw, mappable; and TPDO1
/// (0x1800/0x1A00).
pub const APP: u16 = 0x2000;

/// What slave `id` is.
pub fn identity(id: u8) -> comm::Identity {
    comm::Identity {
        device_type: DEVICE_TYPE,
        vendor: VENDOR,
        product: 0x100 + id as u32,
        revision: 0x0002_0001,
        serial: 10_000 + id as u32,
    }
}

/// What the master expects of slave `id` (everything checked).
pub fn expected(id: u8) -> ExpectedIdentity {
    let i = identity(id);
    ExpectedIdentity {
        device_type: i.device_type,
        vendor: i.vendor,
        product: i.product,
        revision: i.revision,
        serial: i.serial,
    }
}

/// A slave node with the standard dictionary, `identity`, and the application entries.
pub fn slave_node(id: u8, identity: comm::Identity) -> Node<DynamicDictionary> {
    Node::new(
        NodeConfig::slave(NodeId::must(id)),
        slave_dictionary(id, identity, None),
    )
}

/// The standard dictionary, `identity`, and the application entries; `app3` checks writes to
/// 0x2000 sub 3.
pub fn slave_dictionary(
    id: u8,
    identity: comm::Identity,
    app3: Option<WriteHook>,
) -> DynamicDictionary {
    let mut od = comm::standard_dictionary(id, identity);
    let sub3 = ObjectDef::u16(APP, 3, Access::Rw, 0).mappable();
    od.insert_all(&[
        ObjectDef::u8(APP, 0, Access::Const, 3),
        ObjectDef::u16(APP, 1, Access::Rw, 0).mappable(),
        ObjectDef::u16(APP, 2, Access::Rw, 0).mappable(),
        app3.map_or(sub3, |h| sub3.hook(h)),
    ])
    .unwrap();
    // TPDO1 on its predefined identifier, event-driven, nothing mapped yet.
    od.insert_all(&params::tpdo_comm(
        1,
        params::predefined_tpdo_cob(1),
        255,
        0,
        0,
    ))
    .unwrap();
    od.insert_all(&params::tpdo_mapping::<9>(1, &[])).unwrap();
    od
}

pub fn slave(id: u8) -> SlaveDev {
    Station::single(slave_node(id, identity(id)))
}

/// A master (node 1) built from `config` on the master dictionary.
pub fn master(config: MasterConfig) -> Master<DynamicDictionary> {
    master_with(MASTER_ID, config, |_| {})
}

/// A master with node-ID `id`; `prepare` may change its dictionary first (SYNC producer, …).
pub fn master_with(
    id: NodeId,
    config: MasterConfig,
    prepare: impl FnOnce(&mut DynamicDictionary),
) -> Master<DynamicDictionary> {
    let mut od = objects::master_dictionary(id.raw(), comm::Identity::default());
    prepare(&mut od);
    Master::new(id, od, config).unwrap()
}

pub struct Net {
    pub sim: SimNetwork,
    pub bus: BusId,
    pub master: DevId<MasterDev>,
    pub slaves: Vec<(u8, DevId<SlaveDev>)>,
}

impl Net {
    /// A bus at `bitrate` with the master (not booted) and unbooted slaves `ids`.
    pub fn new(bitrate: u32, m: Master<DynamicDictionary>, ids: &[u8]) -> Net {
        let mut sim = SimNetwork::new(7);
        let bus = sim.add_bus(BusConfig::new("can0", bitrate));
        let master = sim
            .add_device("master", Station::single(m), &[bus])
            .unwrap();
        let slaves = ids
            .iter()
            .map(|&id| {
                (
                    id,
                    sim.add_device(format!("slave{id}"), slave(id), &[bus])
                        .unwrap(),
                )
            })
            .collect();
        Net {
            sim,
            bus,
            master,
            slaves,
        }
    }

    pub fn slave_dev(&self, id: u8) -> DevId<SlaveDev> {
        self.slaves.iter().find(|(i, _)| *i == id).unwrap().1
    }

    pub fn slave(&self, id: u8) -> &Node<DynamicDictionary> {
        &self.sim.device(self.slave_dev(id)).machine
    }

    pub fn m(&self) -> &Master<DynamicDictionary> {
        &self.sim.device(self.master).machine
    }

    pub fn m_mut(&mut self) -> &mut Master<DynamicDictionary> {
        &mut self.sim.device_mut(self.master).machine
    }

    /// Boots the master now.
    pub fn boot_master(&mut self) {
        let now = self.sim.now();
        self.m_mut().boot(now);
    }

    /// Boots slave `id` at `t`.
    pub fn boot_slave_at(&mut self, id: u8, t: Instant) {
        let dev = self.slave_dev(id);
        self.sim.at(t, move |sim| {
            let now = sim.now();
            sim.device_mut(dev).machine.boot(now);
        });
    }

    /// Power-cycles slave `id` at `t`: a fresh node (dictionary back to defaults) that boots.
    pub fn power_cycle_at(&mut self, id: u8, t: Instant) {
        let dev = self.slave_dev(id);
        self.sim.at(t, move |sim| {
            let now = sim.now();
            sim.replace(dev, slave(id)).unwrap();
            sim.device_mut(dev).machine.boot(now);
        });
    }

    /// The master's events so far, without the node pass-through.
    pub fn events(&self) -> Vec<MasterEvent> {
        master_events(self.sim.events(self.master))
    }

    /// Every frame that went on the bus, with its end time.
    pub fn frames(&self) -> Vec<(Instant, Frame)> {
        frames(&self.sim)
    }
}

/// A bus at `bitrate` with the master built from `config`, slaves 2 and 3 and a tool whose
/// client carries up to `limit` bytes; all booted, run for 100 ms.
pub fn with_tool(bitrate: u32, config: MasterConfig, limit: usize) -> (Net, DevId<Tool>) {
    let mut n = Net::new(bitrate, master(config), &[2, 3]);
    let node = Node::new(
        NodeConfig::slave(TOOL),
        comm::standard_dictionary(TOOL.raw(), Default::default()),
    );
    let client = duocan::sdo::SdoClient::new(limit);
    let station = Station::single(duocan::machine::Composite::new(node, client));
    let tool = n.sim.add_device("tool", station, &[n.bus]).unwrap();
    n.sim.device_mut(tool).machine.a.boot(Instant::ZERO);
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(1));
    n.boot_slave_at(3, Instant::from_millis(1));
    n.sim.run_until(Instant::from_millis(100));
    (n, tool)
}

pub fn master_events(log: &[(Instant, StationEvent<Infallible, MasterEvent>)]) -> Vec<MasterEvent> {
    log.iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Machine(e) if !matches!(e.kind, MasterEventKind::Node(_)) => {
                Some(e.clone())
            }
            _ => None,
        })
        .collect()
}

/// Every frame that went on the bus, with its end time.
pub fn frames(sim: &SimNetwork) -> Vec<(Instant, Frame)> {
    sent(sim).into_iter().map(|(t, _, f)| (t, f)).collect()
}

/// Every frame that went on the bus: end time, sender's device name, frame.
pub fn sent(sim: &SimNetwork) -> Vec<(Instant, String, Frame)> {
    sim.trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(t) if matches!(t.outcome, TxOutcome::Delivered { .. }) => {
                Some((t.end, t.sender_name.to_string(), t.frame))
            }
            _ => None,
        })
        .collect()
}

/// NMT commands on the bus: (end time, command byte, node byte).
pub fn nmt_frames(sim: &SimNetwork) -> Vec<(Instant, u8, u8)> {
    frames(sim)
        .into_iter()
        .filter(|(_, f)| f.id() == Id::Standard(0))
        .map(|(t, f)| (t, f.data()[0], f.data()[1]))
        .collect()
}

/// The worst-case duration of an 8-byte 11-bit frame at `bitrate`: an SDO request or answer.
pub fn sdo_frame(bitrate: u32) -> Duration {
    timing::bits_duration(timing::worst_case_bits(false, 8), bitrate)
}

/// First event matching `f`.
pub fn find<T>(
    events: &[MasterEvent],
    f: impl Fn(&MasterEventKind) -> Option<T>,
) -> Option<(Instant, T)> {
    events.iter().find_map(|e| f(&e.kind).map(|x| (e.at, x)))
}

/// Every event matching `f`.
pub fn all<T>(
    events: &[MasterEvent],
    f: impl Fn(&MasterEventKind) -> Option<T>,
) -> Vec<(Instant, T)> {
    events
        .iter()
        .filter_map(|e| f(&e.kind).map(|x| (e.at, x)))
        .collect()
}

pub fn ms(t: Instant) -> f64 {
    t.as_micros() as f64 / 1000.0
}
