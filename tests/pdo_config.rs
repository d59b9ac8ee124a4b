//! Master-side PDO configuration: the configurator job against a slave's bus-side dictionary
//! access (the rules its SDO server applies), the seed's fallback for devices that refuse to be
//! disabled, and the master's mirrored PDOs exchanging data both ways at a 10 ms SYNC on the
//! simulated bus.

use duocan::machine::StationEvent;
use duocan::node::{NodeEventKind, ObjectAccess};
use duocan::od::{comm, Access, DataType, DynamicDictionary, ObjectDef, ObjectDictionary};
use duocan::pdo::{
    mirror, params, AccessError, ConfigErrorKind, Dir, Local, MapEntry, Mirror, MirrorError,
    PdoConfig, PdoConfigurator, PdoEvent, SdoAccess,
};
use duocan::sim::{BusConfig, SimNetwork, TraceRecord, TxOutcome};
use duocan::{
    AbortCode, CobId, Frame, Id, Instant, NmtCommand, NmtTarget, Node, NodeConfig, NodeId, Station,
};

const S: NodeId = NodeId::must(5);

fn slave_app() -> Vec<ObjectDef> {
    vec![
        ObjectDef::u8(0x6000, 0, Access::Rw, 0).mappable(),
        ObjectDef::u16(0x6001, 0, Access::Rw, 0).mappable(),
        ObjectDef::u8(0x6200, 0, Access::Rw, 0).mappable(),
        ObjectDef::new(0x6201, 0, DataType::Integer16)
            .mappable()
            .access(Access::Rw),
    ]
}

/// A slave dictionary with TPDO1 and RPDO1 (predefined COB-IDs, type 255, one entry each).
fn slave_od(tpdo_comm: &[ObjectDef]) -> DynamicDictionary {
    let mut od = comm::standard_dictionary(5, comm::Identity::default());
    od.insert_all(&slave_app()).unwrap();
    od.insert_all(tpdo_comm).unwrap();
    od.insert_all(&params::tpdo_mapping::<9>(1, &[0x6000_0008]))
        .unwrap();
    od.insert_all(&params::rpdo_comm(
        1,
        params::predefined_rpdo_cob(1),
        255,
        0,
    ))
    .unwrap();
    od.insert_all(&params::rpdo_mapping::<9>(1, &[0x6200_0008]))
        .unwrap();
    od
}

fn standard_tpdo1() -> [ObjectDef; params::TPDO_COMM_LEN] {
    params::tpdo_comm(1, params::predefined_tpdo_cob(1), 255, 0, 0)
}

/// Runs a job against a node's bus-side access; returns the accesses it made.
fn run_local<A: ObjectAccess>(
    job: &mut PdoConfigurator,
    dev: &mut A,
    now: Instant,
) -> Vec<SdoAccess> {
    let mut log = vec![];
    while let Some(a) = job.next() {
        log.push(a);
        let r = match a {
            SdoAccess::Read { index, sub } => dev.read(index, sub).map(<[u8]>::to_vec),
            SdoAccess::Write { index, sub, .. } => {
                dev.write(now, index, sub, a.data()).map(|_| vec![])
            }
        };
        job.handle(r.as_deref().map_err(|e| AccessError::Aborted(*e)));
    }
    log
}

fn tpdo_cfg() -> PdoConfig {
    PdoConfig::new(CobId(0x185), 1)
        .mapping(&[MapEntry::new(0x6000, 0, 8), MapEntry::new(0x6001, 0, 16)])
        .unwrap()
}

fn rpdo_cfg() -> PdoConfig {
    PdoConfig::new(CobId(0x205), 1)
        .mapping(&[MapEntry::new(0x6200, 0, 8), MapEntry::new(0x6201, 0, 16)])
        .unwrap()
}

