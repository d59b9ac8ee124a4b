//! What the master does when slaves are not what it expects, refuse their configuration, or are
//! missing: events naming the slave and the reason (CiA 302-2 error status letters), the other
//! slaves started, the network start held back by a missing mandatory slave.

use crate::net::*;
use duocan::master::{
    BootError, BootPhase, ErrorStatus, MasterConfig, MasterEventKind as K, NmtStartup, SlaveConfig,
};
use duocan::od::{comm, ObjectDictionary};
use duocan::sdo::SdoErrorKind;
use duocan::{AbortCode, Duration, Instant, NmtState, NodeId, NodeSet};

const BITRATE: u32 = 500_000;

fn slave_cfg(id: u8) -> SlaveConfig {
    SlaveConfig::new(NodeId::must(id))
        .identity(expected(id))
        .heartbeat(50, 150)
        .write_u16(APP, 1, 7)
}

#[test]
fn identity_mismatch_on_an_optional_slave_the_others_start() {
    let net = MasterConfig::new()
        .startup(NmtStartup::MASTER.with(NmtStartup::START_ALL))
        .slave(slave_cfg(2).mandatory())
        .slave(slave_cfg(3).mandatory())
        .slave(slave_cfg(4))
        .slave(slave_cfg(5))
        .slave(slave_cfg(6).mandatory());
    let mut n = Net::new(BITRATE, master(net), &[2, 3, 4, 5, 6]);
    // Slave 4 is another product; slave 5 another device type.
    let wrong_product = comm::Identity {
        product: 0x999,
        ..identity(4)
    };
    let wrong_type = comm::Identity {
        device_type: 0x0002_0191,
        ..identity(5)
    };
    n.sim
        .replace(
            n.slave_dev(4),
            duocan::Station::single(slave_node(4, wrong_product)),
        )
        .unwrap();
    n.sim
        .replace(
            n.slave_dev(5),
            duocan::Station::single(slave_node(5, wrong_type)),
        )
        .unwrap();
    n.boot_master();
    for id in 2..=6 {
        n.boot_slave_at(id, Instant::from_millis(10 + id as u64));
    }
    n.sim.run_until(Instant::from_secs(1));
    let ev = n.events();

    let mismatches = all(&ev, |k| match *k {
        K::IdentityMismatch { node, mismatch: m } => {
            Some((node.raw(), m.status, m.index, m.sub, m.expected, m.actual))
        }
        _ => None,
    });
    assert_eq!(
        mismatches.iter().map(|(_, m)| *m).collect::<Vec<_>>(),
        [
            (4, ErrorStatus::M, 0x1018, 2, 0x104, 0x999),
            (5, ErrorStatus::C, 0x1000, 0, DEVICE_TYPE, 0x0002_0191)
        ]
    );
    for (id, status) in [(4, ErrorStatus::M), (5, ErrorStatus::C)] {
        assert_eq!(n.slave(id).nmt_state(), NmtState::PreOperational);
        // Neither configured: its heartbeat producer is still off.
        assert_eq!(
            n.slave(id).od().get_u32(comm::HEARTBEAT_PRODUCER, 0),
            Some(0)
        );
        let v = n.m().slave(NodeId::must(id));
        assert_eq!(v.phase, BootPhase::Failed(status));
        assert_eq!(v.last_error, Some(status));
    }
    for id in [2, 3, 6] {
        assert_eq!(n.slave(id).nmt_state(), NmtState::Operational, "slave {id}");
    }
    // A broadcast would have started the mismatched slaves: one start per good slave instead.
    let (_, broadcast) = find(&ev, |k| match k {
        K::NetworkStarted { broadcast, .. } => Some(*broadcast),
        _ => None,
    })
    .unwrap();
    assert!(!broadcast);
    let starts: Vec<u8> = nmt_frames(&n.sim)
        .iter()
        .filter(|(_, cs, _)| *cs == 0x01)
        .map(|(_, _, node)| *node)
        .collect();
    assert_eq!(starts, [2, 3, 6]);
    let text = format!("{}", ErrorStatus::M);
    println!("slave 4: {text}; slave 5: {}", ErrorStatus::C);
}

#[test]
fn a_refused_configuration_write_names_the_slave_object_and_abort_code() {
    let net = MasterConfig::new()
        .slave(slave_cfg(2))
        // 0x2000 sub 9 does not exist on the slave.
        .slave(slave_cfg(3).write_u16(APP, 9, 1));
    let mut n = Net::new(BITRATE, master(net), &[2, 3]);
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(1));
    n.boot_slave_at(3, Instant::from_millis(1));
    n.sim.run_until(Instant::from_millis(500));
    let ev = n.events();
    let (_, (status, reason)) = find(&ev, |k| match k {
        K::ConfigFailed {
            node,
            status,
            reason,
        } if node.raw() == 3 => Some((*status, *reason)),
        _ => None,
    })
    .unwrap();
    assert_eq!(status, ErrorStatus::J);
    let BootError::Sdo(e) = reason else {
        panic!("{reason:?}")
    };
    assert_eq!((e.node.raw(), e.index, e.sub), (3, APP, 9));
    assert_eq!(e.kind, SdoErrorKind::Server(AbortCode::NO_SUB_INDEX));
    assert_eq!(
        reason.to_string(),
        "SDO download to node 3 (0x03), object 0x2000 sub 9: the server aborted with 0x06090011 (sub-index does not exist)"
    );
    // The writes before it happened; the slave is not started.
    assert_eq!(n.slave(3).od().get_u32(APP, 1), Some(7));
    assert_eq!(n.slave(3).nmt_state(), NmtState::PreOperational);
    assert_eq!(n.slave(2).nmt_state(), NmtState::Operational);
}

