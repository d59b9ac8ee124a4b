//! The configuration manager (CiA 302-3): 20 slaves configured at boot from their DCFs, PDO
//! remapping included, each value checked in the slave's dictionary and read back over SDO; the
//! expected configuration date and time (0x1F26/0x1F27) against each
//! slave's 0x1020 so that a second boot writes nothing; a refused write reported per object
//! while the rest of the configuration goes on.

use crate::net::*;
use duocan::eds::{export_dcf, Description, ExportOptions, ImportOptions};
use duocan::machine::SinglePort;
use duocan::master::{
    objects, ConciseDcf, ConfigurationStamp, MasterConfig, MasterEventKind as K, SlaveConfig,
};
use duocan::od::parameters::{MemoryStorage, StoredDictionary};
use duocan::od::{
    abort::AbortCode, comm, Access, DynamicDictionary, ObjectDef, ObjectDictionary, WriteHook,
};
use duocan::sdo::{Direction, SdoOptions};
use duocan::sim::{BusConfig, SimNetwork};
use duocan::{Duration, Id, Instant, NmtState, Node, NodeConfig, NodeId, Station};

const BITRATE: u32 = 500_000;
const STAMP: ConfigurationStamp = ConfigurationStamp {
    date: 15_300,
    time: 43_200_000,
};
/// The slave whose 0x2000 sub 3 refuses every write (its DCF says it is writable).
pub(crate) const REFUSING: u8 = 21;
pub(crate) const IDS: core::ops::RangeInclusive<u8> = 2..=21;

type Od = StoredDictionary<DynamicDictionary, MemoryStorage<8192>, 8192>;

fn refuse(_: u16, _: u8, _: &[u8]) -> Result<(), AbortCode> {
    Err(AbortCode::READ_ONLY)
}

/// Slave `id`'s dictionary as the device ships: the standard objects, 0x1020, three
/// application entries, TPDO1 on its predefined identifier with nothing mapped. `refusing`:
/// 0x2000 sub 3 refuses writes.
fn device(id: u8, refusing: bool) -> DynamicDictionary {
    let mut od = slave_dictionary(id, identity(id), refusing.then_some(refuse as WriteHook));
    let record = duocan::od::ObjectType::Record;
    od.insert_all(&[
        ObjectDef::u8(0x1020, 0, Access::Const, 2).object_type(record),
        ObjectDef::u32(0x1020, 1, Access::Rw, 0).object_type(record),
        ObjectDef::u32(0x1020, 2, Access::Rw, 0).object_type(record),
    ])
    .unwrap();
    od
}

/// Slave `id`'s DCF: its device's dictionary configured (heartbeat, application values,
/// TPDO1 remapped to 0x2000 sub 1–3, asynchronous with an event timer), exported and read
/// back as a tool would hand it over.
fn dcf(id: u8) -> Description {
    let mut od = device(id, false);
    let cob = 0x180 + id as u32;
    let mut set = |index: u16, sub: u8, data: &[u8]| od.write(index, sub, data).unwrap();
    set(comm::HEARTBEAT_PRODUCER, 0, &50u16.to_le_bytes());
    set(APP, 1, &(0x100 + id as u16).to_le_bytes());
    set(APP, 2, &(0x200 + id as u16).to_le_bytes());
    set(APP, 3, &7u16.to_le_bytes());
    set(0x1800, 1, &(cob | 1 << 31).to_le_bytes());
    set(0x1800, 2, &[254]);
    set(0x1800, 5, &100u16.to_le_bytes());
    set(0x1A00, 0, &[0]);
    for sub in 1..=3u8 {
        set(
            0x1A00,
            sub,
            &(0x2000_0010 | (sub as u32) << 8).to_le_bytes(),
        );
    }
    set(0x1A00, 0, &[3]);
    set(0x1800, 1, &cob.to_le_bytes());
    let text = export_dcf(&od, &ExportOptions::default()).unwrap();
    Description::parse(text.as_bytes(), "slave.dcf", &ImportOptions::strict())
        .unwrap_or_else(|e| panic!("{e}"))
}

type Slave = Station<SinglePort, Node<Od>>;

pub(crate) struct Run {
    pub(crate) sim: SimNetwork,
    pub(crate) master: duocan::sim::DevId<MasterDev>,
    slaves: Vec<(u8, duocan::sim::DevId<Slave>)>,
    pub(crate) dcfs: Vec<Description>,
}

/// Where the master takes each slave's configuration from.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum From {
    /// [`SlaveConfig::from_dcf`].
    Dcf,
    /// The slave's concise DCF, written into the master's 0x1F22 before it boots.
    Concise,
}

fn network() -> Run {
    network_from(From::Dcf)
}

