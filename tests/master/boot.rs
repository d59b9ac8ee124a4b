//! A 20-slave network booted by the CiA 302-2 master on the simulated bus: identities checked,
//! heartbeat and application entries configured, every slave started; the time it takes,
//! measured in simulated time against the slowest slave's boot and the SDO round trips of its
//! boot process.

use crate::net::*;
use duocan::cia302::pdo_config::PdoConfig;
use duocan::master::{
    BootPhase, MasterConfig, MasterEventKind as K, NmtStartup, SlaveConfig, StartPolicy,
};
use duocan::od::{comm, ObjectDictionary};
use duocan::pdo::MapEntry;
use duocan::{CobId, Duration, Id, Instant, NmtState, NodeId};

const BITRATE: u32 = 500_000;
const IDS: std::ops::RangeInclusive<u8> = 2..=21;
/// SDO accesses of each slave's boot process: 0x1000, 0x1018 sub 1–4, three application
/// entries, TPDO1 (read the COB-ID, disable, type, event timer, mapping count 0, two entries,
/// count, enable), 0x1017.
const ACCESSES: u32 = 18;
const TPDO_PERIOD_MS: u16 = 100;

fn tpdo1(id: u8) -> PdoConfig {
    PdoConfig::new(CobId(0x180 + id as u32), 254)
        .event_timer(TPDO_PERIOD_MS)
        .mapping(&[MapEntry::new(APP, 1, 16), MapEntry::new(APP, 2, 16)])
        .unwrap()
}

fn network(mandatory: bool, startup: NmtStartup) -> MasterConfig {
    let mut net = MasterConfig::new().startup(startup).boot_time_ms(2_000);
    for id in IDS {
        let mut s = SlaveConfig::new(NodeId::must(id))
            .identity(expected(id))
            .heartbeat(50, 150)
            .write_u16(APP, 1, id as u16 * 10)
            .write_u16(APP, 2, id as u16 * 100)
            .write_u16(APP, 3, 0xBEEF)
            .tpdo(1, tpdo1(id));
        if mandatory {
            s = s.mandatory();
        }
        net = net.slave(s);
    }
    net
}

/// Slave boot instants: spread over 5–245 ms in a scrambled order.
fn boot_time(id: u8) -> Instant {
    Instant::from_micros(5_000 + ((id as u64 * 7919) % 20) * 12_000 + id as u64 * 17)
}

/// Checks every slave is configured as asked and operational, the master monitors it, and its
/// TPDO1 carries its two application values every 100 ms.
fn assert_configured_and_running(n: &Net) {
    let frames = n.frames();
    let quiet = frames
        .iter()
        .rfind(|(_, f)| matches!(f.id(), Id::Standard(0x581..=0x67F)))
        .unwrap()
        .0;
    for id in IDS {
        let od = n.slave(id).od();
        assert_eq!(od.get_value::<u32>(0x1800, 1), Ok(0x180 + id as u32));
        assert_eq!(od.get_value::<u8>(0x1800, 2), Ok(254));
        assert_eq!(od.get_value::<u16>(0x1800, 5), Ok(TPDO_PERIOD_MS));
        assert_eq!(od.get_value::<u8>(0x1A00, 0), Ok(2));
        assert_eq!(od.get_value::<u32>(0x1A00, 1), Ok(0x2000_0110));
        assert_eq!(od.get_value::<u32>(0x1A00, 2), Ok(0x2000_0210));
        let tpdos: Vec<_> = frames
            .iter()
            .filter(|(_, f)| f.id() == Id::Standard(0x180 + id as u16))
            .collect();
        assert!(tpdos.len() >= 5, "slave {id}: {} TPDOs", tpdos.len());
        let a = (id as u16 * 10).to_le_bytes();
        let b = (id as u16 * 100).to_le_bytes();
        for (_, f) in &tpdos {
            assert_eq!(f.data(), [a[0], a[1], b[0], b[1]], "slave {id}");
        }
        // Exact period once the boot traffic is over (during it, a heartbeat starved by another
        // slave's SDO exchange holds the TPDO behind it in the slave's controller queue).
        let steady: Vec<_> = tpdos
            .iter()
            .filter(|(t, _)| *t > quiet + Duration::from_millis(20))
            .collect();
        assert!(steady.len() >= 5);
        for w in steady.windows(2) {
            let gap = w[1].0 - w[0].0;
            assert_eq!(
                gap,
                Duration::from_millis(TPDO_PERIOD_MS as u64),
                "slave {id}"
            );
        }
    }
    for id in IDS {
        let s = n.slave(id);
        assert_eq!(s.nmt_state(), NmtState::Operational, "slave {id}");
        assert_eq!(s.od().get_value::<u16>(comm::HEARTBEAT_PRODUCER, 0), Ok(50));
        assert_eq!(s.od().get_value::<u16>(APP, 1), Ok(id as u16 * 10));
        assert_eq!(s.od().get_value::<u16>(APP, 2), Ok(id as u16 * 100));
        assert_eq!(s.od().get_value::<u16>(APP, 3), Ok(0xBEEF));
        let v = n.m().slave(NodeId::must(id));
        assert_eq!(v.state, Some(NmtState::Operational));
        assert!(!v.missing);
        assert_eq!(v.last_error, None);
        assert_eq!(
            n.m()
                .node()
                .od()
                .get_value::<u32>(comm::HEARTBEAT_CONSUMER, id),
            Ok(((id as u32) << 16) | 150),
            "the master consumes slave {id}'s heartbeat"
        );
    }
}

