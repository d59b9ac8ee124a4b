//! Two masters on one bus, as the redundancy supervisor runs them: the standby sends nothing but
//! its own heartbeat and follows the slaves' states; when it becomes active it resets nothing,
//! adopts the running slaves, boots the pre-operational ones, produces SYNC. Slaves whose start
//! is left to the application stay pre-operational until the application starts them.

use crate::net::*;
use duocan::machine::{SinglePort, StationEvent};
use duocan::master::{
    BootPhase, Master, MasterConfig, MasterEventKind as K, SlaveConfig, StartPolicy,
};
use duocan::node::NodeEventKind;
use duocan::od::{comm, DynamicDictionary, ObjectDictionary};
use duocan::sim::DevId;
use duocan::{Duration, Id, Instant, NmtState, NodeId, Station};

const BITRATE: u32 = 500_000;
const STANDBY_ID: NodeId = NodeId::must(0x10);
const SYNC_PERIOD_US: u32 = 10_000;

fn network() -> MasterConfig {
    let mut net = MasterConfig::new();
    for id in 2..=4u8 {
        net = net.slave(
            SlaveConfig::new(NodeId::must(id))
                .mandatory()
                .identity(expected(id))
                .heartbeat(50, 150)
                .write_u16(APP, 1, 0x42),
        );
    }
    // The standby member of a slave pair: the supervisor decides when it runs.
    net.slave(
        SlaveConfig::new(NodeId::must(5))
            .identity(expected(5))
            .heartbeat(50, 150)
            .write_u16(APP, 1, 0x42)
            .start(StartPolicy::Application),
    )
}

/// A master producing SYNC every 10 ms and its heartbeat every 100 ms.
fn producing(id: NodeId, config: MasterConfig) -> Master<DynamicDictionary> {
    master_with(id, config, |od| {
        od.write(comm::SYNC_COB_ID, 0, &0x4000_0080u32.to_le_bytes())
            .unwrap();
        od.write(comm::SYNC_PERIOD, 0, &SYNC_PERIOD_US.to_le_bytes())
            .unwrap();
        od.write(comm::HEARTBEAT_PRODUCER, 0, &100u16.to_le_bytes())
            .unwrap();
    })
}

type MasterDev = Station<SinglePort, Master<DynamicDictionary>>;

struct Pairing {
    n: Net,
    standby: DevId<MasterDev>,
}

fn two_masters() -> Pairing {
    let mut n = Net::new(BITRATE, producing(MASTER_ID, network()), &[2, 3, 4, 5]);
    let standby = n
        .sim
        .add_device(
            "standby",
            Station::single(producing(STANDBY_ID, network().standby())),
            &[n.bus],
        )
        .unwrap();
    n.boot_master();
    n.sim.device_mut(standby).machine.boot(Instant::ZERO);
    for id in 2..=5 {
        n.boot_slave_at(id, Instant::from_millis(5));
    }
    Pairing { n, standby }
}

impl Pairing {
    fn b(&self) -> &Master<DynamicDictionary> {
        &self.n.sim.device(self.standby).machine
    }
    fn b_events(&self) -> Vec<duocan::master::MasterEvent> {
        master_events(self.n.sim.events(self.standby))
    }
    fn sent_by(&self, who: &str, after: Instant) -> Vec<(Instant, duocan::Frame)> {
        sent(&self.n.sim)
            .into_iter()
            .filter(|(t, name, _)| name == who && *t > after)
            .map(|(t, _, f)| (t, f))
            .collect()
    }
}

