//! What the application (a slave-pair supervisor) does through the master: assign a slave at
//! run time, boot one again on demand, command NMT; and the 0x1F80/0x1F81 bits for error control
//! of mandatory slaves and node guarding.

use crate::net::*;
use duocan::master::{
    BootPhase, ErrorStatus, MasterConfig, MasterError, MasterEventKind as K, NmtStartup,
    SlaveConfig, StartPolicy,
};
use duocan::od::{comm, ObjectDictionary};
use duocan::{Duration, Id, Instant, NmtCommand, NmtState, NmtTarget, NodeId};

const BITRATE: u32 = 500_000;

fn cfg(id: u8) -> SlaveConfig {
    SlaveConfig::new(NodeId::must(id))
        .identity(expected(id))
        .heartbeat(50, 150)
        .write_u16(APP, 1, 0x77)
}

#[test]
fn slave_assigned_at_run_time_is_probed_configured_and_started() {
    let mut n = Net::new(BITRATE, master(MasterConfig::new().slave(cfg(2))), &[2, 3]);
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(1));
    // Slave 3 runs unassigned: its boot-up is not the master's business.
    n.boot_slave_at(3, Instant::from_millis(1));
    n.sim.run_until(Instant::from_millis(100));
    assert_eq!(n.slave(3).nmt_state(), NmtState::PreOperational);
    assert_eq!(n.m().slave(NodeId::must(3)).phase, BootPhase::Unassigned);
    assert!(n.m().slaves().all(|v| v.node.raw() == 2));

    let t = n.sim.now();
    n.m_mut().add_slave(t, cfg(3)).unwrap();
    // Its 0x1F8x entries and the consumer entry were written.
    let od = n.m().node().od();
    assert_eq!(
        od.get_value::<u32>(duocan::master::objects::SLAVE_ASSIGNMENT, 3),
        Ok(0b101)
    );
    assert_eq!(
        od.get_value::<u32>(duocan::master::objects::PRODUCT_CODE, 3),
        Ok(expected(3).product)
    );
    assert_eq!(
        od.get_value::<u32>(comm::HEARTBEAT_CONSUMER, 3),
        Ok((3 << 16) | 150)
    );
    n.sim.run_until(Instant::from_millis(200));
    // Found by the probe (its boot-up is long gone), configured and started, no reset.
    let (started, _) = find(&n.events(), |k| match k {
        K::SlaveStarted { node, .. } if node.raw() == 3 => Some(()),
        _ => None,
    })
    .unwrap();
    assert!(started - t < Duration::from_millis(5));
    assert_eq!(n.slave(3).nmt_state(), NmtState::Operational);
    assert_eq!(n.slave(3).od().get_value::<u16>(APP, 1), Ok(0x77));
    assert!(!nmt_frames(&n.sim)
        .iter()
        .any(|(_, cs, node)| *node == 3 && *cs != 0x01));
    assert_eq!(n.m().stats().probes, 1);
}

#[test]
fn boot_on_demand_reconfigures_without_reset_and_respects_the_start_policy() {
    let mut n = Net::new(
        BITRATE,
        master(MasterConfig::new().slave(cfg(2).start(StartPolicy::Application))),
        &[2],
    );
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(1));
    n.sim.run_until(Instant::from_millis(50));
    assert_eq!(n.m().slave(NodeId::must(2)).phase, BootPhase::Ready);
    assert_eq!(n.slave(2).nmt_state(), NmtState::PreOperational);

    // The application changes a value behind the master's back; a boot on demand rewrites it.
    let dev = n.slave_dev(2);
    let now = n.sim.now();
    n.sim
        .device_mut(dev)
        .machine
        .set(now, APP, 1, 0x1234u16)
        .unwrap();
    n.m_mut().boot_slave(now, NodeId::must(2)).unwrap();
    assert_eq!(n.m().slave(NodeId::must(2)).phase, BootPhase::Identifying);
    n.sim.run_until(Instant::from_millis(100));
    assert_eq!(n.slave(2).od().get_value::<u16>(APP, 1), Ok(0x77));
    let configured = all(&n.events(), |k| match k {
        K::SlaveConfigured { node, start } if node.raw() == 2 => Some(*start),
        _ => None,
    });
    assert_eq!(configured.len(), 2);
    assert!(configured
        .iter()
        .all(|(_, p)| *p == StartPolicy::Application));
    assert_eq!(n.slave(2).nmt_state(), NmtState::PreOperational);
    assert_eq!(n.m().slave(NodeId::must(2)).boot_ups, 1, "never reset");

    // Started, stopped and started again through the master, which tracks it.
    let now = n.sim.now();
    n.m_mut().start_slave(now, NodeId::must(2)).unwrap();
    n.sim.run_for(Duration::from_millis(5));
    assert_eq!(n.slave(2).nmt_state(), NmtState::Operational);
    let now = n.sim.now();
    n.m_mut()
        .nmt(now, NmtCommand::Stop, NmtTarget::Node(NodeId::must(2)))
        .unwrap();
    assert_eq!(
        n.m().slave(NodeId::must(2)).state,
        Some(NmtState::Stopped),
        "as commanded until heard"
    );
    n.sim.run_for(Duration::from_millis(60));
    assert_eq!(n.slave(2).nmt_state(), NmtState::Stopped);
    assert_eq!(n.m().slave(NodeId::must(2)).state, Some(NmtState::Stopped));

    // Refusals say why.
    let now = n.sim.now();
    assert_eq!(
        n.m_mut().boot_slave(now, NodeId::must(9)),
        Err(MasterError::NotAssigned(NodeId::must(9)))
    );
    assert_eq!(
        n.m_mut().start_slave(now, MASTER_ID),
        Err(MasterError::OwnNode(MASTER_ID))
    );
    n.m_mut().set_active(now, false);
    assert_eq!(
        n.m_mut().start_slave(now, NodeId::must(2)),
        Err(MasterError::Standby)
    );
    assert_eq!(
        MasterError::NotAssigned(NodeId::must(9)).to_string(),
        "node 0x09 is not an assigned slave: set bit 0 of 0x1F81 sub 9"
    );
}

