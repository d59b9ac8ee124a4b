//! The master's slots sized to its slaves (`MasterConfig::max_slaves`): allocated once, only
//! slaves get one, and a slave beyond them is an error (from the configuration, `add_slave`) or
//! an event with the 0x1F81 entry set back (a write over the bus), never growth.

use crate::net::*;
use duocan::machine::{CompositeEvent, StationEvent};
use duocan::master::objects::SLAVE_ASSIGNMENT;
use duocan::master::{BootPhase, MasterConfig, MasterError, MasterEventKind as K, SlaveConfig};
use duocan::od::{comm, ObjectDictionary};
use duocan::sdo::SdoOptions;
use duocan::{Instant, NmtState, NodeId};

const BITRATE: u32 = 500_000;

fn cfg(id: u8) -> SlaveConfig {
    SlaveConfig::new(NodeId::must(id))
        .identity(expected(id))
        .heartbeat(50, 150)
}

fn two_slots() -> MasterConfig {
    MasterConfig::new()
        .max_slaves(2)
        .slave(cfg(2))
        .slave(cfg(3))
}

#[test]
fn a_configuration_with_more_slaves_than_slots_is_refused_naming_the_first_beyond() {
    let od = objects_dictionary();
    let err = duocan::master::Master::new(MASTER_ID, od, two_slots().slave(cfg(4)))
        .err()
        .expect("three slaves in two slots");
    assert_eq!(
        err,
        MasterError::TooManySlaves {
            node: NodeId::must(4),
            capacity: 2
        }
    );
    assert!(err.to_string().contains("max_slaves"), "{err}");
}

#[test]
fn a_slave_assigned_in_the_dictionary_beyond_the_slots_is_refused_too() {
    let mut od = objects_dictionary();
    od.write_local(SLAVE_ASSIGNMENT, 9, &1u32.to_le_bytes())
        .unwrap();
    let err = duocan::master::Master::new(MASTER_ID, od, two_slots())
        .err()
        .expect("node 9 assigned beyond two slots");
    assert_eq!(
        err,
        MasterError::TooManySlaves {
            node: NodeId::must(9),
            capacity: 2
        }
    );
}

fn objects_dictionary() -> duocan::od::DynamicDictionary {
    duocan::master::objects::master_dictionary(MASTER_ID.raw(), comm::Identity::default())
}

#[test]
fn a_master_with_two_slots_boots_its_two_slaves_and_refuses_a_third() {
    let mut n = Net::new(BITRATE, master(two_slots()), &[2, 3, 4]);
    n.boot_master();
    for id in [2, 3, 4] {
        n.boot_slave_at(id, Instant::from_millis(1));
    }
    n.sim.run_until(Instant::from_millis(200));
    for id in [2, 3] {
        assert_eq!(n.slave(id).nmt_state(), NmtState::Operational, "slave {id}");
        let v = n.m().slave(NodeId::must(id));
        assert_eq!(v.phase, BootPhase::Started, "slave {id}");
        assert_eq!(v.boot_ups, 1, "slave {id}");
        assert!(n.m().slave_config(NodeId::must(id)).is_some());
    }
    // Node 4 is not a slave: no slot, so nothing noted of it beyond what its heartbeat shows
    // (a master with a slot for every node-ID counts its boot-up).
    let four = NodeId::must(4);
    let v = n.m().slave(four);
    assert_eq!(v.phase, BootPhase::Unassigned);
    assert_eq!(v.boot_ups, 0);
    assert_eq!(v.state, Some(NmtState::PreOperational));
    assert!(n.m().slave_config(four).is_none());

    let t = n.sim.now();
    assert_eq!(
        n.m_mut().add_slave(t, cfg(4)),
        Err(MasterError::TooManySlaves {
            node: four,
            capacity: 2
        })
    );
    // Refused before anything was written.
    let od = n.m().node().od();
    assert_eq!(od.get_value::<u32>(SLAVE_ASSIGNMENT, 4), Ok(0));
    assert_eq!(od.get_value::<u32>(comm::HEARTBEAT_CONSUMER, 4), Ok(0));
    n.sim.run_until(Instant::from_millis(400));
    assert_eq!(n.slave(4).nmt_state(), NmtState::PreOperational);
}

#[test]
fn the_default_keeps_a_slot_for_every_node_id() {
    let net = MasterConfig::new().slave(cfg(2)).slave(cfg(3));
    assert_eq!(net.max_slaves, 127);
    let mut n = Net::new(BITRATE, master(net), &[2, 3, 4]);
    n.boot_master();
    for id in [2, 3, 4] {
        n.boot_slave_at(id, Instant::from_millis(1));
    }
    n.sim.run_until(Instant::from_millis(200));
    let four = NodeId::must(4);
    assert_eq!(n.m().slave(four).boot_ups, 1);
    assert!(n.m().slave_config(four).is_some());
}

#[test]
fn a_0x1f81_write_over_the_bus_beyond_the_slots_is_set_back_and_reported() {
    let (mut n, tool) = with_tool(BITRATE, two_slots(), 64);
    n.sim.run_until(Instant::from_millis(200));
    let now = n.sim.now();
    let id = n
        .sim
        .device_mut(tool)
        .machine
        .b
        .download(
            now,
            MASTER_ID,
            SLAVE_ASSIGNMENT,
            5,
            &1u32.to_le_bytes(),
            SdoOptions::default(),
        )
        .unwrap();
    let result = loop {
        n.sim.step().expect("idle without a result");
        let done = n
            .sim
            .take_events(tool)
            .into_iter()
            .find_map(|(_, e)| match e {
                StationEvent::Machine(CompositeEvent::B(e)) if e.request == id => Some(e.result),
                _ => None,
            });
        if let Some(r) = done {
            break r;
        }
    };
    // The write itself was accepted (the entry takes any value); the master set it back.
    assert!(result.is_ok(), "{result:?}");
    n.sim
        .run_until(n.sim.now() + duocan::Duration::from_millis(10));
    let five = NodeId::must(5);
    assert!(find(&n.events(), |k| match k {
        K::TooManySlaves { node, capacity: 2 } if *node == five => Some(()),
        _ => None,
    })
    .is_some());
    assert_eq!(
        n.m().node().od().get_value::<u32>(SLAVE_ASSIGNMENT, 5),
        Ok(0)
    );
    assert_eq!(n.m().slave(five).phase, BootPhase::Unassigned);
    assert!(n
        .m()
        .slaves()
        .all(|v| v.node.raw() == 2 || v.node.raw() == 3));
}
