//! The sticky merge on the simulated dual bus: a master and 20 nodes exchange frames every
//! 10 ms (a counter and an unchanged frame each), beat every 50 ms, the master sends SYNC every
//! 10 ms; every station runs the sticky merge with its default timeout (40 ms).
//!
//! Whatever happens, no station's application gets a frame twice or out of order. What is lost
//! is exactly what the rule says: for each stream (a node's frames, or SYNC) bound at the fault
//! to the bus that fails, the copies the other bus carried within one timeout after the
//! stream's last frame on the failed bus, and nothing else. Streams bound to the other bus lose
//! nothing; nothing is lost when the bus returns.

use crate::sim::*;
use duocan::profile::Predefined;
use duocan::sim::TxOutcome;
use duocan::{Duration, Frame, Id, Instant, NodeId};
use duocan_redundancy::link::sticky::StreamKey;
use duocan_redundancy::{DualBusConfig, FrameClassifier, MergePolicy, PortState};
use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;

const SLAVES: u8 = 20;
const TIMEOUT: Duration = MergePolicy::STICKY_TIMEOUT;
const SILENCE_LIMIT: Duration = Duration::from_millis(150);
const FAULT: Instant = Instant::from_millis(1_005);
const REPAIR: Instant = Instant::from_millis(2_000);
const STOP: Instant = Instant::from_millis(3_500);
const END: Instant = Instant::from_millis(3_600);
const SYNC: Id = Id::Standard(0x080);

fn config() -> DualBusConfig {
    active_active().with_merge(MergePolicy::sticky())
}

/// The streams of the network: each node's, and the master's SYNC.
fn streams() -> Vec<StreamKey> {
    let mut v: Vec<_> = (1..=SLAVES + 1)
        .map(|n| StreamKey::Node(NodeId::must(n)))
        .collect();
    v.push(StreamKey::Id {
        id: SYNC,
        remote: false,
    });
    v
}

fn of_stream(frame: &Frame, key: StreamKey) -> bool {
    StreamKey::of(frame, Predefined.sender(frame)) == key
}

/// Per station and stream, the bus the stream is bound to, read at `t`.
type Bindings = Rc<RefCell<HashMap<(u8, StreamKey), Option<usize>>>>;

fn record_bindings(net: &mut Net, t: Instant) -> Bindings {
    let seen: Bindings = Rc::default();
    let out = seen.clone();
    let devs = net.devs.clone();
    net.sim.at(t, move |sim| {
        for (i, d) in devs.iter().enumerate() {
            let link = &sim.device(*d).link;
            for key in streams() {
                let bound = link.sticky().expect("configured").bound(key);
                out.borrow_mut().insert((i as u8 + 1, key), bound);
            }
        }
    });
    seen
}

/// What station `r` loses of stream `key` by the rule, when the stream was bound at `fault`
/// to `bus`, which then stopped handing it anything: the frames of the stream on the other bus
/// that ended within one timeout after its last one on `bus` before the fault.
fn rule_loss(net: &Net, r: u8, key: StreamKey, bus: usize, fault: Instant) -> Vec<Frame> {
    let on = |b: usize| {
        net.wire(b).into_iter().filter(move |(_, s, f, o)| {
            *s != r && matches!(o, TxOutcome::Delivered { .. }) && of_stream(f, key)
        })
    };
    let last = on(bus)
        .map(|(end, ..)| end)
        .filter(|end| *end < fault)
        .max()
        .expect("the stream was on the bus");
    on(1 - bus)
        .filter(|(end, ..)| *end > last && *end <= last + TIMEOUT)
        .map(|(_, _, f, _)| f)
        .collect()
}