fn per_slave_bound() -> Duration {
    // Boot-up frame, the boot process's round trips, the start; one more round trip for
    // heartbeats of the other slaves that win arbitration on the way.
    sdo_frame(BITRATE).saturating_mul(2 * (ACCESSES as u64 + 2))
}

#[test]
fn twenty_mandatory_slaves_started_by_one_broadcast_after_the_slowest() {
    let mut n = Net::new(
        BITRATE,
        master(network(
            true,
            NmtStartup::MASTER.with(NmtStartup::START_ALL),
        )),
        &IDS.collect::<Vec<_>>(),
    );
    n.boot_master();
    for id in IDS {
        n.boot_slave_at(id, boot_time(id));
    }
    n.sim.run_until(Instant::from_secs(2));
    let ev = n.events();

    let slowest = IDS.map(boot_time).max().unwrap();
    let (t_net, broadcast) = find(&ev, |k| match k {
        K::NetworkStarted { broadcast, .. } => Some(*broadcast),
        _ => None,
    })
    .expect("network started");
    assert!(broadcast, "all configured: one start-all broadcast");
    let configured = all(&ev, |k| match k {
        K::SlaveConfigured { node, start } => Some((*node, *start)),
        _ => None,
    });
    assert_eq!(configured.len(), 20);
    assert!(configured.iter().all(|(_, (_, p))| *p == StartPolicy::Auto));
    let started = all(&ev, |k| match k {
        K::SlaveStarted { node, broadcast } => Some((*node, *broadcast)),
        _ => None,
    });
    assert_eq!(started.len(), 20);
    assert!(started.iter().all(|(t, (_, b))| *b && *t == t_net));
    // One reset-communication broadcast at boot and one start broadcast: nothing per node.
    assert_eq!(
        nmt_frames(&n.sim)
            .iter()
            .map(|(_, cs, node)| (*cs, *node))
            .collect::<Vec<_>>(),
        [(0x82, 0), (0x01, 0)]
    );
    assert!(
        !ev.iter().any(|e| matches!(
            e.kind,
            K::ConfigFailed { .. } | K::IdentityMismatch { .. } | K::SlaveLost { .. }
        )),
        "{ev:#?}"
    );
    assert_configured_and_running(&n);

    let bound = slowest + per_slave_bound();
    println!(
        "20 mandatory slaves at {} kbit/s: slowest slave booted at {:.3} ms, network started (one broadcast) at {:.3} ms: {:.3} ms after it ({} SDO round trips of its boot process; bound {:.3} ms)",
        BITRATE / 1000,
        ms(slowest),
        ms(t_net),
        ms(t_net) - ms(slowest),
        ACCESSES,
        ms(bound) - ms(slowest),
    );
    assert!(t_net <= bound, "{t_net:?} > {bound:?}");
    assert!(n.m().network_started());
    assert_eq!(n.m().node().nmt_state(), NmtState::Operational);
}

#[test]
fn twenty_optional_slaves_each_started_right_after_its_configuration() {
    let mut n = Net::new(
        BITRATE,
        master(network(false, NmtStartup::MASTER)),
        &IDS.collect::<Vec<_>>(),
    );
    n.boot_master();
    for id in IDS {
        n.boot_slave_at(id, boot_time(id));
    }
    n.sim.run_until(Instant::from_secs(2));
    let ev = n.events();
    // No mandatory slave: the network (and the master itself) start at once.
    let (t_net, broadcast) = find(&ev, |k| match k {
        K::NetworkStarted { broadcast, .. } => Some(*broadcast),
        _ => None,
    })
    .unwrap();
    assert_eq!((t_net, broadcast), (Instant::ZERO, false));
    let mut worst = Duration::ZERO;
    for id in IDS {
        let node = NodeId::must(id);
        let (t, b) = find(&ev, |k| match k {
            K::SlaveStarted { node: x, broadcast } if *x == node => Some(*broadcast),
            _ => None,
        })
        .unwrap();
        assert!(!b);
        let took = t - boot_time(id);
        assert!(took <= per_slave_bound(), "slave {id}: {took:?}");
        worst = worst.max(took);
    }
    let last = all(&ev, |k| matches!(k, K::SlaveStarted { .. }).then_some(()))
        .last()
        .unwrap()
        .0;
    let slowest = IDS.map(boot_time).max().unwrap();
    println!(
        "20 optional slaves at {} kbit/s: each started at most {:.3} ms after its boot; all started at {:.3} ms, slowest booted at {:.3} ms",
        BITRATE / 1000,
        worst.as_micros() as f64 / 1000.0,
        ms(last),
        ms(slowest)
    );
    assert!(last <= slowest + per_slave_bound());
    assert_configured_and_running(&n);
    // Reset at boot, then one start per slave.
    let nmt = nmt_frames(&n.sim);
    assert_eq!(nmt.len(), 21);
    assert_eq!((nmt[0].1, nmt[0].2), (0x82, 0));
}

