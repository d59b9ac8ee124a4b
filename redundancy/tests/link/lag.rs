//! A bus that lags: the master's port on bus 2 hands it every frame a fixed time late (the
//! simulator's per-port latency), a slave sends a cyclic TPDO with a counter and an unchanged
//! one every 20 ms for 10 s, and a heartbeat every 50 ms.
//!
//! Without lag handling every cyclic frame reached the application twice once the lag passed the
//! 10 ms skew window, with nothing reported. Now, for each lag of 12 / 15 / 25 / 40 ms:
//!
//! - the lag is detected at the second twin that shows it: the slave's boot-up is the first, its
//!   first heartbeat (pre-operational, 50.117 ms on the wire) the second, so at 50.117 ms + the lag, exactly;
//! - those two frames, and only they, reach the application twice (they came before the lag was
//!   known, and a twin that late looks like a new frame until two show it); nothing after;
//! - nothing is lost, every counter arrives once and in order;
//! - the lag is reported with its figure and the merge window that follows it (skew window +
//!   lag); 40 ms is beyond the maximum window (40 ms: a lag up to 30 ms fits): bus 2 is suspect,
//!   and its frames only match twins.

use super::sim::{App, Dev, Net, HB_MS, MASTER};
use duocan::machine::Composite;
use duocan::od::comm;
use duocan::sim::{BusConfig, SimNetwork, TxOutcome};
use duocan::{Duration, Frame, Id, Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEventKind, LinkMode, PortReason, PortState};

const SLAVE: u8 = 2;
const PERIOD: Duration = Duration::from_millis(20);
const START: Instant = Instant::from_millis(100);
const STOP: Instant = Instant::from_millis(10_100);
const END: Instant = Instant::from_millis(10_300);

fn ms(x: u64) -> Duration {
    Duration::from_millis(x)
}

/// The default active-active timing for a 50 ms heartbeat: skew window 10 ms, maximum 40 ms,
/// silence limit (and lag period) 150 ms.
fn config() -> DualBusConfig {
    DualBusConfig::with_guard_period(LinkMode::ActiveActive, ms(HB_MS as u64))
}

/// The master (node 1) and the slave (node 2) on two 1 Mbit/s buses; the master's port on bus
/// 2 lags by `lag`.
fn rig(lag: Duration) -> Net {
    let mut sim = SimNetwork::new(1);
    let buses = [
        sim.add_bus(BusConfig::new("can1", 1_000_000)),
        sim.add_bus(BusConfig::new("can2", 1_000_000)),
    ];
    let mut devs = vec![];
    for id in [MASTER, SLAVE] {
        let nid = NodeId::must(id);
        let od = comm::standard_dictionary(id, comm::Identity::default());
        let nc = if id == MASTER {
            NodeConfig::master(nid)
        } else {
            NodeConfig::slave(nid)
        };
        let mut node = Node::new(nc, od);
        node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, HB_MS)
            .unwrap();
        node.boot(Instant::ZERO);
        let app = App::new(id, START, PERIOD, STOP);
        let station: Dev = Station::new(DualBus::new(config()), Composite::new(node, app));
        devs.push(sim.add_device(format!("n{id}"), station, &buses).unwrap());
    }
    sim.set_port_latency(devs[0].port(1), lag);
    Net { sim, buses, devs }
}

impl Net {
    /// The end of the slave's transmissions of `frame` on `bus` that reached the master.
    fn slave_frames(&self, bus: usize) -> Vec<(Instant, Frame)> {
        self.wire(bus)
            .into_iter()
            .filter(|(_, s, _, o)| *s == SLAVE && matches!(o, TxOutcome::Delivered { .. }))
            .map(|(t, _, f, _)| (t, f))
            .collect()
    }
    /// The master's lag reports: (instant, port, lag, window), and its port events.
    fn lag_events(&self) -> Vec<(Instant, LinkEventKind)> {
        self.link_events(MASTER)
            .into_iter()
            .filter(|e| {
                matches!(
                    e.kind,
                    LinkEventKind::Lag { .. }
                        | LinkEventKind::LagCleared { .. }
                        | LinkEventKind::Port { .. }
                )
            })
            .map(|e| (e.at, e.kind))
            .collect()
    }
    fn master_link(&self) -> &DualBus {
        &self.station(MASTER).link
    }
}