/// The 20 slaves and their master, configured from their DCFs either way.
pub(crate) fn network_from(from: From) -> Run {
    let dcfs: Vec<Description> = IDS.map(dcf).collect();
    let mut net = MasterConfig::new().default_consumer_ms(150);
    for (id, d) in IDS.zip(&dcfs) {
        let node = NodeId::must(id);
        let cfg = match from {
            From::Dcf => SlaveConfig::from_dcf(node, d),
            From::Concise => SlaveConfig::new(node),
        };
        net = net.slave(
            cfg.identity(expected(id))
                .with_stamp(STAMP)
                .with_store(true),
        );
    }
    let mut m = master(net);
    if from == From::Concise {
        for (id, d) in IDS.zip(&dcfs) {
            let bytes = ConciseDcf::from_dcf(NodeId::must(id), d).to_bytes();
            m.node_mut()
                .od_mut()
                .write(objects::CONCISE_DCF, id, &bytes)
                .unwrap();
        }
    }
    let mut sim = SimNetwork::new(7);
    let bus = sim.add_bus(BusConfig::new("can0", BITRATE));
    let master = sim
        .add_device("master", Station::single(m), &[bus])
        .unwrap();
    let slaves = IDS
        .map(|id| {
            let od = Od::new(device(id, id == REFUSING), MemoryStorage::default());
            let node = Node::new(NodeConfig::slave(NodeId::must(id)), od);
            let dev = sim
                .add_device(format!("slave{id}"), Station::single(node), &[bus])
                .unwrap();
            (id, dev)
        })
        .collect();
    let mut run = Run {
        sim,
        master,
        slaves,
        dcfs,
    };
    let now = run.sim.now();
    run.sim.device_mut(run.master).machine.boot(now);
    for &(_, dev) in &run.slaves {
        run.sim.at(Instant::from_millis(1), move |sim| {
            let now = sim.now();
            sim.device_mut(dev).machine.boot(now);
        });
    }
    run
}

impl Run {
    pub(crate) fn slave(&self, id: u8) -> &Node<Od> {
        let dev = self.slaves.iter().find(|(i, _)| *i == id).unwrap().1;
        &self.sim.device(dev).machine
    }
    /// Uploads each (node, index, sub, value) through the master's SDO client from `from` on,
    /// and checks every answer; returns how many answered with the value.
    pub(crate) fn read_back(&mut self, from: Instant, items: &[(u8, u16, u8, Vec<u8>)]) -> usize {
        // Round-robin over the slaves, so that the transfers of one batch (one per session)
        // are to different nodes.
        let mut seen = std::collections::HashMap::new();
        let mut keyed: Vec<_> = items
            .iter()
            .map(|item| {
                let k = seen.entry(item.0).or_insert(0usize);
                *k += 1;
                ((*k, item.0), item)
            })
            .collect();
        keyed.sort_by_key(|(key, _)| *key);
        let order: Vec<&(u8, u16, u8, Vec<u8>)> = keyed.into_iter().map(|(_, i)| i).collect();
        let sessions = self.sim.device(self.master).machine.sdo().sessions();
        let master = self.master;
        for (k, batch) in order.chunks(sessions).enumerate() {
            let batch: Vec<(u8, u16, u8)> = batch.iter().map(|(n, i, s, _)| (*n, *i, *s)).collect();
            let at = from + Duration::from_millis(10 * k as u64);
            self.sim.at(at, move |sim| {
                let now = sim.now();
                for (node, index, sub) in batch {
                    let sdo = sim.device_mut(master).machine.sdo_mut();
                    sdo.upload(now, NodeId::must(node), index, sub, SdoOptions::default())
                        .unwrap();
                }
            });
        }
        let end = from + Duration::from_millis(10 * order.len().div_ceil(sessions) as u64 + 50);
        self.sim.run_until(end);
        let events = master_events(self.sim.events(self.master));
        let answers: Vec<_> = all(&events, |k| match k {
            K::Sdo(e) if e.at >= from && e.direction == Direction::Upload => {
                Some((e.node.raw(), e.index, e.sub, e.data().map(<[u8]>::to_vec)))
            }
            _ => None,
        });
        assert_eq!(answers.len(), items.len());
        let mut matching = 0;
        for (n, i, s, v) in items {
            let got = answers
                .iter()
                .find(|(_, a)| (a.0, a.1, a.2) == (*n, *i, *s));
            assert_eq!(
                got.map(|(_, a)| a.3.as_deref()),
                Some(Some(v.as_slice())),
                "slave {n} 0x{i:04X} sub {s}"
            );
            matching += 1;
        }
        matching
    }

    /// SDO requests the master sent (0x600 + node) after `from`.
    fn sdo_requests(&self, from: Instant) -> usize {
        frames(&self.sim)
            .iter()
            .filter(|(t, f)| {
                *t >= from && matches!(f.id(), Id::Standard(c) if (0x601..=0x67F).contains(&c))
            })
            .count()
    }
}

