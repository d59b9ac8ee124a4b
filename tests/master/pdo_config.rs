//! Master-side PDO configuration: the configurator job against a slave's bus-side dictionary
//! access (the rules its SDO server applies), the published design's fallback for devices that
//! refuse to be disabled, and, on the simulated bus, configuration over SDO followed by the
//! master's mirrored PDOs exchanging data both ways at a 10 ms SYNC.

use duocan::cia302::pdo_config::{
    mirror, AccessError, Local, Mirror, MirrorError, PdoConfig, PdoConfigErrorKind,
    PdoConfigurator, SdoAccess, SdoPdoJob,
};
use duocan::machine::{Composite, CompositeEvent, SinglePort, StationEvent};
use duocan::node::NodeEventKind;
use duocan::od::ObjectAccess;
use duocan::od::{comm, Access, DataType, DynamicDictionary, ObjectDef, ObjectDictionary};
use duocan::pdo::{params, Dir, MapEntry, PdoEvent};
use duocan::sdo::SdoClient;
use duocan::sim::{BusConfig, DevId, SimNetwork, TraceRecord, TxOutcome};
use duocan::{
    AbortCode, CobId, Duration, Frame, Id, Instant, NmtCommand, NmtTarget, Node, NodeConfig,
    NodeId, Station,
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
fn slave_od(id: u8, tpdo_comm: &[ObjectDef]) -> DynamicDictionary {
    let mut od = comm::standard_dictionary(id, comm::Identity::default());
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

fn tpdo6_cfg() -> PdoConfig {
    PdoConfig {
        cob_id: CobId(0x186),
        ..tpdo_cfg()
    }
}

fn rpdo_cfg() -> PdoConfig {
    PdoConfig::new(CobId(0x205), 1)
        .mapping(&[MapEntry::new(0x6200, 0, 8), MapEntry::new(0x6201, 0, 16)])
        .unwrap()
}

#[test]
fn configurator_rewrites_a_slave_pdo_in_cia_order() {
    let mut slave = Node::new(NodeConfig::slave(S), slave_od(5, &standard_tpdo1()));
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
    assert_eq!(e.kind, PdoConfigErrorKind::Aborted(AbortCode::PDO_LENGTH));
}

fn refuse_disable(_: u16, _: u8, data: &[u8]) -> Result<(), AbortCode> {
    if data.get(3).is_some_and(|b| b & 0x80 != 0) {
        Err(AbortCode::DEVICE_STATE)
    } else {
        Ok(())
    }
}

/// TPDO1 whose COB-ID refuses bit 31, already on 0x185 mapping 0x6000 (8) and 0x6001 (16).
fn stubborn_slave(id: u8) -> Node<DynamicDictionary> {
    let mut comm1 = standard_tpdo1();
    comm1[1] = comm1[1].hook(refuse_disable);
    let mut od = slave_od(id, &comm1);
    od.upsert(ObjectDef::u8(0x1A00, 0, Access::Rw, 2).object_type(duocan::od::ObjectType::Record));
    od.upsert(
        ObjectDef::u32(0x1A00, 2, Access::Rw, 0x6001_0010)
            .object_type(duocan::od::ObjectType::Record),
    );
    let mut n = Node::new(NodeConfig::slave(NodeId::must(id)), od);
    n.boot(Instant::ZERO);
    n
}

#[test]
fn seed_fallback_accepts_a_device_that_refuses_to_be_disabled_when_it_matches() {
    let mut slave = stubborn_slave(5);
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
        PdoConfigErrorKind::Mismatch {
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
            PdoConfigErrorKind::Mismatch {
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

type Master = Station<SinglePort, Composite<Node<DynamicDictionary>, SdoClient>>;

/// Configuration over SDO, then two-way exchange, on the simulated bus at 250 kbit/s. The master
/// configures slave 5's TPDO1 and RPDO1 and slave 6's TPDO1 (slave 6 refuses to disable it and
/// is accepted by the fallback because it already matches), mirrors them into its own RPDO1,
/// TPDO1 and RPDO2, starts the network and produces SYNC every 10 ms. Each side sees the other's
/// values at the SYNC CiA 301 says.
#[test]
fn master_configures_slaves_over_sdo_then_exchanges_both_ways_at_10ms_sync() {
    let mut sim = SimNetwork::new(3);
    let bus = sim.add_bus(BusConfig::new("can0", 250_000));
    let master = Node::new(
        NodeConfig::master(NodeId::must(1)),
        comm::standard_dictionary(1, comm::Identity::default()),
    );
    let pair = Composite::new(master, SdoClient::new(64));
    let m: DevId<Master> = sim
        .add_device("master", Station::single(pair), &[bus])
        .unwrap();
    let s5 = Node::new(NodeConfig::slave(S), slave_od(5, &standard_tpdo1()));
    let s5 = sim
        .add_device("slave5", Station::single(s5), &[bus])
        .unwrap();
    let s6 = sim
        .add_device("slave6", Station::single(stubborn_slave(6)), &[bus])
        .unwrap();
    sim.device_mut(m).machine.a.boot(Instant::ZERO);
    sim.device_mut(s5).machine.boot(Instant::ZERO);

    // 1. Configure over SDO: three jobs; the client serves one transfer per node at a time.
    let n6 = NodeId::must(6);
    let mut jobs = [
        SdoPdoJob::new(PdoConfigurator::new(S, Dir::Transmit, 1, tpdo_cfg())),
        SdoPdoJob::new(PdoConfigurator::new(S, Dir::Receive, 1, rpdo_cfg())),
        SdoPdoJob::new(PdoConfigurator::new(n6, Dir::Transmit, 1, tpdo6_cfg())),
    ];
    let now = sim.now();
    for j in jobs.iter_mut() {
        j.poll(now, &mut sim.device_mut(m).machine.b);
    }
    while jobs.iter().any(|j| j.result().is_none()) {
        let t = sim.step().expect("configuration stalled");
        assert!(
            t < Instant::from_millis(200),
            "configuration takes too long"
        );
        for (_, e) in sim.take_events(m) {
            if let StationEvent::Machine(CompositeEvent::B(ev)) = e {
                assert!(
                    jobs.iter_mut().any(|j| j.handle_event(&ev)),
                    "unclaimed {ev:?}"
                );
            }
        }
        let client = &mut sim.device_mut(m).machine.b;
        for j in jobs.iter_mut() {
            j.poll(t, client);
        }
    }
    let results: Vec<_> = jobs.iter().map(|j| j.result().unwrap().unwrap()).collect();
    assert_eq!(
        results.iter().map(|r| r.fallback).collect::<Vec<_>>(),
        [false, false, true]
    );
    let configured = sim.now();
    let sdo_frames = sim
        .trace()
        .iter()
        .filter(
            |r| matches!(r, TraceRecord::Tx(t) if (0x581..=0x67F).contains(&t.frame.id().raw())),
        )
        .count();
    // Slave 5: 2 × (read, disable, type, clear, 2 entries, count, enable); slave 6: read,
    // refused disable, type, then the mapping checked (count, 2 entries). Expedited: 2 frames each.
    assert_eq!(sdo_frames, 2 * (8 + 8 + 6));
    let sl = &sim.device(s5).machine;
    assert_eq!(sl.od().get_value::<u8>(0x1800, 2), Ok(1));
    assert_eq!(sl.od().get_value::<u32>(0x1A00, 2), Ok(0x6001_0010));
    assert_eq!(sl.od().get_value::<u32>(0x1600, 2), Ok(0x6201_0010));
    assert_eq!(
        sim.device(s6).machine.od().get_value::<u8>(0x1800, 2),
        Ok(1)
    );

    // 2. Mirror the slaves' PDOs in the master, produce SYNC, start everyone.
    let inputs5 = [
        Some(Local::new(0x2005, 1, DataType::Unsigned8)),
        Some(Local::new(0x2005, 2, DataType::Unsigned16)),
    ];
    let inputs6 = [
        Some(Local::new(0x2006, 1, DataType::Unsigned8)),
        Some(Local::new(0x2006, 2, DataType::Unsigned16)),
    ];
    let outputs5 = [
        Some(Local::new(0x2105, 1, DataType::Unsigned8)),
        Some(Local::new(0x2105, 2, DataType::Integer16)),
    ];
    let mir = |pdo, transmission_type, locals| Mirror {
        pdo,
        transmission_type,
        event_timer_ms: 25,
        inhibit_100us: 0,
        locals,
    };
    let master = &mut sim.device_mut(m).machine.a;
    let t0 = configured;
    mirror(
        master,
        t0,
        Dir::Transmit,
        &tpdo_cfg(),
        &mir(1, 255, &inputs5),
    )
    .unwrap();
    mirror(
        master,
        t0,
        Dir::Transmit,
        &tpdo6_cfg(),
        &mir(2, 255, &inputs6),
    )
    .unwrap();
    mirror(master, t0, Dir::Receive, &rpdo_cfg(), &mir(1, 1, &outputs5)).unwrap();
    master
        .set(t0, comm::SYNC_COB_ID, 0, 0x4000_0080u32)
        .unwrap();
    master.set(t0, comm::SYNC_PERIOD, 0, 10_000u32).unwrap();
    master
        .nmt_command(t0, NmtCommand::Start, NmtTarget::All)
        .unwrap();

    // 3. Application values change 5 ms after each SYNC, on every node.
    for k in 0..100u64 {
        sim.at(t0 + Duration::from_micros(k * 10_000 + 5_000), move |sim| {
            let now = sim.now();
            let a = &mut sim.device_mut(s5).machine;
            a.set(now, 0x6000, 0, k as u8).unwrap();
            a.set(now, 0x6001, 0, 1000 + k as u16).unwrap();
            let b = &mut sim.device_mut(s6).machine;
            b.set(now, 0x6000, 0, 50 + k as u8).unwrap();
            b.set(now, 0x6001, 0, 2000 + k as u16).unwrap();
            let ma = &mut sim.device_mut(m).machine.a;
            ma.write(now, 0x2105, 1, &[k as u8 ^ 0xFF]).unwrap();
            ma.write(now, 0x2105, 2, &(-(k as i16)).to_le_bytes())
                .unwrap();
        });
    }
    sim.run_until(t0 + Duration::from_millis(1_005));

    let wire = |id: u16| -> Vec<(Instant, Instant, Frame)> {
        sim.trace()
            .iter()
            .filter_map(|r| match r {
                TraceRecord::Tx(t)
                    if t.frame.id() == Id::Standard(id)
                        && t.start >= t0
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
    assert!(syncs
        .iter()
        .enumerate()
        .all(|(k, s)| s.0 == t0 + Duration::from_millis(10 * (k as u64 + 1))));
    // Slaves → master: TPDO1 of each slave at every SYNC, with the values written 5 ms before.
    let up5 = wire(0x185);
    let up6 = wire(0x186);
    assert_eq!((up5.len(), up6.len()), (100, 100));
    for k in 0..100 {
        let v = k as u64;
        assert_eq!(
            up5[k].0,
            syncs[k].1,
            "slave 5 answers the instant SYNC {} ends",
            k + 1
        );
        assert_eq!(up6[k].0, up5[k].1, "slave 6 right after (arbitration)");
        assert_eq!(
            up5[k].2.data(),
            [v as u8, (1000 + v) as u8, ((1000 + v) >> 8) as u8]
        );
        assert_eq!(
            up6[k].2.data(),
            [50 + v as u8, (2000 + v) as u8, ((2000 + v) >> 8) as u8]
        );
    }
    // Master → slave 5: TPDO1 queued at each SYNC it produces, on the wire after the slaves'.
    let down = wire(0x205);
    assert_eq!(down.len(), 100);
    assert!(down.iter().zip(&up6).all(|(d, u)| d.0 == u.1));
    // The master applied what it received at once; slave 5 at the SYNC after reception.
    let ma = &sim.device(m).machine.a;
    assert_eq!(ma.od().get_value::<u8>(0x2005, 1), Ok(99));
    assert_eq!(ma.od().get_value::<u16>(0x2005, 2), Ok(1099));
    assert_eq!(ma.od().get_value::<u8>(0x2006, 1), Ok(149));
    assert_eq!(ma.od().get_value::<u16>(0x2006, 2), Ok(2099));
    let sl = &sim.device(s5).machine;
    assert_eq!(sl.od().get_value::<u8>(0x6200, 0), Ok(98 ^ 0xFF));
    assert_eq!(sl.od().get_value::<i16>(0x6201, 0), Ok(-98));
    let applied: Vec<Instant> = sim
        .events(s5)
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
    // The master's reception timeouts (25 ms) never fired while the slaves kept sending.
    assert!(!sim.events(m).iter().any(|(_, e)| matches!(
        e,
        StationEvent::Machine(CompositeEvent::A(ev)) if matches!(ev.kind, NodeEventKind::Pdo(PdoEvent::RpdoTimeout { .. }))
    )));
}
