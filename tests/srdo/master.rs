//! The master configures a slave's SRDO over SDO during its boot (parameters, mapping,
//! checksum, 0x13FE) and starts it; the slave then produces. A configuration the slave cannot
//! serve keeps it out of operational.

use crate::support::*;
use duocan::cia304::srdo::config::{self, SrdoConfig};
use duocan::master::{objects as master_objects, Master, MasterConfig, SlaveConfig};
use duocan::od::{comm, ObjectDictionary};
use duocan::pdo::MapEntry;
use duocan::sim::{BusConfig, SimNetwork};
use duocan::{Id, Instant, NmtState, NodeId, Station};

fn boot(
    cfg: &SrdoConfig,
) -> (
    SimNetwork,
    duocan::sim::DevId<Station<duocan::machine::SinglePort, crate::common::TestNode>>,
) {
    let id = NodeId::must(P_ID);
    let slave_cfg = SlaveConfig::new(id).mandatory().srdo(1, cfg);
    let net = MasterConfig::new().slave(slave_cfg);
    let od = master_objects::master_dictionary(1, comm::Identity::default());
    let master = Master::new(NodeId::must(1), od, net).unwrap();
    let mut slave = bare(P_ID);
    // The application's value, plain and inverted.
    slave.set(Instant::ZERO, 0x6000, 0, 0x0102u16).unwrap();
    slave.set(Instant::ZERO, 0x6001, 0, 0x03u8).unwrap();
    slave.set(Instant::ZERO, 0x6010, 0, !0x0102u16).unwrap();
    slave.set(Instant::ZERO, 0x6011, 0, !0x03u8).unwrap();
    let mut sim = SimNetwork::new(1);
    let bus = sim.add_bus(BusConfig::new("can0", 500_000));
    let m = sim
        .add_device("master", Station::single(master), &[bus])
        .unwrap();
    let s = sim
        .add_device("slave", Station::single(slave), &[bus])
        .unwrap();
    sim.device_mut(m).machine.boot(Instant::ZERO);
    sim.device_mut(s).machine.boot(Instant::ZERO);
    sim.run_until(Instant::from_millis(200));
    (sim, s)
}

#[test]
fn the_master_configures_the_slave_srdo_and_the_slave_produces() {
    let cfg = SrdoConfig::new(true, REFRESH_MS, SRVT_MS, NORMAL, mapping());
    let (sim, s) = boot(&cfg);
    let slave = &sim.device(s).machine;
    assert_eq!(slave.nmt_state(), NmtState::Operational);
    let od = slave.od();
    let sum = config::signature(&cfg.params, &cfg.mapping);
    assert_eq!(od.get_value::<u16>(config::CHECKSUMS, 1), Ok(sum));
    assert_eq!(
        od.get_value::<u8>(config::CONFIG_VALID, 0),
        Ok(config::VALID)
    );
    let pairs = sim
        .trace()
        .iter()
        .filter(|r| matches!(r, duocan::sim::TraceRecord::Tx(x) if x.frame.id() == Id::Standard(INVERTED)))
        .count();
    assert!(
        pairs >= 5,
        "the slave produces once started ({pairs} pairs)"
    );
}

#[test]
fn a_configuration_the_slave_cannot_serve_keeps_it_preoperational() {
    // 0x6500 does not exist on the slave: every write is taken, the start is refused.
    let bad =
        config::SrdoMapping::pairs(&[(MapEntry::new(0x6500, 0, 16), MapEntry::new(0x6010, 0, 16))]);
    let cfg = SrdoConfig::new(true, REFRESH_MS, SRVT_MS, NORMAL, bad);
    let (sim, s) = boot(&cfg);
    assert_eq!(sim.device(s).machine.nmt_state(), NmtState::PreOperational);
    // It was told to start, and said why not: the entry the mapping names.
    let reason = sim.events(s).iter().find_map(|(_, e)| match e {
        duocan::machine::StationEvent::Machine(n) => match n.kind {
            duocan::node::NodeEventKind::OperationalRefused { reason } => Some(reason),
            _ => None,
        },
        _ => None,
    });
    let reason = reason.expect("the refusal is reported");
    assert_eq!((reason.index, reason.sub), (config::MAPPING, 1));
    assert_eq!(
        reason.problem,
        config::SrdoProblem::Mapping(duocan::AbortCode::NO_OBJECT)
    );
}