fn lose_mandatory(startup: NmtStartup) -> (Net, Instant) {
    let net = MasterConfig::new()
        .startup(startup)
        .slave(cfg(2).mandatory())
        .slave(cfg(3));
    let mut n = Net::new(BITRATE, master(net), &[2, 3]);
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(1));
    n.boot_slave_at(3, Instant::from_millis(1));
    let dev = n.slave_dev(2);
    n.sim
        .at(Instant::from_millis(300), move |sim| sim.power_off(dev));
    n.sim.run_until(Instant::from_millis(600));
    let (lost, status) = find(&n.events(), |k| match k {
        K::SlaveLost { node, status } if node.raw() == 2 => Some(*status),
        _ => None,
    })
    .unwrap();
    assert_eq!(status, ErrorStatus::E);
    (n, lost)
}

#[test]
fn mandatory_slave_lost_with_stop_all_stops_the_network() {
    let (n, lost) = lose_mandatory(NmtStartup::MASTER.with(NmtStartup::STOP_ALL));
    let after: Vec<_> = nmt_frames(&n.sim)
        .into_iter()
        .filter(|(t, _, _)| *t >= lost)
        .map(|(t, cs, node)| {
            assert!(t - lost < Duration::from_millis(1));
            (cs, node)
        })
        .collect();
    assert_eq!(after, [(0x02, 0)]);
    assert_eq!(n.slave(3).nmt_state(), NmtState::Stopped);
}

#[test]
fn mandatory_slave_lost_with_reset_all_resets_and_reboots_the_others() {
    let (n, lost) = lose_mandatory(NmtStartup::MASTER.with(NmtStartup::RESET_ALL));
    let after: Vec<_> = nmt_frames(&n.sim)
        .into_iter()
        .filter(|(t, _, _)| *t >= lost)
        .map(|(_, cs, node)| (cs, node))
        .collect();
    // Reset communication of all, then slave 3 booted again and started.
    assert_eq!(after, [(0x82, 0), (0x01, 3)]);
    assert_eq!(n.slave(3).nmt_state(), NmtState::Operational);
    assert_eq!(n.m().slave(NodeId::must(3)).boot_ups, 2);
}

#[test]
fn guarded_slave_lost_is_error_status_f() {
    // No heartbeat: the master guards slave 2 every 100 ms, life time factor 3.
    let guarded = SlaveConfig::new(NodeId::must(2))
        .identity(expected(2))
        .with_assignment(duocan::master::Assignment::slave().guarded(100, 3));
    let mut n = Net::new(BITRATE, master(MasterConfig::new().slave(guarded)), &[2]);
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(1));
    n.sim.run_until(Instant::from_millis(500));
    let requests = n
        .frames()
        .iter()
        .filter(|(_, f)| f.id() == Id::Standard(0x702) && f.is_remote())
        .count();
    assert!(requests >= 4, "{requests}");
    let dev = n.slave_dev(2);
    n.sim
        .at(Instant::from_millis(520), move |sim| sim.power_off(dev));
    n.sim.run_until(Instant::from_millis(1_200));
    let lost = all(&n.events(), |k| match k {
        K::SlaveLost { node, status } if node.raw() == 2 => Some(*status),
        _ => None,
    });
    assert_eq!(lost.len(), 1);
    assert_eq!(lost[0].1, ErrorStatus::F);
    assert!(n.m().slave(NodeId::must(2)).missing);
}