/// Every station got every other station's application frames and the SYNCs, once each, in
/// order, but for what the rule loses for the streams `bindings` bound to `bus` at `fault`.
/// Returns how many streams lost something.
fn assert_only_the_rule_loses(net: &Net, bindings: &Bindings, bus: usize, fault: Instant) -> usize {
    let (mut losing, n) = (0, SLAVES + 1);
    for r in 1..=n {
        let app = &net.station(r).machine.b;
        let mut lost_at_r = |key: StreamKey| {
            let bound = bindings.borrow()[&(r, key)];
            assert!(bound.is_some(), "station {r}: {key:?} bound");
            let lost = if bound == Some(bus) {
                rule_loss(net, r, key, bus, fault)
            } else {
                vec![]
            };
            losing += usize::from(!lost.is_empty());
            lost
        };
        for s in (1..=n).filter(|s| *s != r) {
            let lost = lost_at_r(StreamKey::Node(NodeId::must(s)));
            let sender = &net.station(s).machine.b;
            let lost_counters: Vec<u32> = lost
                .iter()
                .filter(|f| f.id() == Id::Standard(0x180 + s as u16))
                .map(|f| u32::from_le_bytes(f.data().try_into().unwrap()))
                .collect();
            assert!(lost_counters.len() <= 4, "{r} from {s}: {lost_counters:?}");
            let want: Vec<u32> = (0..sender.sent_counter)
                .filter(|c| !lost_counters.contains(c))
                .collect();
            assert_eq!(app.counters_from(s), want, "station {r} from {s}");
            let lost_const = lost
                .iter()
                .filter(|f| f.id() == Id::Standard(0x280 + s as u16))
                .count();
            assert_eq!(
                app.constants_from(s),
                sender.sent_const as usize - lost_const,
                "station {r}: unchanged frames of {s}"
            );
        }
        if r != MASTER {
            let lost = lost_at_r(StreamKey::Id {
                id: SYNC,
                remote: false,
            });
            let (produced, received) = sync_counts(net, r);
            assert_eq!(received, produced - lost.len(), "SYNC at {r}");
        }
    }
    losing
}

/// `bus` is cut at 1,005 ms and repaired at 2 s.
fn cut(bus: usize) -> (Net, usize) {
    let mut net = network(1, SLAVES, config(), STOP);
    let bindings = record_bindings(&mut net, FAULT);
    // A second after the repair, while the traffic runs (after it stops, streams carry only
    // heartbeats, slower than the timeout: they follow whichever bus brings one first).
    let after = record_bindings(&mut net, REPAIR + Duration::from_secs(1));
    let b = net.buses[bus];
    net.sim.at(FAULT, move |sim| sim.bus_down(b));
    net.sim.at(REPAIR, move |sim| sim.bus_up(b));
    stop_sync(&mut net, STOP);
    net.sim.run_until(END);

    let losing = assert_only_the_rule_loses(&net, &bindings, bus, FAULT);
    net.assert_no_heartbeat_lost();
    for node in 1..=SLAVES + 1 {
        // Port health as with the exact merge: the cut bus fails exactly the silence limit
        // after the last frame it brought or acknowledged, and is ok again after the repair.
        let last = net.last_heard(node, bus, FAULT);
        let ev = net.port_events(node, bus as u8);
        let failed = ev.iter().find(|e| e.2 == PortState::Failed).unwrap();
        assert_eq!(failed.0, last + SILENCE_LIMIT, "node {node}");
        let link = &net.station(node).link;
        assert_eq!(link.port_state(bus), PortState::Ok);
        assert!(net.port_events(node, 1 - bus as u8).is_empty());
        // Every stream is on the bus that stayed: the repair moves nothing back.
        for key in streams() {
            let own = key == StreamKey::Node(NodeId::must(node))
                || (node == MASTER && !matches!(key, StreamKey::Node(_)));
            if !own {
                assert_eq!(
                    after.borrow()[&(node, key)],
                    Some(1 - bus),
                    "{node} {key:?}"
                );
            }
        }
        assert_eq!(
            link.merger().stats().delivered,
            0,
            "the exact merge is idle"
        );
    }
    (net, losing)
}

#[test]
fn cut_bus_1_loses_only_at_the_switch_within_the_timeout_and_doubles_nothing() {
    let (_, losing) = cut(0);
    // The simulator hands a frame's two copies over at the same instant, bus 1's first: every
    // stream is bound to bus 1 and switches, 20 node streams and SYNC at each slave, 20 node
    // streams at the master.
    assert_eq!(losing, 21 * 20 + 20);
}

#[test]
fn cut_bus_2_loses_only_at_the_switch_within_the_timeout_and_doubles_nothing() {
    let (_, losing) = cut(1);
    // No stream was bound to bus 2: nothing lost.
    assert_eq!(losing, 0);
}

