//! Whether each fault took effect.
//!
//! A fault can reach its class in the coverage report and test nothing: the campaign's impostor
//! once beat a heartbeat with a state byte no node sends, which every layer dropped as
//! malformed, so the one-bus rule was never exercised while the report said "impostor
//! heartbeat" in every budget. So each fault is judged, a second after it ends (at most five
//! seconds after it began), by what the plant shows of it:
//!
//! - a bus cut, in sequence or flapping: a device's port on that bus (both, for a sequence)
//!   left `Ok`, or failed a transmission;
//! - a lag on a port: that device's port handed a frame over late (after its receive stamp);
//! - a babble: a port on that bus failed for a transmit stall;
//! - an unplugged port: that device's port left `Ok`;
//! - an impostor, a live board's duplicate: a master found the node's heartbeats implausible
//!   (suspect, duplicate, babbling);
//! - a board that stops: a master saw its heartbeat say so;
//! - noise: error reports on that bus; an overrun: that controller's overflow reports;
//! - a transceiver that cannot send: that controller reported a bus-off;
//! - a controller stuck error passive: that controller reported error passive;
//! - a bridge loop: the bridge's copies reached the other bus (acknowledged there);
//! - a slow transmitter: a frame waited in that controller for its delay;
//! - port writes drifting apart: a frame waited in that controller, and (a duocan sender) its
//!   layer failed the port for a transmit stall;
//! - a board or master that dies (once or in a boot loop), a master's clock stepped back or
//!   jumped ahead, a device's clock at a wrong rate: the device was powered when the fault
//!   came (its effect is the simulator's or the clock's own doing).
//!
//! The fixed budget then asserts that every class took effect at least once.

use crate::faults::{bus_of, Fault};
use crate::plant::{STRONG, WEAK};
use crate::run::Run;
use duocan::machine::{ErrorCause, StationEvent};
use duocan::node::NodeEventKind;
use duocan::{Duration, Instant};
use duocan_redundancy::link::health::HealthCounters;
use duocan_redundancy::{
    DualBus, LinkEvent, LinkEventKind, PortReason, PortState, SupervisorEvent,
};

/// How long after its end a fault is judged, and the longest it is watched for.
const AFTER: Duration = Duration::from_secs(1);
const LONGEST: Duration = Duration::from_secs(4);

/// Judges `f`, applied now, once its window has passed; counts it in `run.effective`.
pub fn watch(run: &mut Run, f: Fault) {
    let from = run.now();
    let direct = match f {
        Fault::BoardDies { node, .. }
        | Fault::BootLoop { node, .. }
        | Fault::Stops { node, .. } => run.plant.sim.is_powered(run.plant.slave(node).0),
        Fault::MasterDies { id, .. }
        | Fault::MasterBootLoop { id, .. }
        | Fault::StepBack { id, .. }
        | Fault::JumpAhead { id, .. } => run.plant.sim.is_powered(run.plant.master(id)),
        Fault::ClockRate { node, .. }
        | Fault::TxDead { node, .. }
        | Fault::ErrorPassive { node, .. }
            if node == STRONG || node == WEAK =>
        {
            run.plant.sim.is_powered(run.plant.master(node))
        }
        Fault::ClockRate { node, .. }
        | Fault::TxDead { node, .. }
        | Fault::ErrorPassive { node, .. } => run.plant.sim.is_powered(run.plant.slave(node).0),
        _ => true,
    };
    let before = counters(run);
    let waited = tx_waited(run, &f);
    let bridged = bridge_sent(run);
    let written = producer_written(run);
    let until = from + f.span().min(LONGEST) + AFTER;
    run.at(until, move |r| {
        let now = r.now();
        let seen = direct
            && match f {
                Fault::SlowTx { .. } => tx_waited(r, &f) > waited,
                Fault::Bridge { .. } => bridge_sent(r) > bridged,
                // The master confirmed the download (a master that stayed standby did not).
                Fault::ProducerTime { .. } => producer_written(r) > written,
                // Past the stall time: a duocan sender's layer flushed the port and failed it
                // (the node that is not duocan has no layer: its frames waited).
                Fault::TxDrift { node, port, .. } => {
                    tx_waited(r, &f) > waited
                        && (node == crate::foreign::FOREIGN || stalled(r, node, port, from, now))
                }
                _ => took_effect(r, f, from, now, &before),
            };
        if seen {
            *r.effective.entry(f.class()).or_default() += 1;
        }
    });
}

/// Producer times the masters downloaded and had confirmed.
fn producer_written(run: &Run) -> u32 {
    [STRONG, WEAK]
        .into_iter()
        .map(|id| run.plant.sim.device(run.plant.master(id)).producer_done)
        .sum()
}

/// How many copies the bridge between the buses sent so far.
fn bridge_sent(run: &Run) -> u64 {
    run.plant.sim.bridge_stats().map_or(0, |s| s.sent)
}

