//! A dual-bus network on the simulator: stations made of a [`DualBus`] link and a standard
//! [`Node`] paired with a small cyclic application, and helpers to read what happened.
#![allow(dead_code)]

use duocan::machine::{Composite, CompositeEvent, StationEvent};
use duocan::node::NodeEventKind;
use duocan::od::{comm, DynamicDictionary};
use duocan::sim::{BusConfig, BusId, DevId, SimNetwork, TraceRecord, TxOutcome, TxRecord};
use duocan::{Duration, Frame, Id, Instant, Machine, Node, NodeConfig, NodeEvent, NodeId, Station};
use duocan_redundancy::{DualBus, DualBusConfig, LinkEvent, LinkEventKind, PortReason, PortState};
use std::collections::VecDeque;

pub use super::app_station::{AppStation, WideTpdo1};

/// The application of every station: every `period`, TPDO1 (0x180 + id) with a counter and
/// TPDO2 (0x280 + id) with a constant payload (the same frame again and again, a legitimate
/// repeat); records every such frame of the others.
pub struct App {
    pub id: u8,
    pub period: Duration,
    next: Instant,
    pub stop_at: Instant,
    pub sent_counter: u32,
    pub sent_const: u32,
    pub received: Vec<(Instant, Frame)>,
    out: VecDeque<Frame>,
}

impl App {
    pub fn new(id: u8, start: Instant, period: Duration, stop_at: Instant) -> Self {
        App {
            id,
            period,
            next: start,
            stop_at,
            sent_counter: 0,
            sent_const: 0,
            received: vec![],
            out: VecDeque::new(),
        }
    }
    /// TPDO1 counters received from `sender`, in order.
    pub fn counters_from(&self, sender: u8) -> Vec<u32> {
        self.received
            .iter()
            .filter(|(_, f)| f.id() == Id::Standard(0x180 + sender as u16))
            .map(|(_, f)| u32::from_le_bytes(f.data().try_into().unwrap()))
            .collect()
    }
    /// TPDO2 frames received from `sender`.
    pub fn constants_from(&self, sender: u8) -> usize {
        self.received
            .iter()
            .filter(|(_, f)| f.id() == Id::Standard(0x280 + sender as u16))
            .count()
    }
}

impl Machine for App {
    type Event = ();
    type LinkCommand = std::convert::Infallible;
    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        let raw = frame.id().raw();
        if (0x181..=0x1FF).contains(&raw) || (0x281..=0x2FF).contains(&raw) {
            self.received.push((now, *frame));
        }
    }
    fn handle_timeout(&mut self, now: Instant) {
        while self.next <= now && self.next < self.stop_at {
            let id = self.id as u16;
            self.out.push_back(Frame::from_array(
                Id::Standard(0x180 + id),
                self.sent_counter.to_le_bytes(),
            ));
            self.out
                .push_back(Frame::from_array(Id::Standard(0x280 + id), [self.id, 0xAA]));
            self.sent_counter += 1;
            self.sent_const += 1;
            self.next += self.period;
        }
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        self.out.pop_front()
    }
    fn poll_timeout(&self) -> Option<Instant> {
        (self.next < self.stop_at).then_some(self.next)
    }
    fn poll_event(&mut self) -> Option<()> {
        None
    }
}

pub type Machines = Composite<Node<DynamicDictionary>, App>;
pub type Dev = AppStation;
pub type Ev = StationEvent<LinkEvent, CompositeEvent<NodeEvent, ()>>;

pub const MASTER: u8 = 1;
/// Heartbeat period of every node; the health and reachability timing derives from it.
pub const HB_MS: u16 = 50;

pub struct Net {
    pub sim: SimNetwork,
    pub buses: [BusId; 2],
    /// Index i holds node-ID i + 1 (the master first).
    pub devs: Vec<DevId<Dev>>,
}