#[test]
fn twenty_slaves_end_with_their_dcf_values_and_a_second_boot_writes_nothing() {
    let mut run = network();
    run.sim.run_until(Instant::from_millis(500));
    let events = master_events(run.sim.events(run.master));
    let mut read_back = vec![];
    for (id, d) in IDS.zip(&run.dcfs) {
        let s = run.slave(id);
        assert_eq!(s.nmt_state(), NmtState::Operational, "slave {id}");
        let mut checked = 0;
        for e in d.parameter_values() {
            if matches!(
                e.access,
                duocan::eds::AccessType::Ro | duocan::eds::AccessType::Const
            ) {
                continue;
            }
            let want = e.value_bytes(id);
            let have = s.od().read(e.index, e.sub).map(|b| b.to_vec());
            if id == REFUSING && (e.index, e.sub) == (APP, 3) {
                assert_eq!(have, Ok(0u16.to_le_bytes().to_vec()));
                read_back.push((id, e.index, e.sub, have.unwrap()));
                continue;
            }
            // 0x1020 holds the stamp; reading 0x1010/0x1011 gives what storage can do.
            if matches!(
                e.index,
                0x1020 | comm::STORE_PARAMETERS | comm::RESTORE_DEFAULTS
            ) {
                continue;
            }
            assert_eq!(
                have,
                Ok(want.clone()),
                "slave {id} 0x{:04X} sub {}",
                e.index,
                e.sub
            );
            if e.index != comm::HEARTBEAT_CONSUMER {
                read_back.push((id, e.index, e.sub, want));
            }
            checked += 1;
        }
        assert!(checked > 20, "slave {id}: {checked} entries checked");
        // Stamped and stored unless a write was refused.
        let stamp = (s.od().get_u32(0x1020, 1), s.od().get_u32(0x1020, 2));
        if id == REFUSING {
            assert_eq!(stamp, (Some(0), Some(0)));
        } else {
            assert_eq!(stamp, (Some(STAMP.date), Some(STAMP.time)), "slave {id}");
        }
    }
    // The refusal: reported once, with the object and the abort code; every slave configured.
    let refused = all(&events, |k| match k {
        K::ConfigWriteAborted {
            node,
            index,
            sub,
            code,
        } => Some((node.raw(), *index, *sub, *code)),
        _ => None,
    });
    assert_eq!(
        refused.iter().map(|(_, x)| *x).collect::<Vec<_>>(),
        [(REFUSING, APP, 3, AbortCode::READ_ONLY)]
    );
    let configured = all(&events, |k| match k {
        K::SlaveConfigured { node, .. } => Some(node.raw()),
        _ => None,
    });
    assert_eq!(configured.len(), 20);
    assert!(all(&events, |k| matches!(k, K::ConfigFailed { .. })
        .then_some(()))
    .is_empty());
    // The remapped TPDO1 runs: 0x2000 sub 1–3 of slave 2 on 0x182 every 100 ms.
    let pdo = frames(&run.sim)
        .into_iter()
        .find(|(_, f)| f.id() == Id::Standard(0x182))
        .map(|(_, f)| f.data().to_vec());
    assert_eq!(pdo, Some(vec![0x02, 0x01, 0x02, 0x02, 7, 0]));
    let first = run.sdo_requests(Instant::ZERO);
    // The same values read back over SDO by the master, in parallel on its sessions.
    let from = Instant::from_millis(500);
    assert_eq!(run.read_back(from, &read_back), read_back.len());
    println!("{} values read back over SDO", read_back.len());

    // A second boot of the master: every slave is reset (communication), reloads what it
    // stored, and holds the expected stamp: only 0x1000, the identity and 0x1020 are read.
    let t = Instant::from_millis(2_000);
    let master = run.master;
    run.sim.at(t, move |sim| {
        let now = sim.now();
        sim.device_mut(master).machine.boot(now);
    });
    run.sim.run_until(Instant::from_millis(2_500));
    let second = run.sdo_requests(t);
    println!("SDO requests: first boot {first}, second boot {second}");
    // 0x1000, 0x1018 sub 1–4, 0x1020 sub 1–2 per slave; the refusing slave, not stamped,
    // is configured again (its writes, 0x2000 sub 3 refused again).
    let reads = 7 * 20;
    let again = SlaveConfig::from_dcf(NodeId::must(REFUSING), &run.dcfs[19])
        .steps
        .len()
        + 1;
    assert_eq!(second, reads + again);
    let frames_after = frames(&run.sim);
    let writes_after = frames_after.iter().filter(|(at, f)| {
        *at >= t
            && matches!(f.id(), Id::Standard(c) if (0x602..=0x614).contains(&c))
            && f.data()[0] & 0xE0 == 0x20
    });
    assert_eq!(writes_after.count(), 0, "a stamped slave is written again");
    for id in IDS {
        assert_eq!(
            run.slave(id).nmt_state(),
            NmtState::Operational,
            "slave {id}"
        );
    }
}