/// How many frames a slow transmitter's port has held back (0 for other faults).
fn tx_waited(run: &Run, f: &Fault) -> u64 {
    match *f {
        Fault::SlowTx { node, port, .. } | Fault::TxDrift { node, port, .. } => {
            let p = crate::faults::port_of(run, node, port);
            run.plant.sim.port_stats(p).tx_waited
        }
        _ => 0,
    }
}

/// Every device's port counters, by node (a master's id, a slave's node-ID).
type Counters = Vec<(u8, [HealthCounters; 2])>;

fn links(run: &Run) -> Vec<(u8, &DualBus)> {
    let sim = &run.plant.sim;
    let mut v = vec![];
    for (k, d) in run.plant.masters.iter().enumerate() {
        v.push((k as u8 + 1, &sim.device(*d).inner.link.inner));
    }
    for (id, d, _) in &run.plant.slaves {
        v.push((*id, &sim.device(*d).inner.link.inner));
    }
    v
}

fn counters(run: &Run) -> Counters {
    links(run)
        .into_iter()
        .map(|(n, l)| (n, [0, 1].map(|p| *l.health().port(p).counters())))
        .collect()
}

/// The link events of device `node` (a master's id, or a slave's node-ID) in `[from, to]`.
fn link_events(run: &Run, node: u8, from: Instant, to: Instant) -> Vec<LinkEvent> {
    let sim = &run.plant.sim;
    if node == STRONG || node == WEAK {
        links_of(sim.events(run.plant.master(node)), from, to)
    } else {
        links_of(sim.events(run.plant.slave(node).0), from, to)
    }
}

/// Device `node`'s port `port` failed for a transmit stall in `[from, to]`.
fn stalled(run: &Run, node: u8, port: usize, from: Instant, to: Instant) -> bool {
    link_events(run, node, from, to).iter().any(|e| {
        matches!(e.kind, LinkEventKind::Port { port: p, reason: PortReason::TxStalled { .. }, .. }
            if p as usize == port)
    })
}

/// How many times device `node`'s port `port` changed state in `[from, to]`.
pub fn port_changes(run: &Run, node: u8, port: usize, from: Instant, to: Instant) -> usize {
    link_events(run, node, from, to)
        .iter()
        .filter(|e| matches!(e.kind, LinkEventKind::Port { port: p, .. } if p as usize == port))
        .count()
}

/// The link events among a station's `events` in `[from, to]`.
fn links_of<M>(
    events: &[(Instant, StationEvent<LinkEvent, M>)],
    from: Instant,
    to: Instant,
) -> Vec<LinkEvent> {
    events
        .iter()
        .filter(|(t, _)| *t >= from && *t <= to)
        .filter_map(|(_, e)| match e {
            StationEvent::Link(l) => Some(*l),
            _ => None,
        })
        .collect()
}

/// Every device's link events in `[from, to]`, each with the device's port on bus 1, on
/// bus 2 (crossed cabling swaps them).
fn all_link_events(run: &Run, from: Instant, to: Instant) -> Vec<([usize; 2], LinkEvent)> {
    links(run)
        .into_iter()
        .flat_map(|(n, _)| {
            let ports = [0, 1].map(|b| bus_of(run, n, b));
            link_events(run, n, from, to)
                .into_iter()
                .map(move |e| (ports, e))
        })
        .collect()
}

/// Both masters' supervisor events in `[from, to]`.
fn master_events(run: &Run, from: Instant, to: Instant) -> Vec<SupervisorEvent> {
    let sim = &run.plant.sim;
    run.plant
        .masters
        .iter()
        .flat_map(|d| sim.events(*d).iter())
        .filter(|(t, _)| *t >= from && *t <= to)
        .filter_map(|(_, e)| match e {
            StationEvent::Machine(m) => Some(m.clone()),
            _ => None,
        })
        .collect()
}

/// A port on bus `bus` left `Ok` (any device).
fn port_left_ok(events: &[([usize; 2], LinkEvent)], bus: usize) -> bool {
    events.iter().any(|(ports, e)| {
        matches!(e.kind, LinkEventKind::Port { port, to, .. }
            if port as usize == ports[bus] && to != PortState::Ok)
    })
}

/// Error reports (controller errors, failed transmissions) on bus `bus` grew since `before`,
/// at device `node` or any (`None`), counting only `cause` if given.
fn errors_grew(
    run: &Run,
    before: &Counters,
    bus: usize,
    node: Option<u8>,
    cause: Option<ErrorCause>,
) -> bool {
    let now = counters(run);
    now.iter().zip(before).any(|((id, n), (_, b))| {
        if node.is_some_and(|x| x != *id) {
            return false;
        }
        let port = bus_of(run, *id, bus);
        let (n, b) = (&n[port], &b[port]);
        match cause {
            Some(c) => n.errors_of(c) > b.errors_of(c),
            None => n.errors.iter().sum::<u32>() > b.errors.iter().sum::<u32>(),
        }
    })
}