impl Net {
    pub fn dev(&self, node: u8) -> DevId<Dev> {
        self.devs[node as usize - 1]
    }
    pub fn station(&self, node: u8) -> &Dev {
        self.sim.device(self.dev(node))
    }
    pub fn link_events(&self, node: u8) -> Vec<LinkEvent> {
        self.sim
            .events(self.dev(node))
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Link(l) => Some(*l),
                _ => None,
            })
            .collect()
    }
    pub fn node_events(&self, node: u8) -> Vec<NodeEvent> {
        self.sim
            .events(self.dev(node))
            .iter()
            .filter_map(|(_, e)| match e {
                StationEvent::Machine(CompositeEvent::A(n)) => Some(*n),
                _ => None,
            })
            .collect()
    }
    /// (time, from, to, reason) of every state change of `port` at `node`.
    pub fn port_events(
        &self,
        node: u8,
        port: u8,
    ) -> Vec<(Instant, PortState, PortState, PortReason)> {
        self.link_events(node)
            .into_iter()
            .filter_map(|e| match e.kind {
                LinkEventKind::Port {
                    port: p,
                    from,
                    to,
                    reason,
                } if p == port => Some((e.at, from, to, reason)),
                _ => None,
            })
            .collect()
    }
    /// (time, heard) of every reachability report of `about` at `node`.
    pub fn reach_events(&self, node: u8, about: u8) -> Vec<(Instant, [bool; 2])> {
        self.link_events(node)
            .into_iter()
            .filter_map(|e| match e.kind {
                LinkEventKind::Reach { node: n, heard } if n.raw() == about => Some((e.at, heard)),
                _ => None,
            })
            .collect()
    }
    /// The end of the last frame delivered on `bus` to `node` (sent by someone else) up to `t`:
    /// the instant the node last received on that bus.
    pub fn last_rx(&self, node: u8, bus: usize, t: Instant) -> Instant {
        let me = self.dev(node).erased();
        self.sim
            .trace()
            .iter()
            .filter_map(|r| match r {
                TraceRecord::Tx(x)
                    if x.bus == self.buses[bus]
                        && x.sender.device != me
                        && x.end <= t
                        && matches!(x.outcome, TxOutcome::Delivered { .. }) =>
                {
                    Some(x.end)
                }
                _ => None,
            })
            .max()
            .expect("something was received")
    }
    /// The end of the last frame on `bus` up to `t` that `node` received or sent (delivered:
    /// its driver confirmed it): the last sign, at that node, that its bus worked.
    pub fn last_heard(&self, node: u8, bus: usize, t: Instant) -> Instant {
        self.sim
            .trace()
            .iter()
            .filter_map(|r| match r {
                TraceRecord::Tx(x)
                    if x.bus == self.buses[bus]
                        && !x.babble
                        && x.end <= t
                        && matches!(x.outcome, TxOutcome::Delivered { .. }) =>
                {
                    Some(x.end)
                }
                _ => None,
            })
            .max()
            .unwrap_or(self.last_rx(node, bus, t))
    }
    /// `node`'s own frames delivered on `bus` (not a babbling controller's), in time order.
    fn delivered_by(&self, node: u8, bus: usize) -> impl Iterator<Item = &TxRecord> + '_ {
        let me = self.dev(node).erased();
        let bus = self.buses[bus];
        self.sim.trace().iter().filter_map(move |r| match r {
            TraceRecord::Tx(x)
                if x.bus == bus
                    && x.sender.device == me
                    && !x.babble
                    && matches!(x.outcome, TxOutcome::Delivered { .. }) =>
            {
                Some(x)
            }
            _ => None,
        })
    }
    /// Ends of `node`'s frames delivered on `bus` that started at or after `t`.
    pub fn sent_from(&self, node: u8, bus: usize, t: Instant) -> Vec<Instant> {
        self.delivered_by(node, bus)
            .filter(|x| x.start >= t)
            .map(|x| x.end)
            .collect()
    }
    /// The end of the last frame `node` got onto `bus` up to `t`.
    pub fn last_tx(&self, node: u8, bus: usize, t: Instant) -> Instant {
        self.delivered_by(node, bus)
            .map(|x| x.end)
            .filter(|end| *end <= t)
            .max()
            .expect("something was sent")
    }

    /// Every transmission attempt on `bus`: (end, sender node-ID, frame, outcome).
    pub fn wire(&self, bus: usize) -> Vec<(Instant, u8, Frame, TxOutcome)> {
        self.sim
            .trace()
            .iter()
            .filter_map(|r| match r {
                TraceRecord::Tx(x) if x.bus == self.buses[bus] && !x.babble => {
                    Some((x.end, x.sender.device.index() as u8 + 1, x.frame, x.outcome))
                }
                _ => None,
            })
            .collect()
    }

    /// Every slave received every SYNC the master produced, exactly once; how many it produced
    /// (for the caller's check that SYNC ran).
    pub fn assert_sync_exact(&self) -> usize {
        let mut produced = 0;
        for r in 2..=self.devs.len() as u8 {
            let (p, received) = sync_counts(self, r);
            assert_eq!(received, p, "SYNC at node {r}");
            produced = p;
        }
        produced
    }

    /// Every station received every other station's application frames exactly once, in order.
    pub fn assert_application_exact(&self) {
        for r in 1..=self.devs.len() as u8 {
            self.assert_application_exact_at(r);
        }
    }

    /// Station `r` received every other station's application frames exactly once, in order.
    pub fn assert_application_exact_at(&self, r: u8) {
        let n = self.devs.len() as u8;
        let app = &self.station(r).machine.b;
        for s in (1..=n).filter(|s| *s != r) {
            let sender = &self.station(s).machine.b;
            let want: Vec<u32> = (0..sender.sent_counter).collect();
            let got = app.counters_from(s);
            assert!(
                got == want,
                "node {r} from node {s}: {} counters instead of {} (first difference at {:?})",
                got.len(),
                want.len(),
                got.iter().zip(&want).position(|(a, b)| a != b)
            );
            assert_eq!(
                app.constants_from(s),
                sender.sent_const as usize,
                "node {r}: repeated frames of node {s}"
            );
        }
    }

    /// No heartbeat consumer timed out anywhere.
    pub fn assert_no_heartbeat_lost(&self) {
        for node in 1..=self.devs.len() as u8 {
            let lost: Vec<_> = self
                .node_events(node)
                .into_iter()
                .filter(|e| matches!(e.kind, NodeEventKind::HeartbeatTimeout { .. }))
                .collect();
            assert!(lost.is_empty(), "node {node}: {lost:?}");
        }
    }
}