#[test]
fn configurator_rewrites_a_slave_pdo_in_cia_order() {
    let mut slave = Node::new(NodeConfig::slave(S), slave_od(&standard_tpdo1()));
    slave.boot(Instant::ZERO);
    let cfg = tpdo_cfg().inhibit(20).event_timer(0);
    let mut job = PdoConfigurator::new(S, Dir::Transmit, 1, cfg);
    let log = run_local(&mut job, slave.core_mut(), Instant::ZERO);
    let r = job.result().unwrap().unwrap();
    assert!(!r.fallback);
    assert_eq!(r.previous_cob_id, CobId(0x185));
    assert_eq!(
        log.len(),
        10,
        "read, disable, 3 parameters, clear, 2 entries, count, enable"
    );
    let od = slave.od();
    assert_eq!(od.get_value::<u32>(0x1800, 1), Ok(0x185));
    assert_eq!(od.get_value::<u8>(0x1800, 2), Ok(1));
    assert_eq!(od.get_value::<u16>(0x1800, 3), Ok(20));
    assert_eq!(od.get_value::<u8>(0x1A00, 0), Ok(2));
    assert_eq!(od.get_value::<u32>(0x1A00, 2), Ok(0x6001_0010));
    let st = slave.tpdo_status(1).unwrap();
    assert_eq!((st.transmission_type, st.mapped_bits), (1, 24));

    // A mapping the device refuses ends the job with the device's abort code.
    let bad = PdoConfig::new(CobId(0x185), 1)
        .mapping(&[MapEntry::new(0x6001, 0, 16); 5])
        .unwrap();
    let mut job = PdoConfigurator::new(S, Dir::Transmit, 1, bad);
    run_local(&mut job, slave.core_mut(), Instant::ZERO);
    let e = job.result().unwrap().unwrap_err();
    assert_eq!((e.index, e.sub), (0x1A00, 0));
    assert_eq!(e.kind, ConfigErrorKind::Aborted(AbortCode::PDO_LENGTH));
}

fn refuse_disable(_: u16, _: u8, data: &[u8]) -> Result<(), AbortCode> {
    if data.get(3).is_some_and(|b| b & 0x80 != 0) {
        Err(AbortCode::DEVICE_STATE)
    } else {
        Ok(())
    }
}

/// TPDO1 whose COB-ID refuses bit 31, already on 0x185 mapping 0x6000 (8) and 0x6001 (16).
fn stubborn_slave() -> Node<DynamicDictionary> {
    let mut comm1 = standard_tpdo1();
    comm1[1] = comm1[1].hook(refuse_disable);
    let mut od = slave_od(&comm1);
    od.upsert(ObjectDef::u8(0x1A00, 0, Access::Rw, 2).object_type(duocan::od::ObjectType::Record));
    od.upsert(
        ObjectDef::u32(0x1A00, 2, Access::Rw, 0x6001_0010)
            .object_type(duocan::od::ObjectType::Record),
    );
    let mut n = Node::new(NodeConfig::slave(S), od);
    n.boot(Instant::ZERO);
    n
}

#[test]
fn seed_fallback_accepts_a_device_that_refuses_to_be_disabled_when_it_matches() {
    let mut slave = stubborn_slave();
    // Type can be written while valid; inhibit cannot, but already holds the wanted 0.
    let cfg = tpdo_cfg().inhibit(0);
    let mut job = PdoConfigurator::new(S, Dir::Transmit, 1, cfg);
    let log = run_local(&mut job, slave.core_mut(), Instant::ZERO);
    let r = job.result().unwrap().unwrap();
    assert!(r.fallback);
    assert_eq!(slave.od().get_value::<u8>(0x1800, 2), Ok(1), "type written");
    assert!(
        log.iter()
            .all(|a| !matches!(a, SdoAccess::Write { index: 0x1A00, .. })),
        "the mapping of a valid PDO is checked, never written"
    );
    assert!(
        log.contains(&SdoAccess::Read {
            index: 0x1800,
            sub: 3
        }),
        "inhibit read back"
    );

    // A different mapping cannot be accepted.
    let other = PdoConfig::new(CobId(0x185), 1)
        .mapping(&[MapEntry::new(0x6000, 0, 8), MapEntry::new(0x6001, 0, 12)])
        .unwrap();
    let mut job = PdoConfigurator::new(S, Dir::Transmit, 1, other);
    run_local(&mut job, slave.core_mut(), Instant::ZERO);
    let e = job.result().unwrap().unwrap_err();
    assert!(e.fallback);
    assert_eq!((e.index, e.sub), (0x1A00, 2));
    assert_eq!(
        e.kind,
        ConfigErrorKind::Mismatch {
            wanted: 0x6001_000C,
            found: 0x6001_0010
        }
    );
    assert!(e.to_string().contains("refuses to disable"));

    // Neither can another identifier, nor a parameter it refuses with another value.
    let mut job = PdoConfigurator::new(S, Dir::Transmit, 1, PdoConfig::new(CobId(0x186), 1));
    run_local(&mut job, slave.core_mut(), Instant::ZERO);
    let e = job.result().unwrap().unwrap_err();
    assert_eq!((e.index, e.sub), (0x1800, 1));
    let mut job = PdoConfigurator::new(
        S,
        Dir::Transmit,
        1,
        PdoConfig::new(CobId(0x185), 1).inhibit(7),
    );
    run_local(&mut job, slave.core_mut(), Instant::ZERO);
    let e = job.result().unwrap().unwrap_err();
    assert_eq!(
        (e.index, e.sub, e.kind),
        (
            0x1800,
            3,
            ConfigErrorKind::Mismatch {
                wanted: 7,
                found: 0
            }
        )
    );
}