#[test]
fn standby_observes_then_takes_over_without_resetting_anything() {
    let mut p = two_masters();
    p.n.sim.run_until(Instant::from_millis(1_000));

    // Active master: 2–4 started; 5 configured and left pre-operational.
    let a_ev = p.n.events();
    let (_, policy) = find(&a_ev, |k| match k {
        K::SlaveConfigured { node, start } if node.raw() == 5 => Some(*start),
        _ => None,
    })
    .unwrap();
    assert_eq!(policy, StartPolicy::Application);
    assert_eq!(p.n.m().slave(NodeId::must(5)).phase, BootPhase::Ready);
    assert_eq!(p.n.slave(5).nmt_state(), NmtState::PreOperational);
    for id in 2..=4 {
        assert_eq!(p.n.slave(id).nmt_state(), NmtState::Operational);
    }

    // The standby sent its boot-up and heartbeats, nothing else; it knows every state.
    let b_frames = p.sent_by("standby", Instant::ZERO);
    assert!(b_frames.len() >= 10);
    assert!(b_frames.iter().all(|(_, f)| f.id() == Id::Standard(0x710)));
    assert_eq!(p.b().stats().nmt_sent, 0);
    assert_eq!(p.b().sdo().stats().started, 0);
    for id in 2..=5u8 {
        let v = p.b().slave(NodeId::must(id));
        assert_eq!(v.phase, BootPhase::Observed);
        let want = if id == 5 {
            NmtState::PreOperational
        } else {
            NmtState::Operational
        };
        assert_eq!(v.state, Some(want), "slave {id}");
    }
    assert!(!p.b().network_started());
    assert_eq!(p.b().node().nmt_state(), NmtState::Operational);
    // SYNC from the active master only, every 10 ms.
    let syncs: Vec<_> = sent(&p.n.sim)
        .into_iter()
        .filter(|(_, _, f)| f.id() == Id::Standard(0x80))
        .collect();
    assert!(syncs.iter().all(|(_, who, _)| who == "master"));
    assert!((99..=100).contains(&syncs.len()), "{}", syncs.len());

    // The active master dies; the supervisor (here: the test) activates the standby.
    let master = p.n.master;
    p.n.sim.at(Instant::from_millis(1_500), move |sim| {
        sim.power_off(master)
    });
    p.n.sim.run_until(Instant::from_millis(1_600));
    let t = p.n.sim.now();
    p.n.sim.device_mut(p.standby).machine.set_active(t, true);
    p.n.sim.run_until(Instant::from_millis(2_500));

    let b_ev = p.b_events();
    let adopted: Vec<u8> = all(&b_ev, |k| match k {
        K::SlaveAdopted {
            node,
            state: NmtState::Operational,
        } => Some(node.raw()),
        _ => None,
    })
    .into_iter()
    .map(|(at, n)| {
        assert_eq!(at, t);
        n
    })
    .collect();
    assert_eq!(adopted, [2, 3, 4]);
    assert_eq!(
        find(&b_ev, |k| match k {
            K::NetworkStarted { takeover, .. } => Some(*takeover),
            _ => None,
        }),
        Some((t, true))
    );
    // No NMT command at all; SDO only to slave 5, the pre-operational one (booted, not started).
    assert!(nmt_frames(&p.n.sim).iter().all(|(at, _, _)| *at < t));
    let b_after = p.sent_by("standby", t);
    let sdo_to: Vec<u16> = b_after
        .iter()
        .filter_map(|(_, f)| match f.id() {
            Id::Standard(id @ 0x601..=0x67F) => Some(id - 0x600),
            _ => None,
        })
        .collect();
    assert!(
        !sdo_to.is_empty() && sdo_to.iter().all(|n| *n == 5),
        "{sdo_to:?}"
    );
    let (_, policy) = find(&b_ev, |k| match k {
        K::SlaveConfigured { node, start } if node.raw() == 5 => Some(*start),
        _ => None,
    })
    .unwrap();
    assert_eq!(policy, StartPolicy::Application);
    assert_eq!(p.b().slave(NodeId::must(5)).phase, BootPhase::Ready);
    assert_eq!(p.n.slave(5).nmt_state(), NmtState::PreOperational);

    // SYNC resumes from the new active master, one period after the takeover, every 10 ms.
    let b_syncs: Vec<Instant> = b_after
        .iter()
        .filter(|(_, f)| f.id() == Id::Standard(0x80))
        .map(|(t, _)| *t)
        .collect();
    assert!((89..=90).contains(&b_syncs.len()), "{}", b_syncs.len());
    let first = b_syncs[0];
    assert!(first > t && first - t < Duration::from_micros(SYNC_PERIOD_US as u64 + 500));
    println!(
        "takeover at {:.3} ms: no NMT command, 3 slaves adopted operational, slave 5 configured and left pre-operational; first SYNC of the new master at {:.3} ms",
        ms(t),
        ms(first)
    );

    // The running slaves never changed state after they were started.
    for id in 2..=4u8 {
        let dev = p.n.slave_dev(id);
        let changes = p
            .n
            .sim
            .events(dev)
            .iter()
            .filter(|(at, e)| {
                *at > Instant::from_millis(100)
                    && matches!(e, StationEvent::Machine(e) if matches!(e.kind, NodeEventKind::StateChanged { .. }))
            })
            .count();
        assert_eq!(changes, 0, "slave {id}");
        assert_eq!(p.n.slave(id).nmt_state(), NmtState::Operational);
    }

    // The supervisor starts the pair's member when it wants it.
    let now = p.n.sim.now();
    p.n.sim
        .device_mut(p.standby)
        .machine
        .start_slave(now, NodeId::must(5))
        .unwrap();
    p.n.sim.run_for(Duration::from_millis(10));
    assert_eq!(p.n.slave(5).nmt_state(), NmtState::Operational);
    assert_eq!(p.b().slave(NodeId::must(5)).phase, BootPhase::Started);
    assert_eq!(
        p.b().slave(NodeId::must(5)).state,
        Some(NmtState::Operational)
    );
}