fn mandatory_net() -> MasterConfig {
    MasterConfig::new()
        .boot_time_ms(1_000)
        .sdo_timeout(Duration::from_millis(500))
        .probe_interval(Duration::from_millis(1_000))
        .slave(slave_cfg(2).mandatory())
        .slave(slave_cfg(3).mandatory())
        .slave(slave_cfg(4))
}

#[test]
fn mandatory_slave_missing_holds_the_network_until_it_comes() {
    let mut n = Net::new(BITRATE, master(mandatory_net()), &[2, 3, 4]);
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(10));
    n.boot_slave_at(4, Instant::from_millis(10));
    n.sim.run_until(Instant::from_millis(2_400));
    let ev = n.events();
    assert!(!n.m().network_started());
    assert!(find(&ev, |k| matches!(k, K::NetworkStarted { .. }).then_some(())).is_none());
    // Exactly at the boot time: which mandatory slave is missing.
    let missing = all(&ev, |k| match k {
        K::MandatoryMissing { nodes } => Some(*nodes),
        _ => None,
    });
    let mut only3 = NodeSet::EMPTY;
    only3.insert(NodeId::must(3));
    assert_eq!(missing, [(Instant::from_millis(1_000), only3)]);
    assert_eq!(only3.to_string(), "{3}");
    // Probed a second after the boot, and a second after each unanswered probe (500 ms SDO
    // timeout): its silence is reported once, with why.
    let silent = all(&ev, |k| match k {
        K::ConfigFailed {
            node,
            status: ErrorStatus::B,
            reason: BootError::Sdo(e),
        } if node.raw() == 3 => Some(e.is_timeout()),
        _ => None,
    });
    assert_eq!(silent, [(Instant::from_millis(1_500), true)]);
    assert_eq!(n.m().stats().probes, 1);
    let v = n.m().slave(NodeId::must(3));
    assert!(v.missing);
    assert_eq!(v.phase, BootPhase::WaitBootUp);
    assert_eq!(v.last_error, Some(ErrorStatus::B));
    n.sim.run_until(Instant::from_millis(2_999));
    assert_eq!(n.m().stats().probes, 2);
    assert_eq!(
        n.events().len(),
        ev.len(),
        "the second silence is not reported again"
    );
    // The others are configured but wait for the network start, and so does the master.
    for id in [2, 4] {
        assert_eq!(n.slave(id).nmt_state(), NmtState::PreOperational);
        assert_eq!(n.m().slave(NodeId::must(id)).phase, BootPhase::WaitStart);
    }
    assert_eq!(n.m().node().nmt_state(), NmtState::PreOperational);

    // It comes: booted, the network starts.
    n.boot_slave_at(3, Instant::from_millis(3_000));
    n.sim.run_until(Instant::from_millis(3_100));
    let ev = n.events();
    let (t, _) = find(&ev, |k| matches!(k, K::NetworkStarted { .. }).then_some(())).unwrap();
    println!(
        "mandatory slave 3 missing: reported at {:.3} ms (boot time 1000 ms); it booted at 3000 ms, network started at {:.3} ms",
        ms(missing[0].0),
        ms(t)
    );
    assert!(t > Instant::from_millis(3_000) && t < Instant::from_millis(3_010));
    for id in 2..=4 {
        assert_eq!(n.slave(id).nmt_state(), NmtState::Operational, "slave {id}");
    }
    assert_eq!(n.m().node().nmt_state(), NmtState::Operational);
    assert!(!n.m().slave(NodeId::must(3)).missing);
}

#[test]
fn mandatory_slaves_present_the_network_starts_within_the_boot_time() {
    let mut n = Net::new(BITRATE, master(mandatory_net()), &[2, 3, 4]);
    n.boot_master();
    for id in 2..=4 {
        n.boot_slave_at(id, Instant::from_millis(10));
    }
    n.sim.run_until(Instant::from_millis(2_000));
    let ev = n.events();
    let (t, _) = find(&ev, |k| matches!(k, K::NetworkStarted { .. }).then_some(())).unwrap();
    assert!(t < Instant::from_millis(30), "{t:?}");
    assert!(find(&ev, |k| matches!(k, K::MandatoryMissing { .. })
        .then_some(()))
    .is_none());
    assert!(find(&ev, |k| matches!(k, K::ConfigFailed { .. }).then_some(())).is_none());
    for id in 2..=4 {
        assert_eq!(n.slave(id).nmt_state(), NmtState::Operational);
    }
}
