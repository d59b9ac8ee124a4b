//! Slaves that boot again while the network runs (power cycle, reset by the master, heartbeat
//! lost and back) are identified, configured and started again by themselves; keep-alive
//! slaves are not reset by the master's boot.

use crate::net::*;
use duocan::machine::StationEvent;
use duocan::master::{BootPhase, ErrorStatus, MasterConfig, MasterEventKind as K, SlaveConfig};
use duocan::node::NodeEventKind;
use duocan::od::{comm, ObjectDictionary};
use duocan::{Duration, Id, Instant, NmtState, NodeId};

const BITRATE: u32 = 500_000;

fn slave_cfg(id: u8) -> SlaveConfig {
    SlaveConfig::new(NodeId::must(id))
        .identity(expected(id))
        .heartbeat(50, 150)
        .write_u16(APP, 1, 0x100 + id as u16)
        .write_u16(APP, 2, 0x200 + id as u16)
}

fn running(ids: &[u8]) -> Net {
    let mut net = MasterConfig::new();
    for &id in ids {
        net = net.slave(slave_cfg(id));
    }
    let mut n = Net::new(BITRATE, master(net), ids);
    n.boot_master();
    for &id in ids {
        n.boot_slave_at(id, Instant::from_millis(1));
    }
    n.sim.run_until(Instant::from_millis(100));
    for &id in ids {
        assert_eq!(n.slave(id).nmt_state(), NmtState::Operational);
    }
    n
}

fn configured(n: &Net, id: u8) {
    let s = n.slave(id);
    assert_eq!(s.nmt_state(), NmtState::Operational, "slave {id}");
    assert_eq!(s.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0), Ok(50));
    assert_eq!(s.od().get_value::<u16>(APP, 1), Ok(0x100 + id as u16));
    assert_eq!(s.od().get_value::<u16>(APP, 2), Ok(0x200 + id as u16));
}

/// (boot-up seen, configured, started) of `id` after `from`.
fn reboot_times(n: &Net, id: u8, from: Instant) -> (Instant, Instant, Instant) {
    let node = NodeId::must(id);
    let ev: Vec<_> = n.events().into_iter().filter(|e| e.at >= from).collect();
    let t = |f: &dyn Fn(&K) -> bool| ev.iter().find(|e| f(&e.kind)).map(|e| e.at).unwrap();
    (
        t(&|k| matches!(k, K::SlaveBootUp { node: x } if *x == node)),
        t(&|k| matches!(k, K::SlaveConfigured { node: x, .. } if *x == node)),
        t(&|k| matches!(k, K::SlaveStarted { node: x, .. } if *x == node)),
    )
}

#[test]
fn power_cycled_slave_is_reconfigured_and_restarted() {
    let mut n = running(&[2, 3, 4]);
    let t = Instant::from_millis(500);
    n.power_cycle_at(3, t);
    n.sim.run_until(Instant::from_millis(499));
    // Its dictionary holds what the master wrote; the fresh one will not.
    assert_eq!(n.slave(3).od().get_value::<u16>(APP, 1), Ok(0x103));
    n.sim.run_until(Instant::from_secs(1));
    let (boot_up, cfg, started) = reboot_times(&n, 3, t);
    println!(
        "slave 3 power-cycled at {:.3} ms: boot-up seen {:.3} ms, configured {:.3} ms, started {:.3} ms",
        ms(t),
        ms(boot_up),
        ms(cfg),
        ms(started)
    );
    assert!(started - t < Duration::from_millis(6));
    configured(&n, 3);
    let v = n.m().slave(NodeId::must(3));
    assert_eq!(
        (v.boot_ups, v.phase, v.missing),
        (2, BootPhase::Started, false)
    );
    // Quick enough that error control never noticed.
    assert!(!n
        .events()
        .iter()
        .any(|e| matches!(e.kind, K::SlaveLost { .. })));
    for id in [2, 4] {
        assert_eq!(n.m().slave(NodeId::must(id)).boot_ups, 1);
    }
}

#[test]
fn slave_reset_by_the_master_is_reconfigured_and_restarted() {
    let mut n = running(&[2, 3, 4]);
    n.sim.run_until(Instant::from_millis(300));
    let t = n.sim.now();
    n.m_mut().reset_slave(t, NodeId::must(4)).unwrap();
    assert_eq!(n.m().slave(NodeId::must(4)).phase, BootPhase::WaitBootUp);
    assert_eq!(
        n.m().slave(NodeId::must(4)).state,
        None,
        "reset: unknown until heard"
    );
    n.sim.run_until(Instant::from_millis(600));
    assert!(nmt_frames(&n.sim)
        .iter()
        .any(|(at, cs, node)| *at > t && (*cs, *node) == (0x81, 4)));
    let (_, _, started) = reboot_times(&n, 4, t);
    println!(
        "slave 4 reset by the master at {:.3} ms: started again at {:.3} ms",
        ms(t),
        ms(started)
    );
    assert!(started - t < Duration::from_millis(6));
    configured(&n, 4);
    // Reset node reset its application entries too: the master wrote them again.
    assert_eq!(n.m().slave(NodeId::must(4)).boot_ups, 2);
}