#[test]
fn demoted_master_goes_quiet_at_once() {
    let mut p = two_masters();
    // Mid-boot: the slaves' boot-ups came at 5 ms, their configuration runs.
    p.n.sim.run_until(Instant::from_millis(7));
    assert!(p.n.m().slaves().any(|v| v.phase.is_running()));
    let t = p.n.sim.now();
    p.n.m_mut().set_active(t, false);
    p.n.sim.run_until(Instant::from_millis(1_000));
    // What it still sends: at most the SDO requests already handed to the driver, then only its
    // heartbeat.
    let late: Vec<_> = p
        .sent_by("master", t + Duration::from_millis(2))
        .into_iter()
        .filter(|(_, f)| f.id() != Id::Standard(0x701))
        .collect();
    assert!(late.is_empty(), "{late:?}");
    assert!(p.n.m().slaves().all(|v| v.phase == BootPhase::Observed));
    assert!(!p.n.m().is_active());
    assert_eq!(
        p.n.m().node().od().get_u32(comm::SYNC_COB_ID, 0),
        Some(0x80),
        "SYNC production off while standby"
    );
    for id in 2..=5 {
        assert_eq!(p.n.slave(id).nmt_state(), NmtState::PreOperational);
    }
    let ev = p.n.events();
    assert!(
        find(&ev, |k| match k {
            K::ActiveChanged { active } => Some(*active),
            _ => None,
        }) == Some((t, false))
    );
}

/// Events of the master's own node (the pass-through), with their kinds.
fn node_kinds(
    log: &[(
        Instant,
        StationEvent<std::convert::Infallible, duocan::master::MasterEvent>,
    )],
) -> Vec<(Instant, NodeEventKind)> {
    log.iter()
        .filter_map(|(_, e)| match e {
            StationEvent::Machine(duocan::master::MasterEvent {
                at,
                kind: K::Node(k),
            }) => Some((*at, *k)),
            _ => None,
        })
        .collect()
}