/// A master (node 1) and `slaves` nodes on two 1 Mbit/s buses, every station on both, each
/// running `cfg`. Everyone boots at 0; slaves beat every 50 ms; the master consumes their
/// heartbeats (150 ms) and produces SYNC every 10 ms. The applications exchange frames every
/// 10 ms from 100 ms (staggered by 300 µs per node) until `stop`.
pub fn network(seed: u64, slaves: u8, cfg: DualBusConfig, stop: Instant) -> Net {
    network_with(seed, slaves, |_| cfg, stop)
}

/// As [`network`], with a configuration per node-ID.
pub fn network_with(
    seed: u64,
    slaves: u8,
    cfg: impl Fn(u8) -> DualBusConfig,
    stop: Instant,
) -> Net {
    network_wired(seed, slaves, cfg, &[], stop)
}

/// As [`network_with`], the nodes in `crossed` cabled crossed: their port 0 (the connector
/// marked "bus 1") on bus 2 and their port 1 on bus 1, an installation error.
pub fn network_wired(
    seed: u64,
    slaves: u8,
    cfg: impl Fn(u8) -> DualBusConfig,
    crossed: &[u8],
    stop: Instant,
) -> Net {
    build(seed, slaves, cfg, crossed, None, stop)
}

/// As [`network`], on CAN FD buses (1 Mbit/s nominal, `data_bitrate` in the data phase): every
/// station's ports FD, the applications' TPDO1 sent as 64-byte FD frames (see
/// `app_station.rs`).
pub fn network_fd(
    seed: u64,
    slaves: u8,
    cfg: DualBusConfig,
    data_bitrate: u32,
    stop: Instant,
) -> Net {
    build(seed, slaves, |_| cfg, &[], Some(data_bitrate), stop)
}