#[test]
fn mirror_rejects_what_it_cannot_build() {
    let mut master = Node::new(
        NodeConfig::master(NodeId::must(1)),
        comm::standard_dictionary(1, comm::Identity::default()),
    );
    master.boot(Instant::ZERO);
    let locals = [Some(Local::new(0x2001, 1, DataType::Unsigned8)), None];
    let m = |pdo| Mirror {
        pdo,
        transmission_type: 255,
        event_timer_ms: 0,
        inhibit_100us: 0,
        locals: &locals,
    };
    let now = Instant::ZERO;
    assert_eq!(
        mirror(&mut master, now, Dir::Transmit, &tpdo_cfg(), &m(5)),
        Err(MirrorError::NoSuchPdo {
            pdo: 5,
            capacity: 4
        })
    );
    let wide = PdoConfig::new(CobId(0x185), 1)
        .mapping(&[MapEntry::new(0x6001, 0, 16), MapEntry::new(0x6000, 0, 8)])
        .unwrap();
    assert_eq!(
        mirror(&mut master, now, Dir::Transmit, &wide, &m(1)),
        Err(MirrorError::TooShort {
            index: 0x2001,
            sub: 1,
            bits: 16
        })
    );
    assert_eq!(
        mirror(
            &mut master,
            now,
            Dir::Transmit,
            &PdoConfig::new(CobId(0x185), 1),
            &m(1)
        ),
        Err(MirrorError::NoMapping)
    );
    // Dummy for the slave's 16-bit value: only 0x6000 lands locally.
    mirror(&mut master, now, Dir::Transmit, &tpdo_cfg(), &m(1)).unwrap();
    assert_eq!(master.od().get_value::<u32>(0x1600, 2), Ok(0x0006_0010));
    assert_eq!(master.rpdo_status(1).unwrap().id, Some(Id::Standard(0x185)));
}