#[test]
fn standby_guards_the_guarded_slaves_beside_the_active_master() {
    // Slaves 2 and 3 without heartbeat, guarded every 100 ms with life time factor 3.
    let guarded = |id: u8| {
        SlaveConfig::new(NodeId::must(id))
            .identity(expected(id))
            .with_assignment(duocan::master::Assignment::slave().guarded(100, 3))
    };
    let net = || MasterConfig::new().slave(guarded(2)).slave(guarded(3));
    let mut n = Net::new(BITRATE, master(net()), &[2, 3]);
    let standby = n
        .sim
        .add_device(
            "standby",
            Station::single(master_with(STANDBY_ID, net().standby(), |_| {})),
            &[n.bus],
        )
        .unwrap();
    n.boot_master();
    n.sim.device_mut(standby).machine.boot(Instant::ZERO);
    for id in [2, 3] {
        n.boot_slave_at(id, Instant::from_millis(5));
    }
    n.sim.run_until(Instant::from_millis(1_000));

    // Both masters poll both slaves every 100 ms.
    fn rtr(
        sim: &duocan::sim::SimNetwork,
        who: &str,
        node: u16,
        from: Instant,
        to: Instant,
    ) -> usize {
        sent(sim)
            .into_iter()
            .filter(|(t, name, f)| {
                name == who
                    && f.is_remote()
                    && f.id() == Id::Standard(0x700 + node)
                    && *t >= from
                    && *t < to
            })
            .count()
    }
    for who in ["master", "standby"] {
        for node in [2, 3] {
            let c = rtr(
                &n.sim,
                who,
                node,
                Instant::from_millis(200),
                Instant::from_millis(1_000),
            );
            assert_eq!(c, 8, "{who} guarding {node}");
        }
    }
    // The slaves answered every request of either master, toggling each time; neither master
    // saw a toggle error.
    for id in [2u16, 3] {
        let answers: Vec<u8> = sent(&n.sim)
            .into_iter()
            .filter(|(_, name, f)| {
                *name == format!("slave{id}")
                    && !f.is_remote()
                    && f.id() == Id::Standard(0x700 + id)
            })
            .map(|(_, _, f)| f.data()[0])
            .skip(1) // the boot-up
            .collect();
        assert!(answers.len() >= 16, "{answers:?}");
        for w in answers.windows(2) {
            assert_ne!(w[0] & 0x80, w[1] & 0x80, "slave {id}: {answers:?}");
        }
    }
    let toggle_errors = |log: &[(
        Instant,
        StationEvent<std::convert::Infallible, duocan::master::MasterEvent>,
    )]| {
        node_kinds(log)
            .into_iter()
            .filter(|(_, k)| matches!(k, NodeEventKind::GuardToggleError { .. }))
            .count()
    };
    assert_eq!(toggle_errors(n.sim.events(n.master)), 0);
    assert_eq!(toggle_errors(n.sim.events(standby)), 0);
    // Besides its boot-up and heartbeat, the standby sent only guarding requests.
    assert!(sent(&n.sim)
        .into_iter()
        .filter(|(_, name, _)| name == "standby")
        .all(|(_, _, f)| f.id() == Id::Standard(0x710) || f.is_remote()));
    assert_eq!(n.sim.device(standby).machine.stats().nmt_sent, 0);

    // Slave 3 dies: both masters lose it (F) at their own life time after its last answer.
    let dev3 = n.slave_dev(3);
    n.sim
        .at(Instant::from_millis(1_020), move |sim| sim.power_off(dev3));
    n.sim.run_until(Instant::from_millis(1_450));
    let last_answer = sent(&n.sim)
        .into_iter()
        .filter(|(t, name, f)| {
            name == "slave3" && !f.is_remote() && *t < Instant::from_millis(1_020)
        })
        .map(|(t, _, _)| t)
        .max()
        .unwrap();
    for log in [n.sim.events(n.master), n.sim.events(standby)] {
        let lost = all(&master_events(log), |k| match k {
            K::SlaveLost { node, status } if node.raw() == 3 => Some(*status),
            _ => None,
        });
        assert_eq!(lost.len(), 1, "{lost:?}");
        assert_eq!(lost[0].1, duocan::master::ErrorStatus::F);
        // Life time 300 ms from the last valid answer each master took.
        assert!(
            lost[0].0 > last_answer + Duration::from_millis(200)
                && lost[0].0 <= last_answer + Duration::from_millis(300),
            "{} vs {}",
            lost[0].0,
            last_answer
        );
    }
    assert!(n.sim.device(standby).machine.slave(NodeId::must(3)).missing);

    // The active master dies; the standby takes over and guards on, without a toggle error and
    // without touching the running slave.
    let m = n.master;
    n.sim.power_off(m);
    n.sim.run_until(Instant::from_millis(1_500));
    let t = n.sim.now();
    n.sim.device_mut(standby).machine.set_active(t, true);
    n.sim.run_until(Instant::from_millis(2_500));
    assert_eq!(
        rtr(&n.sim, "standby", 2, t, Instant::from_millis(2_500)),
        10
    );
    assert_eq!(toggle_errors(n.sim.events(standby)), 0);
    assert_eq!(n.slave(2).nmt_state(), NmtState::Operational);
    assert!(nmt_frames(&n.sim).iter().all(|(at, _, _)| *at < t));
    assert!(!n.sim.device(standby).machine.slave(NodeId::must(2)).missing);
}
