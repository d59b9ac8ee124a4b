//! Chaos soak: one simulated hour of random faults and repairs of buses, ports, slaves and
//! masters (seeded, reproducible), with the invariants checked every 50 ms of simulated time:
//!
//! - never two active masters for longer than [`TWO_ACTIVE_BOUND`];
//! - every pair with a live member has, once the pair and the active master have been left
//!   alone for [`SETTLE`], exactly one active member in the active master's table, running
//!   (operational), the other live member not running; a pair with no live member has none;
//! - a probe node's messages (a counter every 100 ms on both buses) reach every live master
//!   exactly once and in order.
//!
//! Fault model: at most one connectivity fault at a time (a bus cut, or one port of one device
//! unplugged), so every two devices always share a working bus; any number of dead slaves; at
//! most one dead master.

use crate::net::*;
use duocan::machine::StationEvent;
use duocan::node::NodeEventKind;
use duocan::sim::PortRef;
use duocan::{Device, Duration, Frame, Id, Instant, NmtState, PortStatus};
use duocan_redundancy::supervisor::flying_master::{FlyingEvent, MasterReason};
use duocan_redundancy::supervisor::pairs::{PairsEvent, RoleReason};
use duocan_redundancy::{Member, PairId, SupervisorEvent};

const HOUR: Instant = Instant::from_secs(3600);
const CHECK: Duration = Duration::from_millis(50);
const TWO_ACTIVE_BOUND: Duration = Duration::from_millis(150);
const SETTLE: Duration = Duration::from_millis(1500);
const PAIRS: u8 = 3;
const PROBE: u8 = 0x7E;

/// Sends EMCY (0x80 + 0x7E) with a counter every 100 ms on both ports.
struct Probe {
    next: Instant,
    counter: u32,
    out: Vec<(usize, Frame)>,
}