fn took_effect(run: &Run, f: Fault, from: Instant, to: Instant, before: &Counters) -> bool {
    let all = || all_link_events(run, from, to);
    match f {
        Fault::Cut { bus, .. } | Fault::Flap { bus, .. } => {
            port_left_ok(&all(), bus) || errors_grew(run, before, bus, None, None)
        }
        Fault::Sequence { .. } => {
            let e = all();
            port_left_ok(&e, 0) && port_left_ok(&e, 1)
        }
        Fault::Lag { node, port, .. }
        | Fault::GrowingLag { node, port, .. }
        | Fault::SwitchingLag { node, port, .. } => {
            let o = if node == STRONG || node == WEAK {
                run.plant.master_nodes[node as usize - 1]
            } else {
                run.plant.slave(node).1
            };
            run.plant.oracle.borrow().late[o][port].is_some_and(|t| t >= from)
        }
        Fault::Babble { node, port, .. } => {
            let bus = bus_of(run, node, port);
            all().iter().any(|(ports, e)| {
                matches!(e.kind, LinkEventKind::Port { port: p, reason: PortReason::TxStalled { .. }, .. }
                    if p as usize == ports[bus])
            })
        }
        Fault::Unplug { node, port, .. } => link_events(run, node, from, to).iter().any(|e| {
            matches!(e.kind, LinkEventKind::Port { port: p, to, .. }
                if p as usize == port && to != PortState::Ok)
        }),
        Fault::Impostor { node, .. } | Fault::Duplicate { node, .. } => {
            let events = [STRONG, WEAK]
                .into_iter()
                .flat_map(|m| link_events(run, m, from, to));
            events.into_iter().any(|e| match e.kind {
                LinkEventKind::Suspect { node: n, .. }
                | LinkEventKind::DuplicateNode { node: n, .. }
                | LinkEventKind::Babbling { node: n, .. } => n.raw() == node,
                _ => false,
            })
        }
        Fault::Stops { node, state } => master_events(run, from, to).iter().any(|e| {
            matches!(e, SupervisorEvent::Node(n) if matches!(n.kind,
                NodeEventKind::RemoteState { node: x, to, .. } if x.raw() == node && to == state))
        }),
        Fault::Noise { bus, .. } | Fault::Degrading { bus, .. } | Fault::LongFrames { bus, .. } => {
            errors_grew(run, before, bus, None, None)
        }
        // The others see the errors of its frames on that bus.
        Fault::GroundShift { node, port, .. } => {
            let bus = bus_of(run, node, port);
            counters(run).iter().zip(before).any(|((id, n), (_, b))| {
                let p = bus_of(run, *id, bus);
                *id != node && n[p].errors.iter().sum::<u32>() > b[p].errors.iter().sum::<u32>()
            })
        }
        // The others see its error flags on that bus.
        Fault::WrongBitRate { node, port, .. } => {
            let bus = bus_of(run, node, port);
            counters(run).iter().zip(before).any(|((id, n), (_, b))| {
                let p = bus_of(run, *id, bus);
                *id != node && n[p].errors.iter().sum::<u32>() > b[p].errors.iter().sum::<u32>()
            })
        }
        // Followed: the layer corrected the skew it made (a small one needs no correction).
        Fault::Drift {
            node,
            port,
            ppm,
            dur,
        } => {
            let far = ppm.unsigned_abs() as u64 * dur.as_millis() / 1_000 >= 4_000;
            !far || link_events(run, node, from, to)
                .iter()
                .any(|e| matches!(e.kind, LinkEventKind::Lag { port: p, .. } if p as usize == port))
        }
        // Its controller went bus-off.
        Fault::TxDead { node, port, .. } => {
            let bus = bus_of(run, node, port);
            errors_grew(run, before, bus, Some(node), Some(ErrorCause::BusOff))
        }
        // Its controller reported error passive.
        Fault::ErrorPassive { node, port, .. } => {
            let bus = bus_of(run, node, port);
            errors_grew(run, before, bus, Some(node), Some(ErrorCause::ErrorPassive))
        }
        Fault::Overrun { node, port, .. } => {
            let bus = bus_of(run, node, port);
            errors_grew(run, before, bus, Some(node), Some(ErrorCause::RxOverflow))
        }
        Fault::BoardDies { .. }
        | Fault::BootLoop { .. }
        | Fault::SlowTx { .. }
        | Fault::TxDrift { .. }
        | Fault::MasterDies { .. }
        | Fault::MasterBootLoop { .. }
        | Fault::StepBack { .. }
        | Fault::JumpAhead { .. }
        | Fault::ProducerTime { .. }
        | Fault::Bridge { .. }
        | Fault::ClockRate { .. } => true,
    }
}