/// Slaves that were up before the master: its reset at boot brings all 20 back at once. The
/// SDO exchange of one slave's boot (its answers 0x58x outrank the boot-ups 0x70x, and the next
/// request follows at once) holds the bus, so the other boot-ups wait for it: with zero-latency
/// slaves the boots run one after the other.
#[test]
fn twenty_slaves_reset_at_once_by_the_master() {
    let mut n = Net::new(
        BITRATE,
        master(network(
            true,
            NmtStartup::MASTER.with(NmtStartup::START_ALL),
        )),
        &IDS.collect::<Vec<_>>(),
    );
    for id in IDS {
        n.boot_slave_at(id, Instant::ZERO);
    }
    n.sim.run_until(Instant::from_millis(5));
    n.boot_master();
    let t0 = n.sim.now();
    n.sim.run_until(Instant::from_secs(1));
    let ev = n.events();
    let (t_net, _) = find(&ev, |k| matches!(k, K::NetworkStarted { .. }).then_some(())).unwrap();
    assert_configured_and_running(&n);
    assert!(!ev.iter().any(|e| matches!(e.kind, K::ConfigFailed { .. })));
    let bound = per_slave_bound().saturating_mul(20);
    println!(
        "20 slaves reset at once by the master at {} kbit/s: network started {:.3} ms after the master's boot (bound 20 × one slave's boot = {:.3} ms)",
        BITRATE / 1000,
        ms(t_net) - ms(t0),
        bound.as_micros() as f64 / 1000.0
    );
    assert!(t_net - t0 <= bound);
}

/// A standby master saw 20 slaves boot and stay pre-operational; when it becomes active it
/// boots all 20 at once: 8 on the client's sessions, the others queued for a free one.
#[test]
fn twenty_slaves_found_pre_operational_at_takeover_share_eight_sdo_sessions() {
    let mut n = Net::new(
        BITRATE,
        master(network(true, NmtStartup::MASTER.with(NmtStartup::START_ALL)).standby()),
        &IDS.collect::<Vec<_>>(),
    );
    n.boot_master();
    for id in IDS {
        n.boot_slave_at(id, Instant::from_millis(1));
    }
    n.sim.run_until(Instant::from_millis(20));
    assert!(n
        .events()
        .iter()
        .all(|e| !matches!(e.kind, K::SlaveConfigured { .. })));
    for id in IDS {
        let v = n.m().slave(NodeId::must(id));
        assert_eq!(
            (v.phase, v.state),
            (BootPhase::Observed, Some(NmtState::PreOperational))
        );
    }
    let t0 = n.sim.now();
    n.m_mut().set_active(t0, true);
    n.sim.run_until(Instant::from_secs(1));
    let ev = n.events();
    let (t_net, broadcast) = find(&ev, |k| match k {
        K::NetworkStarted {
            broadcast,
            takeover: false,
        } => Some(*broadcast),
        _ => None,
    })
    .unwrap();
    assert!(broadcast);
    let stats = n.m().stats();
    assert_eq!(stats.jobs_queued, 12, "{stats:?}");
    assert_eq!(stats.max_waiting, 12, "{stats:?}");
    assert_eq!(stats.events_dropped, 0);
    assert_configured_and_running(&n);
    // Bus-bound: 20 × 9 round trips cannot take less than their frames (an 8-byte frame is at
    // least 111 bits with the intermission).
    let floor = duocan::sim::timing::bits_duration(20 * ACCESSES * 2 * 111, BITRATE);
    println!(
        "20 pre-operational slaves at a takeover, {} kbit/s, 8 SDO sessions: network started {:.3} ms after it (their frames alone need {:.3} ms); {} waits for a session",
        BITRATE / 1000,
        ms(t_net) - ms(t0),
        floor.as_micros() as f64 / 1000.0,
        stats.jobs_queued,
    );
    assert!(t_net - t0 >= floor);
    assert!(t_net - t0 <= floor.saturating_mul(2));
}