/// The slave's application frames reached the master's application exactly once, in order.
fn assert_exact(net: &Net) {
    let app = &net.station(MASTER).machine.b;
    let sent = net.station(SLAVE).machine.b.sent_counter;
    assert_eq!(sent, 500);
    assert_eq!(app.counters_from(SLAVE), (0..sent).collect::<Vec<_>>());
    assert_eq!(app.constants_from(SLAVE), 500);
}

fn lagging_bus_2(lag_ms: u64) {
    let lag = ms(lag_ms);
    let mut net = rig(lag);
    let on_bus_2 = |net: &Net| net.slave_frames(1);
    // Up to just before detection: the boot-up and the first heartbeat have slipped.
    net.sim.run_until(Instant::from_millis(50) + lag);
    let frames = on_bus_2(&net);
    let boot = Frame::from_array(Id::Standard(0x702), [0]);
    let hb = Frame::from_array(Id::Standard(0x702), [0x7F]);
    assert_eq!((frames[0].1, frames[1].1), (boot, hb));
    let detected = frames[1].0 + lag;
    assert_eq!(detected, Instant::from_micros(50_117) + lag);
    assert_eq!(net.master_link().merger().stats().slipped, 1);
    net.sim.run_until(END);

    assert_exact(&net);
    let link = net.master_link();
    let merged = link.merger().stats();
    assert_eq!(
        merged.slipped, 2,
        "the boot-up and the first heartbeat, no more"
    );
    // Everything the slave got onto bus 1 reached the master's stack once, those two twice.
    let sent = net.slave_frames(0).len() as u64;
    assert_eq!(sent, on_bus_2(&net).len() as u64);
    assert_eq!(link.stats().delivered, sent + 2);
    assert_eq!(merged.evicted, 0);

    // Reported at the detection, with its figure; nothing else but the distrust beyond the
    // maximum window (the lag of each twin is exact here: the latency is fixed).
    let window = ms(10) + lag;
    let mut want = vec![(
        detected,
        LinkEventKind::Lag {
            port: 1,
            lag,
            window,
        },
    )];
    if lag_ms + 10 > 40 {
        want.push((
            detected,
            LinkEventKind::Port {
                port: 1,
                from: PortState::Ok,
                to: PortState::Suspect,
                reason: PortReason::Lag { lag },
            },
        ));
    }
    assert_eq!(net.lag_events(), want);
    assert_eq!(link.lag().lag(1), lag);
    assert_eq!(link.merger().window(), window);
    let (p0, p1) = (link.port(0).counters(), link.port(1).counters());
    if lag_ms + 10 > 40 {
        // Distrusted: every frame on bus 2 after the detection was a twin.
        assert!(link.lag().distrusted(1));
        assert_eq!(link.port_state(1), PortState::Suspect);
        assert_eq!(p1.untrusted, 0);
        assert_eq!(p1.delivered, 2);
    } else {
        assert_eq!(link.port_state(1), PortState::Ok);
        assert_eq!((p0.delivered, p1.delivered), (sent, 2));
    }
}

#[test]
fn bus_2_lagging_12_ms_is_measured_and_nothing_comes_twice_after_the_detection() {
    lagging_bus_2(12);
}

#[test]
fn bus_2_lagging_15_ms_is_measured_and_nothing_comes_twice_after_the_detection() {
    lagging_bus_2(15);
}

#[test]
fn bus_2_lagging_25_ms_is_measured_and_nothing_comes_twice_after_the_detection() {
    lagging_bus_2(25);
}

#[test]
fn bus_2_lagging_40_ms_is_distrusted_and_nothing_comes_twice_after_the_detection() {
    lagging_bus_2(40);
}