#[test]
fn slave_lost_then_back_is_reported_then_rebooted() {
    let mut n = running(&[2, 3, 4]);
    let off = Instant::from_millis(520);
    let dev = n.slave_dev(2);
    n.sim.at(off, move |sim| sim.power_off(dev));
    n.sim.run_until(Instant::from_millis(900));
    // Lost exactly one consumer time after its last heartbeat.
    let last_hb = n
        .frames()
        .iter()
        .rev()
        .find(|(t, f)| *t < off && f.id() == Id::Standard(0x702))
        .unwrap()
        .0;
    let lost = all(&n.events(), |k| match k {
        K::SlaveLost { node, status } if node.raw() == 2 => Some(*status),
        _ => None,
    });
    assert_eq!(
        lost,
        [(last_hb + Duration::from_millis(150), ErrorStatus::E)]
    );
    let v = n.m().slave(NodeId::must(2));
    assert!(v.missing);
    assert_eq!(v.phase, BootPhase::WaitBootUp);
    assert_eq!(
        n.m()
            .node()
            .od()
            .get_value::<u8>(duocan::master::objects::REQUEST_NMT, 2),
        Ok(1),
        "0x1F82 reads 'missing'"
    );
    let back = Instant::from_millis(1_200);
    n.power_cycle_at(2, back);
    n.sim.run_until(Instant::from_millis(1_500));
    let (_, _, started) = reboot_times(&n, 2, back);
    assert!(started - back < Duration::from_millis(6));
    configured(&n, 2);
    assert!(!n.m().slave(NodeId::must(2)).missing);
}

#[test]
fn keep_alive_slave_is_adopted_not_reset_and_rebooted_when_it_boots_again() {
    let net = MasterConfig::new()
        .slave(slave_cfg(2))
        .slave(slave_cfg(5).keep_alive());
    let mut n = Net::new(BITRATE, master(net), &[2, 5]);
    // Slave 5 runs already (as the previous master left it): operational, beating every 50 ms.
    n.boot_slave_at(5, Instant::ZERO);
    let dev = n.slave_dev(5);
    n.sim.at(Instant::from_millis(1), move |sim| {
        let now = sim.now();
        let s = &mut sim.device_mut(dev).machine;
        s.set(now, comm::HEARTBEAT_PRODUCER, 0, 50u16).unwrap();
        s.set(now, APP, 1, 0x105u16).unwrap();
        s.set_nmt_state(now, NmtState::Operational);
    });
    n.sim.run_until(Instant::from_millis(10));
    n.boot_master();
    n.boot_slave_at(2, Instant::from_millis(20));
    n.sim.run_until(Instant::from_millis(1_000));

    let adopted = all(&n.events(), |k| match k {
        K::SlaveAdopted { node, state } => Some((node.raw(), *state)),
        _ => None,
    });
    assert_eq!(adopted.len(), 1);
    assert_eq!(adopted[0].1, (5, NmtState::Operational));
    // Decided at its first heartbeat after the master's boot, within the consumer time.
    assert!(adopted[0].0 <= Instant::from_millis(10 + 150));
    // The master reset slave 2 alone and never addressed slave 5 (no broadcast either).
    let nmt = nmt_frames(&n.sim);
    assert!(nmt.iter().all(|(_, _, node)| *node == 2), "{nmt:?}");
    assert!(nmt.iter().any(|(_, cs, _)| *cs == 0x82));
    assert!(!n
        .frames()
        .iter()
        .any(|(_, f)| f.id() == Id::Standard(0x605)));
    let slave5_states = n
        .sim
        .events(dev)
        .iter()
        .filter(|(t, e)| {
            *t > Instant::from_millis(1)
                && matches!(e, StationEvent::Machine(e) if matches!(e.kind, NodeEventKind::StateChanged { .. }))
        })
        .count();
    assert_eq!(slave5_states, 0, "slave 5 never changed state");
    assert_eq!(n.m().slave(NodeId::must(5)).phase, BootPhase::Adopted);
    configured(&n, 2);

    // When it boots again anyway (power cycle), it goes through the boot process.
    let t = Instant::from_millis(1_500);
    n.power_cycle_at(5, t);
    n.sim.run_until(Instant::from_millis(2_000));
    let (_, _, started) = reboot_times(&n, 5, t);
    assert!(started - t < Duration::from_millis(6));
    configured(&n, 5);
}

/// A transfer to a slave is gone when the slave boots (here one read while it was missing): the application's is
/// ended at the boot-up (`0800 0022`, the device state), not left to time out, and the slave's
/// boot process does not wait for it (one channel per server): it is configured and started as
/// fast as after any power cycle. It used to wait out the application's SDO timeout.
#[test]
fn a_transfer_to_a_slave_that_boots_ends_at_its_boot_up_and_does_not_hold_up_its_boot() {
    let mut n = running(&[2, 3]);
    let off = Instant::from_millis(520);
    let dev = n.slave_dev(2);
    n.sim.at(off, move |sim| sim.power_off(dev));
    // Lost (a consumer time after its last heartbeat): an operator's read of it meanwhile.
    n.sim.run_until(Instant::from_millis(700));
    assert!(n.m().slave(NodeId::must(2)).missing);
    let at = n.sim.now();
    let opts = duocan::sdo::SdoOptions::default().with_timeout(Duration::from_millis(500));
    let req = n
        .m_mut()
        .sdo_mut()
        .upload(at, NodeId::must(2), APP, 1, opts)
        .unwrap();
    let back = Instant::from_millis(750);
    n.power_cycle_at(2, back);
    n.sim.run_until(Instant::from_millis(1_100));
    let (boot_up, _, started) = reboot_times(&n, 2, back);
    let ended = all(&n.events(), |k| match k {
        K::Sdo(e) if e.request == req => Some(e.result.clone().map(|_| ()).map_err(|e| e.kind)),
        _ => None,
    });
    assert_eq!(
        ended,
        [(
            boot_up,
            Err(duocan::sdo::SdoErrorKind::Client(
                duocan::AbortCode::DEVICE_STATE
            ))
        )]
    );
    assert!(started - back < Duration::from_millis(6), "{}", ms(started));
    configured(&n, 2);
}