/// The master's port on `bus` hands frames over `lag` late from `FAULT` to `REPAIR`, its
/// frames stamped on the wire. A stream bound to it switches when the lag plus the gap
/// between the stream's frames (10 ms) exceeds the timeout; it never doubles a frame.
fn late_reader(bus: usize, lag: Duration) -> (Net, usize) {
    let mut net = network(2, SLAVES, config(), STOP);
    let bindings = record_bindings(&mut net, FAULT);
    let port = net.dev(MASTER).port(bus);
    net.sim
        .at(FAULT, move |sim| sim.set_port_latency(port, lag));
    net.sim.at(REPAIR, move |sim| {
        sim.set_port_latency(port, Duration::ZERO)
    });
    stop_sync(&mut net, STOP);
    net.sim.run_until(END);
    let app = &net.station(MASTER).machine.b;
    let mut losing = 0;
    for s in 2..=SLAVES + 1 {
        let key = StreamKey::Node(NodeId::must(s));
        let bound = bindings.borrow()[&(MASTER, key)];
        let lost = if bound == Some(bus) && lag > TIMEOUT {
            rule_loss(&net, MASTER, key, bus, FAULT)
        } else {
            vec![]
        };
        losing += usize::from(!lost.is_empty());
        let sender = &net.station(s).machine.b;
        let want: Vec<u32> = (0..sender.sent_counter)
            .filter(|c| {
                !lost.iter().any(|f| {
                    f.id() == Id::Standard(0x180 + s as u16) && f.data() == c.to_le_bytes()
                })
            })
            .collect();
        assert_eq!(app.counters_from(s), want, "from {s}");
    }
    net.assert_no_heartbeat_lost();
    (net, losing)
}

/// 25 ms late: with the stream's 10 ms period, the bound port is never silent for the
/// timeout.
#[test]
fn a_late_reader_below_the_timeout_costs_nothing() {
    for bus in [0, 1] {
        let (net, losing) = late_reader(bus, Duration::from_millis(25));
        assert_eq!(losing, 0);
        net.assert_application_exact_at(MASTER);
    }
}

#[test]
fn a_late_reader_beyond_the_timeout_loses_only_at_the_switch() {
    let (net, losing) = late_reader(0, Duration::from_millis(100));
    assert_eq!(
        losing, SLAVES as usize,
        "every stream was on bus 1 and switched"
    );
    let sticky = net.station(MASTER).link.sticky().unwrap().stats();
    assert!(sticky.switches >= SLAVES as u64);
    // The same reader on bus 2, which carried no stream: nothing happens.
    let (net, losing) = late_reader(1, Duration::from_millis(100));
    assert_eq!(losing, 0);
    net.assert_application_exact_at(MASTER);
}

/// A port without receive timestamps whose frames come 30 ms late (its stamps lag by that
/// much, below the timeout), the whole run: every stream stays on the other bus, nothing is
/// lost or doubled.
#[test]
fn a_bus_lagging_below_the_timeout_without_timestamps_costs_nothing() {
    for bus in [0, 1] {
        let mut net = network(3, SLAVES, config(), STOP);
        let port = net.dev(MASTER).port(bus);
        net.sim.set_port_stamps(port, false);
        net.sim.set_port_latency(port, Duration::from_millis(30));
        stop_sync(&mut net, STOP);
        net.sim.run_until(END);
        net.assert_application_exact_at(MASTER);
        net.assert_no_heartbeat_lost();
        let link = &net.station(MASTER).link;
        for s in 2..=SLAVES + 1 {
            let key = StreamKey::Node(NodeId::must(s));
            assert_eq!(link.sticky().unwrap().bound(key), Some(1 - bus));
        }
    }
}

/// The policy is the active-active mode's: the other modes keep the exact merge for what they
/// merge. Under it the transmit-stall rule waits the timeout; a timeout below the skew window
/// is the skew window.
#[test]
fn the_sticky_merge_is_the_active_active_modes_only() {
    use duocan_redundancy::{Cia3026Config, DualBus, EcssConfig, LinkMode};
    let sticky = config();
    assert_eq!(DualBusConfig::default().merge, MergePolicy::Exact);
    let l = DualBus::new(sticky);
    assert_eq!(l.sticky().unwrap().timeout(), TIMEOUT);
    assert_eq!(l.health().config().tx_stall, TIMEOUT);
    assert_eq!(sticky.health.tx_stall, Duration::from_micros(3_000));
    for mode in [
        LinkMode::Cia302_6(Cia3026Config::default()),
        LinkMode::EcssToggle(EcssConfig::master()),
    ] {
        let l = DualBus::new(sticky.with_mode(mode));
        assert!(l.sticky().is_none(), "{mode:?}");
    }
    let short = sticky.with_merge(MergePolicy::Sticky {
        timeout: Duration::from_millis(1),
    });
    let l = DualBus::new(short);
    assert_eq!(l.sticky().unwrap().timeout(), short.skew_window);
}
