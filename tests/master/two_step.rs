//! A master built in two steps (`Master::unconfigured`, then `Master::configure`), as a
//! firmware image builds it in place: the same master as `Master::new`, frame for frame; the
//! configuration written once, before boot; its errors found before anything is written.

use crate::net::*;
use duocan::master::objects::{self, SLAVE_ASSIGNMENT, VENDOR_ID};
use duocan::master::{Master, MasterConfig, MasterError, MasterSdoClient, SlaveConfig};
use duocan::node::NodeConfig;
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::profile::Predefined;
use duocan::sdo::DEFAULT_LIMIT;
use duocan::{Instant, NodeId};

fn config() -> MasterConfig {
    let slave = |id| {
        SlaveConfig::new(NodeId::must(id))
            .identity(expected(id))
            .heartbeat(50, 150)
    };
    MasterConfig::new()
        .max_slaves(4)
        .slave(slave(2))
        .slave(slave(3))
}

fn dictionary() -> DynamicDictionary {
    objects::master_dictionary(MASTER_ID.raw(), comm::Identity::default())
}

fn unconfigured(config: &MasterConfig) -> Master<DynamicDictionary> {
    let sdo = MasterSdoClient::with_sessions(DEFAULT_LIMIT, config.sdo_sessions);
    let node = NodeConfig::master(MASTER_ID);
    Master::unconfigured(node, dictionary(), Predefined, sdo, config)
}

/// Boots the master and slaves 2 and 3 and runs the bus for 600 ms: every frame on it.
fn run(m: Master<DynamicDictionary>) -> Vec<(Instant, duocan::Frame)> {
    let mut n = Net::new(500_000, m, &[2, 3]);
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(5));
    n.boot_slave_at(3, Instant::from_millis(7));
    n.sim.run_until(Instant::from_millis(600));
    assert_eq!(
        n.m()
            .slaves()
            .filter(|s| s.state == Some(duocan::NmtState::Operational))
            .count(),
        2
    );
    n.frames()
}

#[test]
fn built_in_two_steps_it_is_the_master_new_builds_frame_for_frame() {
    let one = Master::new(MASTER_ID, dictionary(), config()).unwrap();
    let mut two = unconfigured(&config());
    two.configure(config()).unwrap();
    let (a, b) = (run(one), run(two));
    assert!(a.len() > 20, "{}", a.len());
    assert_eq!(a, b);
}

#[test]
fn the_configuration_is_written_once_before_boot() {
    let mut m = unconfigured(&config());
    // Nothing is written until configured.
    assert_eq!(m.node().od().get_u32(SLAVE_ASSIGNMENT, 2), Some(0));
    m.configure(config()).unwrap();
    assert_eq!(
        m.node().od().get_u32(SLAVE_ASSIGNMENT, 2).map(|v| v & 1),
        Some(1)
    );
    assert_eq!(m.node().od().get_u32(VENDOR_ID, 3), Some(VENDOR));
    m.boot(Instant::ZERO);
    let e = m.configure(config()).unwrap_err();
    assert_eq!(e, MasterError::AlreadyBooted);
    assert!(e.to_string().contains("before boot"), "{e}");
}

#[test]
fn a_bad_slave_is_found_before_anything_is_written() {
    let mut m = unconfigured(&config());
    // Slave 2 is fine, the second names the master itself.
    let bad = config().slave(SlaveConfig::new(MASTER_ID));
    assert_eq!(
        m.configure(bad).unwrap_err(),
        MasterError::OwnNode(MASTER_ID)
    );
    assert_eq!(m.node().od().get_u32(SLAVE_ASSIGNMENT, 2), Some(0));
    assert_eq!(m.node().od().get_u32(VENDOR_ID, 2), Some(0));
    // A dictionary without the master objects: named, nothing written.
    let sdo = MasterSdoClient::with_sessions(DEFAULT_LIMIT, 1);
    let node = NodeConfig::master(MASTER_ID);
    let bare = comm::standard_dictionary(MASTER_ID.raw(), comm::Identity::default());
    let mut m = Master::unconfigured(node, bare, Predefined, sdo, &config());
    let e = m.configure(config()).unwrap_err();
    assert!(matches!(e, MasterError::MissingObject { .. }), "{e}");
}
