//! The largest network CiA 302-2 allows, booted in parallel: 126 slaves (every node-ID the
//! master does not hold) on one 1 Mbit/s simulated bus, each checked for its identity (0x1000,
//! 0x1018 sub 1–4), given its heartbeat producer time and its TPDO1 (communication and
//! mapping), then all started by one broadcast. Every slave's boot process runs at once (one
//! SDO session each), so the bus, not the round trips, sets the pace: the simulated boot time
//! is measured against the bus time of the frames that went on the bus meanwhile, its lower
//! bound.

use crate::net::*;
use duocan::cia302::pdo_config::PdoConfig;
use duocan::master::{MasterConfig, MasterEventKind as K, NmtStartup, SlaveConfig};
use duocan::od::ObjectDictionary;
use duocan::pdo::MapEntry;
use duocan::{CobId, Instant, NmtState, NodeId};

const BITRATE: u32 = 1_000_000;
const IDS: std::ops::RangeInclusive<u8> = 2..=127;

fn tpdo1(id: u8) -> PdoConfig {
    PdoConfig::new(CobId(0x180 + id as u32), 254)
        .event_timer(500)
        .mapping(&[MapEntry::new(APP, 1, 16), MapEntry::new(APP, 2, 16)])
        .unwrap()
}

/// The master's configuration: every slave mandatory, identity checked, heartbeat every 500 ms
/// (the master consumes it with 1.5 s), TPDO1 configured; `sessions` boot processes at once.
fn network(sessions: usize) -> MasterConfig {
    let mut net = MasterConfig::new()
        .startup(NmtStartup::MASTER.with(NmtStartup::START_ALL))
        .boot_time_ms(10_000)
        .with_sdo_sessions(sessions);
    for id in IDS {
        net = net.slave(
            SlaveConfig::new(NodeId::must(id))
                .mandatory()
                .identity(expected(id))
                .heartbeat(500, 1_500)
                .tpdo(1, tpdo1(id)),
        );
    }
    net
}

/// Boots the network with `sessions` SDO sessions: (network started at, bus time of the frames
/// until then, frames until then, the network).
fn boot(sessions: usize) -> (Instant, duocan::Duration, u64, Net) {
    let mut n = Net::new(BITRATE, master(network(sessions)), &IDS.collect::<Vec<_>>());
    n.sim.set_event_capacity(1 << 16);
    // Everything powers on together; the master's reset-communication broadcast reboots the
    // slaves, whose boot-ups start their boot processes.
    for id in IDS {
        n.boot_slave_at(id, Instant::ZERO);
    }
    n.boot_master();
    let mut started = None;
    while started.is_none() && n.sim.now() < Instant::from_secs(20) {
        n.sim.run_for(duocan::Duration::from_millis(1));
        started = find(&n.events(), |k| {
            matches!(k, K::NetworkStarted { .. }).then_some(())
        });
    }
    let (t, ()) = started.expect("the network started");
    // The bus time of every frame that ended by then (the run may have gone up to 1 ms past).
    let frames = n.frames();
    let until: Vec<_> = frames.iter().filter(|(end, _)| *end <= t).collect();
    let busy = until
        .iter()
        .map(|(_, f)| duocan::sim::timing::frame_duration(f, BITRATE))
        .fold(duocan::Duration::ZERO, |a, b| a + b);
    (t, busy, until.len() as u64, n)
}

#[test]
fn one_hundred_and_twenty_six_slaves_boot_in_parallel_at_the_bus_limit() {
    let (t, busy, frames, mut n) = boot(IDS.count());
    let ev = n.events();
    assert!(
        !ev.iter().any(|e| matches!(
            e.kind,
            K::ConfigFailed { .. } | K::IdentityMismatch { .. } | K::SlaveLost { .. }
        )),
        "{:#?}",
        ev.iter()
            .filter(|e| !matches!(e.kind, K::Node(_)))
            .collect::<Vec<_>>()
    );
    let configured = all(&ev, |k| {
        matches!(k, K::SlaveConfigured { .. }).then_some(())
    });
    assert_eq!(configured.len(), IDS.count());
    n.sim.run_for(duocan::Duration::from_millis(10));
    for id in IDS {
        let s = n.slave(id);
        assert_eq!(s.nmt_state(), NmtState::Operational, "slave {id}");
        assert_eq!(
            s.od()
                .get_value::<u16>(duocan::od::comm::HEARTBEAT_PRODUCER, 0),
            Ok(500)
        );
        assert_eq!(
            s.od().get_value::<u32>(0x1A00, 2),
            Ok(0x2000_0210),
            "slave {id}"
        );
    }
    let ratio = t.as_micros() as f64 / busy.as_micros() as f64;
    println!(
        "126 slaves at 1 Mbit/s, booted in parallel: network started at {:.1} ms; the {frames} \
         frames on the bus by then take {:.1} ms of bus time: {ratio:.3}× the bus's bound",
        ms(t),
        busy.as_micros() as f64 / 1000.0
    );
    // The bus is never idle for long while slaves wait: within 5 % of its bound.
    assert!(ratio <= 1.05, "{ratio:.3}× the bus time");
    // And it carries what the boot needs, little more: per slave two boot-ups (power-on, then
    // after the reset-communication broadcast), 14 SDO accesses of 2 frames (identity 5, TPDO1
    // 8, heartbeat 1) and a heartbeat or so once configured; for a third of them a request
    // the reset-communication broadcast ended (its abort, and the access again).
    let per_slave = frames as f64 / IDS.count() as f64;
    assert!(
        (30.0..=37.0).contains(&per_slave),
        "{per_slave:.1} frames per slave"
    );
}