/// The network of [`network_wired`], on FD buses with a data phase of `fd` if given.
fn build(
    seed: u64,
    slaves: u8,
    cfg: impl Fn(u8) -> DualBusConfig,
    crossed: &[u8],
    fd: Option<u32>,
    stop: Instant,
) -> Net {
    let mut sim = SimNetwork::new(seed);
    let bus = |name| {
        let c = BusConfig::new(name, 1_000_000);
        match fd {
            Some(data) => c.fd(data),
            None => c,
        }
    };
    let buses = [sim.add_bus(bus("can1")), sim.add_bus(bus("can2"))];
    let mut devs = vec![];
    for id in 1..=slaves + 1 {
        let nid = NodeId::must(id);
        let mut od = comm::standard_dictionary(id, comm::Identity::default());
        // The redundancy objects, whose status entries the layer keeps up to date.
        od.insert_all(&duocan_redundancy::link::config::CIA302_6_OBJECTS)
            .unwrap();
        od.insert_all(&duocan_redundancy::link::config::ECSS_OBJECTS)
            .unwrap();
        let nc = if id == MASTER {
            NodeConfig::master(nid)
        } else {
            NodeConfig::slave(nid)
        };
        let mut node = Node::new(nc, od);
        node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, HB_MS)
            .unwrap();
        if id == MASTER {
            for s in 2..=slaves + 1 {
                node.set(
                    Instant::ZERO,
                    comm::HEARTBEAT_CONSUMER,
                    s - 1,
                    ((s as u32) << 16) | (3 * HB_MS as u32),
                )
                .unwrap();
            }
            node.set(Instant::ZERO, comm::SYNC_COB_ID, 0, 0x4000_0080u32)
                .unwrap();
            node.set(Instant::ZERO, comm::SYNC_PERIOD, 0, 10_000u32)
                .unwrap();
        }
        node.boot(Instant::ZERO);
        let start = Instant::from_millis(100) + Duration::from_micros(300 * id as u64);
        let app = App::new(id, start, Duration::from_millis(10), stop);
        let mut link = DualBus::new(cfg(id));
        for p in 0..2 {
            link.set_port_fd(p, fd.is_some());
        }
        let wide = WideTpdo1 { fd: fd.is_some() };
        let station = AppStation::new(Station::new(link, Composite::new(node, app)), wide);
        let wires = if crossed.contains(&id) {
            [buses[1], buses[0]]
        } else {
            buses
        };
        devs.push(sim.add_device(format!("n{id}"), station, &wires).unwrap());
    }
    Net { sim, buses, devs }
}

/// The default active-active configuration with timing from the 50 ms heartbeat: silence limit
/// 150 ms, suspect after 50 ms, probation 50 ms.
pub fn active_active() -> DualBusConfig {
    DualBusConfig::with_guard_period(
        duocan_redundancy::LinkMode::ActiveActive,
        Duration::from_millis(HB_MS as u64),
    )
}

/// Stops the master's SYNC at `t` (so that produced and received counts can be compared).
pub fn stop_sync(net: &mut Net, t: Instant) {
    let m = net.dev(MASTER);
    net.sim.at(t, move |sim| {
        sim.device_mut(m)
            .machine
            .a
            .set(t, comm::SYNC_PERIOD, 0, 0u32)
            .unwrap();
    });
}

/// SYNC produced by the master, and received by `node`.
pub fn sync_counts(net: &Net, node: u8) -> (usize, usize) {
    let count = |n, produced| {
        net.node_events(n)
            .iter()
            .filter(|e| matches!(e.kind, NodeEventKind::Sync { produced: p, .. } if p == produced))
            .count()
    };
    (count(MASTER, true), count(node, false))
}