impl Device for Probe {
    type Event = ();
    fn port_count(&self) -> usize {
        2
    }
    fn handle_rx(&mut self, _: Instant, _: usize, _: &Frame) {}
    fn handle_port_status(&mut self, _: Instant, _: usize, _: PortStatus) {}
    fn handle_timeout(&mut self, now: Instant) {
        while self.next <= now {
            let c = self.counter.to_le_bytes();
            let f = Frame::from_array(
                Id::Standard(0x80 + PROBE as u16),
                [0x00, 0x10, 0, c[0], c[1], c[2], c[3], 0],
            );
            self.out.push((1, f));
            self.out.push((0, f));
            self.counter += 1;
            self.next += Duration::from_millis(100);
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.out.pop()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        Some(self.next)
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn ms(&mut self, lo: u64, hi: u64) -> Duration {
        Duration::from_millis(lo + self.below(hi - lo))
    }
}

#[derive(Clone, Copy, Debug)]
enum Conn {
    Bus(usize),
    Port(PortRef),
}

#[test]
fn one_hour_of_random_faults_keeps_the_invariants() {
    // A supervised station is ~180 KB (bounded tables and queues, no heap): debug builds copy it
    // a few times while building one, more than a test thread's default 2 MB stack holds.
    std::thread::Builder::new()
        .stack_size(32 << 20)
        .spawn(soak)
        .unwrap()
        .join()
        .unwrap();
}

fn soak() {
    let seed = 0x5EED_2024;
    let p = Params {
        seed,
        pairs: PAIRS,
        slave_hb: Duration::from_millis(100),
        consumer: Duration::from_millis(250),
        master_hb: Duration::from_millis(50),
        master_timeout: Duration::from_millis(125),
        sync: Duration::from_millis(100),
        ..Params::default()
    };
    let mut n = SupNet::new(p);
    n.sim.set_recording(false);
    let buses = n.buses;
    let probe = n
        .sim
        .add_device(
            "probe",
            Probe {
                next: Instant::from_millis(1000),
                counter: 0,
                out: vec![],
            },
            &buses,
        )
        .unwrap();
    let mut rng = Rng(seed);

    // Fault bookkeeping.
    let mut conn: Option<(Conn, Instant)> = None;
    let mut dead_slaves: Vec<(u8, Instant)> = vec![];
    let mut dead_master: Option<(u8, Instant)> = None;
    let mut next_fault = Instant::from_secs(3);
    let mut disturbed = [Instant::ZERO; PAIRS as usize];
    let mut master_changed = Instant::ZERO;
    let mut last_active_count_ok = Instant::ZERO;
    // Per master: (life, next expected probe counter).
    let mut expected: [Option<u32>; 2] = [None, None];
    let mut faults = 0u32;
    let mut checks = 0u32;
    let mut pair_checks = 0u32;
    let mut probe_seen = 0u64;
    let mut failovers = 0u32;
    let mut takeovers = 0u32;

    let mut t = Instant::ZERO;
    while t < HOUR {
        t += CHECK;
        // Repairs due.
        if let Some((c, until)) = conn {
            if until <= t {
                match c {
                    Conn::Bus(b) => n.sim.bus_up(buses[b]),
                    Conn::Port(pr) => n.sim.reconnect(pr),
                }
                conn = None;
            }
        }
        for (id, until) in dead_slaves.clone() {
            if until <= t {
                let d = n.slave(id);
                n.sim.replace(d, slave_station(&p, id, t)).unwrap();
                dead_slaves.retain(|x| x.0 != id);
                disturbed[((id & 0x3F) - 0x10) as usize] = t;
            }
        }
        if let Some((id, until)) = dead_master {
            if until <= t {
                let d = n.master(id);
                n.sim.replace(d, master_station(&p, id, t)).unwrap();
                expected[(id - 1) as usize] = None;
                dead_master = None;
            }
        }
        // A new fault.
        if t >= next_fault {
            next_fault = t + rng.ms(500, 6000);
            faults += 1;
            match rng.below(10) {
                0..=3 if conn.is_none() => {
                    let c = if rng.below(2) == 0 {
                        Conn::Bus(rng.below(2) as usize)
                    } else {
                        let devs = 2 + 2 * PAIRS as u64 + 1;
                        let which = rng.below(devs) as usize;
                        let port = rng.below(2) as usize;
                        let dev = if which < 2 {
                            n.masters[which].port(port)
                        } else if which < 2 + 2 * PAIRS as usize {
                            n.slaves[which - 2].1.port(port)
                        } else {
                            probe.port(port)
                        };
                        Conn::Port(dev)
                    };
                    match c {
                        Conn::Bus(b) => n.sim.bus_down(buses[b]),
                        Conn::Port(pr) => n.sim.disconnect(pr),
                    }
                    conn = Some((c, t + rng.ms(300, 8000)));
                }
                4..=7 => {
                    let i = rng.below(2 * PAIRS as u64) as usize;
                    let id = n.slaves[i].0;
                    if !dead_slaves.iter().any(|x| x.0 == id) {
                        n.sim.power_off(n.slave(id));
                        dead_slaves.push((id, t + rng.ms(200, 10_000)));
                        disturbed[((id & 0x3F) - 0x10) as usize] = t;
                    }
                }
                _ if dead_master.is_none() => {
                    let id = 1 + rng.below(2) as u8;
                    n.sim.power_off(n.master(id));
                    dead_master = Some((id, t + rng.ms(500, 10_000)));
                }
                _ => {}
            }
        }
        n.sim.run_until(t);
        checks += 1;

        // Probe messages: exactly once, in order, at every live master.
        for id in [STRONG, WEAK] {
            let ev = n.sim.take_events(n.master(id));
            for (_, e) in ev {
                match e {
                    StationEvent::Machine(SupervisorEvent::Pairs(PairsEvent::Role(r)))
                        if matches!(r.reason, RoleReason::ActiveSilent { .. }) =>
                    {
                        failovers += 1
                    }
                    StationEvent::Machine(SupervisorEvent::FlyingMaster(FlyingEvent::Role(r)))
                        if matches!(r.reason, MasterReason::HeartbeatLost { .. }) =>
                    {
                        takeovers += 1
                    }
                    _ => {}
                }
                if let StationEvent::Machine(SupervisorEvent::Node(ne)) = e {
                    if let NodeEventKind::Emcy { node, msg } = ne.kind {
                        if node.raw() == PROBE {
                            let c = u32::from_le_bytes([
                                msg.data[0],
                                msg.data[1],
                                msg.data[2],
                                msg.data[3],
                            ]);
                            let slot = &mut expected[(id - 1) as usize];
                            if let Some(want) = *slot {
                                assert_eq!(
                                    c, want,
                                    "master {id} at {t}: probe message lost or doubled"
                                );
                            }
                            *slot = Some(c + 1);
                            probe_seen += 1;
                        }
                    }
                }
            }
        }

        // Active masters.
        let live = |id: u8| dead_master.is_none_or(|d| d.0 != id);
        let actives: Vec<u8> = [STRONG, WEAK]
            .into_iter()
            .filter(|id| live(*id) && n.sup(*id).is_active())
            .collect();
        if actives.len() <= 1 {
            last_active_count_ok = t;
        }
        assert!(
            t - last_active_count_ok <= TWO_ACTIVE_BOUND,
            "two active masters since {last_active_count_ok} (at {t})"
        );
        let Some(&m) = actives.first().filter(|_| actives.len() == 1) else {
            master_changed = t;
            continue;
        };
        if n.sup(m).role() != duocan_redundancy::supervisor::flying_master::MasterRole::Active {
            master_changed = t;
        }
        let became = n
            .sup(m)
            .audit()
            .iter()
            .filter(|r| {
                matches!(
                    r.entry,
                    duocan_redundancy::supervisor::audit::AuditEntry::Master(_)
                )
            })
            .map(|r| r.at)
            .max()
            .unwrap_or(Instant::ZERO);
        master_changed = master_changed.max(became);
        if t - master_changed < SETTLE {
            continue;
        }
        // Pairs.
        for i in 0..PAIRS {
            if t - disturbed[i as usize] < SETTLE {
                continue;
            }
            let ids = [a(i), b(i)];
            let alive: Vec<bool> = ids
                .iter()
                .map(|id| n.sim.is_powered(n.slave(*id)))
                .collect();
            let table = n.sup(m).pair_supervisor().pair(PairId(i)).unwrap().active;
            pair_checks += 1;
            if !alive[0] && !alive[1] {
                assert_eq!(table, None, "at {t}: pair {i} has no live member");
                continue;
            }
            let act = table.unwrap_or_else(|| {
                panic!("at {t}: pair {i} ({alive:?}) has no active member at master {m}")
            });
            let ai = if act == Member::A { 0 } else { 1 };
            assert!(alive[ai], "at {t}: pair {i}: the active member is dead");
            let state = |k: usize| n.sim.device(n.slave(ids[k])).machine.nmt_state();
            assert_eq!(
                state(ai),
                NmtState::Operational,
                "at {t}: pair {i} active member"
            );
            if alive[1 - ai] {
                assert_ne!(
                    state(1 - ai),
                    NmtState::Operational,
                    "at {t}: pair {i}: both running"
                );
            }
        }
    }
    eprintln!(
        "{faults} faults, {takeovers} master takeovers, {failovers} pair failovers, {checks} checks, \
         {pair_checks} pair checks, {probe_seen} probe messages"
    );
    assert!(faults > 500 && pair_checks > 100_000 && probe_seen > 50_000);
    assert!(takeovers > 20 && failovers > 50);
    // Recording is off: the masters' events, taken at every check, all arrived; the slaves'
    // logs, never taken, stopped at their capacity instead of growing for an hour.
    for id in [STRONG, WEAK] {
        assert_eq!(n.sim.events_dropped(n.master(id)), 0, "master {id}");
    }
    let slave = n.slave(a(0));
    assert!(n.sim.events_dropped(slave) > 0);
    assert_eq!(
        n.sim.events(slave).len(),
        duocan::sim::DEFAULT_EVENT_CAPACITY
    );
}
