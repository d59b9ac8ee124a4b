//! A transceiver that receives but cannot send (TXD stuck recessive, a broken TX line) on one
//! port of a board or a master, and what the campaign asks of it.
//!
//! The simulator models the controller as it is ([`duocan::sim::SimNetwork::set_port_tx_dead`]):
//! every attempt a bit error, the transmit error counter +8 per attempt, error passive at 128,
//! bus-off at 256 (what it held dropped), its automatic restart after 128 × 11 recessive bits,
//! receiving all along but while bus-off. Nothing it sends reaches that bus; its frames reach
//! the other bus through its other port.
//!
//! Besides every other promise (nothing lost or duplicated on the logical bus, one active
//! master, ...), at the repair, when the device lived through the whole fault:
//!
//! - its own port health reports the port: not `Ok`, bus-off among its causes;
//! - it does not flap: the port's state changes at most twice per re-initialisation (failed,
//!   recovering), plus a few: receiving, or the controller's restart, proves nothing of a
//!   transmitter;
//! - every other powered device that holds a port on that bus in a working state, and heard
//!   the node all the while, hears it on the other bus only (its reachability).

use crate::faults::{dev_index, port_of};
use crate::plant::{MASTER_HB, SLAVE_HB, STRONG, WEAK};
use crate::run::Run;
use duocan::machine::ErrorCause;
use duocan::{Duration, Instant, NodeId};
use duocan_redundancy::link::health::HealthCounters;
use duocan_redundancy::{DualBus, PortState};

/// The shortest fault judged at its repair (shorter ones may end before the first bus-off is
/// reported anywhere, or before the reachability timeout has passed).
const JUDGED: Duration = Duration::from_millis(500);

/// State changes of the dead port allowed on top of two per re-initialisation: its first
/// error, its first bus-off, a lag's suspicion and its end.
const SLACK: usize = 6;

/// The link of device `node` (a master's id, or a slave's node-ID).
pub fn link(run: &Run, node: u8) -> &DualBus {
    let sim = &run.plant.sim;
    if node == STRONG || node == WEAK {
        &sim.device(run.plant.master(node)).inner.link.inner
    } else {
        &sim.device(run.plant.slave(node).0).inner.link.inner
    }
}

fn powered(run: &Run, node: u8) -> bool {
    if node == STRONG || node == WEAK {
        run.plant.sim.is_powered(run.plant.master(node))
    } else {
        run.plant.sim.is_powered(run.plant.slave(node).0)
    }
}

/// `node`'s port `port` cannot send for `dur` from now.
pub fn apply(run: &mut Run, node: u8, port: usize, dur: Duration) {
    let p = port_of(run, node, port);
    let d = dev_index(run, node);
    let from = run.now();
    let before = *link(run, node).health().port(port).counters();
    let set = move |r: &mut Run, on: bool| {
        r.plant.sim.set_port_tx_dead(p, on);
        let t = r.now();
        r.timeline.devs[d].tx_dead[port].set(t, on);
    };
    set(run, true);
    run.at(from + dur, move |r| {
        if dur >= JUDGED {
            judge(r, node, port, from, &before);
        }
        set(r, false);
        left_failed(r, node, port);
    });
}

/// After the repair, a port failed for a bus-off waits for a probe (the node's next heartbeat)
/// or its re-initialisation to carry the node's frames again: the timeline knows its bus
/// carries nothing else of this device's meanwhile.
fn left_failed(run: &mut Run, node: u8, port: usize) {
    if !powered(run, node) {
        return;
    }
    let now = run.now();
    let i = dev_index(run, node);
    let h = link(run, node).health().port(port);
    let Some(at) = h.next_reinit().filter(|_| h.stalled()) else {
        return;
    };
    let clock = run.plant.oracle.borrow().clock[i];
    // On the simulated time line; back at its next heartbeat (its probe, after the
    // controller's restart) if sooner.
    let restart = Duration::from_millis(2);
    let until = clock
        .back(at)
        .min(now + SLAVE_HB.max(MASTER_HB) + restart + Duration::from_millis(2));
    if until > now {
        let sp = &mut run.timeline.devs[i].stalled[port];
        sp.start(now);
        sp.end(until);
    }
}

/// The promises of the class at the repair (see the module documentation).
fn judge(run: &mut Run, node: u8, port: usize, from: Instant, before: &HealthCounters) {
    let now = run.now();
    let i = dev_index(run, node);
    let dev = &run.timeline.devs[i];
    let lived = !dev.off.any(from, now) && !dev.reboots.iter().any(|t| *t >= from);
    if !lived {
        return;
    }
    let bus = dev.port(port);
    let h = link(run, node).health().port(port);
    let c = h.counters();
    let bus_offs = c.errors_of(ErrorCause::BusOff) - before.errors_of(ErrorCause::BusOff);
    let mut problems = vec![];
    if h.state() == PortState::Ok || bus_offs == 0 {
        problems.push(format!(
            "node {node:#x}'s port {port} (bus {}) cannot send since {from}: its health says \
             {:?} with {bus_offs} bus-off reports",
            bus + 1,
            h.state()
        ));
    }
    let reinits = (c.reinits - before.reinits) as usize;
    let changes = crate::effects::port_changes(run, node, port, from, now);
    if changes > 2 * reinits + SLACK {
        problems.push(format!(
            "node {node:#x}'s port {port} (bus {}) cannot send since {from}: {changes} state \
             changes for {reinits} re-initialisations (flapping)",
            bus + 1
        ));
    }
    // The others: each that heard the node all along, its port on that bus working.
    let nid = NodeId::must(node);
    let others: Vec<u8> = run
        .timeline
        .devs
        .iter()
        .map(|d| d.node_id)
        .filter(|n| {
            *n != node && (*n == STRONG || *n == WEAK || run.plant.slaves.iter().any(|s| s.0 == *n))
        })
        .collect();
    for o in others {
        let od = &run.timeline.devs[dev_index(run, o)];
        if od.off.any(from, now) || od.reboots.iter().any(|t| *t >= from) || !powered(run, o) {
            continue;
        }
        let op = od.port(bus);
        let l = link(run, o);
        let works = l.health().port(op).state() == PortState::Ok
            && l.health().port(1 - op).state() == PortState::Ok;
        // A lag on its ports (frames of before the fault handed over late) or an impostor of
        // the node (its heartbeats on that bus) aside.
        let lagged = !od.lag(from, now).is_zero();
        let impostor = run
            .timeline
            .impostors
            .iter()
            .any(|(n, sp)| *n == node && sp.any(from, now));
        if !works || lagged || impostor {
            continue;
        }
        if let Some(heard) = l.reach().heard(nid) {
            if heard[op] {
                problems.push(format!(
                    "node {o:#x} hears node {node:#x} on bus {} at {now}, whose port there \
                     cannot send since {from}",
                    bus + 1
                ));
            }
        }
    }
    for p in problems {
        run.problem(now, p);
    }
}