/// Two-way exchange on the simulated bus: the master configures the slave's TPDO1 and RPDO1 (the
/// configurator's accesses applied through the slave's bus-side dictionary access), mirrors them
/// into its own RPDO1/TPDO1, produces SYNC every 10 ms, and both sides see each other's values
/// at the SYNC CiA 301 says.
#[test]
fn master_configures_then_exchanges_both_ways_at_10ms_sync() {
    let mut slave = Node::new(NodeConfig::slave(S), slave_od(&standard_tpdo1()));
    slave.boot(Instant::ZERO);
    for (dir, cfg) in [(Dir::Transmit, tpdo_cfg()), (Dir::Receive, rpdo_cfg())] {
        let mut job = PdoConfigurator::new(S, dir, 1, cfg);
        run_local(&mut job, slave.core_mut(), Instant::ZERO);
        assert!(job.result().unwrap().is_ok());
    }
    let mut master = Node::new(
        NodeConfig::master(NodeId::must(1)),
        comm::standard_dictionary(1, comm::Identity::default()),
    );
    master.boot(Instant::ZERO);
    let now = Instant::ZERO;
    let inputs = [
        Some(Local::new(0x2005, 1, DataType::Unsigned8)),
        Some(Local::new(0x2005, 2, DataType::Unsigned16)),
    ];
    let outputs = [
        Some(Local::new(0x2105, 1, DataType::Unsigned8)),
        Some(Local::new(0x2105, 2, DataType::Integer16)),
    ];
    let rx = Mirror {
        pdo: 1,
        transmission_type: 255,
        event_timer_ms: 25,
        inhibit_100us: 0,
        locals: &inputs,
    };
    let tx = Mirror {
        pdo: 1,
        transmission_type: 1,
        event_timer_ms: 0,
        inhibit_100us: 0,
        locals: &outputs,
    };
    mirror(&mut master, now, Dir::Transmit, &tpdo_cfg(), &rx).unwrap();
    mirror(&mut master, now, Dir::Receive, &rpdo_cfg(), &tx).unwrap();
    master
        .set(now, comm::SYNC_COB_ID, 0, 0x4000_0080u32)
        .unwrap();
    master.set(now, comm::SYNC_PERIOD, 0, 10_000u32).unwrap();
    master
        .nmt_command(now, NmtCommand::Start, NmtTarget::Node(S))
        .unwrap();

    let mut sim = SimNetwork::new(3);
    let bus = sim.add_bus(BusConfig::new("can0", 250_000));
    let m = sim
        .add_device("master", Station::single(master), &[bus])
        .unwrap();
    let s = sim
        .add_device("slave", Station::single(slave), &[bus])
        .unwrap();
    // Application values change at k·10 ms + 5 ms on both sides.
    for k in 0..100u64 {
        sim.at(Instant::from_micros(k * 10_000 + 5_000), move |sim| {
            let now = sim.now();
            let sl = &mut sim.device_mut(s).machine;
            sl.set(now, 0x6000, 0, k as u8).unwrap();
            sl.set(now, 0x6001, 0, 1000 + k as u16).unwrap();
            let ma = &mut sim.device_mut(m).machine;
            ma.write(now, 0x2105, 1, &[k as u8 ^ 0xFF]).unwrap();
            ma.write(now, 0x2105, 2, &(-(k as i16)).to_le_bytes())
                .unwrap();
        });
    }
    sim.run_until(Instant::from_millis(1_005));

    let wire = |id: u16| -> Vec<(Instant, Instant, Frame)> {
        sim.trace()
            .iter()
            .filter_map(|r| match r {
                TraceRecord::Tx(t)
                    if t.frame.id() == Id::Standard(id)
                        && matches!(t.outcome, TxOutcome::Delivered { .. }) =>
                {
                    Some((t.start, t.end, t.frame))
                }
                _ => None,
            })
            .collect()
    };
    let syncs = wire(0x80);
    assert_eq!(syncs.len(), 100);
    assert_eq!(syncs[0].0, Instant::from_millis(10));
    // Slave → master: TPDO1 at each SYNC, carrying the values written 5 ms before.
    let up = wire(0x185);
    assert_eq!(up.len(), 100);
    for (k, (start, _, f)) in up.iter().enumerate() {
        assert_eq!(
            *start,
            syncs[k].1,
            "slave answers the instant SYNC {} ends",
            k + 1
        );
        let v = k as u64;
        assert_eq!(
            f.data(),
            [v as u8, (1000 + v) as u8, ((1000 + v) >> 8) as u8]
        );
    }
    // Master → slave: TPDO1 queued at each SYNC it produces, on the wire right after the
    // slave's TPDO1, which wins arbitration (lower identifier).
    let down = wire(0x205);
    assert_eq!(down.len(), 100);
    assert!(down.iter().zip(&up).all(|(d, u)| d.0 == u.1));
    // Both sides applied what they received: the master at once, the slave at the next SYNC.
    let ma = &sim.device(m).machine;
    assert_eq!(ma.od().get_value::<u8>(0x2005, 1), Ok(99));
    assert_eq!(ma.od().get_value::<u16>(0x2005, 2), Ok(1099));
    let sl = &sim.device(s).machine;
    assert_eq!(sl.od().get_value::<u8>(0x6200, 0), Ok(98 ^ 0xFF));
    assert_eq!(sl.od().get_value::<i16>(0x6201, 0), Ok(-98));
    let applied: Vec<Instant> = sim
        .events(s)
        .iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Machine(ev) => match ev.kind {
                NodeEventKind::Pdo(PdoEvent::RpdoReceived { pdo: 1 }) => Some(ev.at),
                _ => None,
            },
            _ => None,
        })
        .collect();
    let expected: Vec<Instant> = syncs[1..].iter().map(|s| s.1).collect();
    assert_eq!(
        applied, expected,
        "synchronous RPDO: at the SYNC after reception"
    );
    // The master's reception timeout (25 ms) never fired while the slave kept sending.
    assert!(!sim.events(m).iter().any(|(_, e)| matches!(
        e,
        StationEvent::Machine(ev) if matches!(ev.kind, NodeEventKind::Pdo(PdoEvent::RpdoTimeout { .. }))
    )));
}