/// Bus 2 lags 40 ms (distrusted); at 5 s the master's bus-1 port is unplugged: bus 2 is all it
/// has. Every frame the slave sends after its last one on bus 1 is delivered from bus 2, exactly
/// 40 ms after it ended on the wire; none twice, none lost.
#[test]
fn when_the_good_bus_dies_the_lagging_one_delivers_everything_after_its_last_frame() {
    const CUT: Instant = Instant::from_millis(5_003);
    let mut net = rig(ms(40));
    let port = net.dev(MASTER).port(0);
    net.sim.at(CUT, move |sim| sim.disconnect(port));
    net.sim.run_until(END);

    assert_exact(&net);
    let last_on_bus_1 = net.last_rx(MASTER, 0, END);
    assert!(last_on_bus_1 < CUT && last_on_bus_1 > CUT - PERIOD);
    // Counters the master got after the cut: each one 40 ms after its end on bus 2.
    let ends: Vec<(Instant, Frame)> = net.slave_frames(1);
    let app = &net.station(MASTER).machine.b;
    let after: Vec<_> = app.received.iter().filter(|(t, _)| *t > CUT).collect();
    assert!(after.len() > 480, "{}", after.len());
    for (t, f) in after {
        let end = ends
            .iter()
            .find(|(e, g)| g == f && *e + ms(40) == *t)
            .map(|(e, _)| *e);
        assert!(end.is_some_and(|e| e > last_on_bus_1), "{t} {f}");
    }
    // Bus 1 failed by silence; bus 2 still lags, but it is the only bus.
    let link = net.master_link();
    assert_eq!(link.port_state(0), PortState::Failed);
    assert_eq!(link.merger().stats().slipped, 2);
}

/// Bus 2 lags 40 ms until 5 s, then not at all: the frames on their way keep their order, the
/// lag is forgotten at the end of the period after the last sample that showed it (periods of
/// 150 ms, the silence limit), and bus 2 is trusted again. Nothing twice, nothing lost.
#[test]
fn a_lag_that_goes_away_is_forgotten_and_the_bus_trusted_again() {
    const BACK: Instant = Instant::from_millis(5_000);
    let mut net = rig(ms(40));
    let port = net.dev(MASTER).port(1);
    net.sim
        .at(BACK, move |sim| sim.set_port_latency(port, Duration::ZERO));
    net.sim.run_until(END);

    assert_exact(&net);
    let link = net.master_link();
    assert_eq!(link.merger().stats().slipped, 2);
    assert!(!link.lag().distrusted(1));
    assert_eq!(link.port_state(1), PortState::Ok);
    // The last twin 40 ms late is the copy of the last frame that ended before 5 s; the queue
    // behind it drains at once. Its period ends at 5.1 s; cleared at the end of the next one.
    let last = net
        .slave_frames(1)
        .into_iter()
        .rfind(|(t, _)| *t < BACK)
        .unwrap()
        .0;
    assert!(last > Instant::from_millis(4_980), "{last}");
    let cleared = Instant::from_millis(5_250);
    let ev = net.lag_events();
    assert_eq!(
        ev[2..],
        [
            (cleared, LinkEventKind::LagCleared { port: 1 }),
            (
                cleared,
                LinkEventKind::Port {
                    port: 1,
                    from: PortState::Suspect,
                    to: PortState::Ok,
                    reason: PortReason::LagWithin {
                        lag: Duration::ZERO
                    }
                }
            ),
        ]
    );
    assert_eq!(link.merger().window(), ms(10));
}

/// Bus 2 lags 12 ms, then from 5 s 40 ms: known to lag, it matches its late twins at once (no
/// duplicate at the step), and it is distrusted at the second twin 40 ms late.
#[test]
fn a_lag_that_grows_beyond_the_maximum_costs_no_duplicate() {
    const STEP: Instant = Instant::from_millis(5_000);
    let mut net = rig(ms(12));
    let port = net.dev(MASTER).port(1);
    net.sim
        .at(STEP, move |sim| sim.set_port_latency(port, ms(40)));
    net.sim.run_until(END);

    assert_exact(&net);
    let link = net.master_link();
    assert_eq!(
        link.merger().stats().slipped,
        2,
        "the two at the start only"
    );
    let ev = net.lag_events();
    assert_eq!(ev.len(), 3, "{ev:?}");
    let (t, kind) = ev[1];
    assert!(t > STEP + ms(40) && t < STEP + ms(40) + PERIOD, "{t}");
    assert_eq!(
        kind,
        LinkEventKind::Lag {
            port: 1,
            lag: ms(40),
            window: ms(50)
        }
    );
    assert_eq!(
        ev[2],
        (
            t,
            LinkEventKind::Port {
                port: 1,
                from: PortState::Ok,
                to: PortState::Suspect,
                reason: PortReason::Lag { lag: ms(40) }
            }
        )
    );
}
