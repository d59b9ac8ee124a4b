//! The fault bridge: real interfaces joined into logical buses, with the simulator's faults in
//! between, so that devices that are not duocan's can be failover-tested on dual vcan.
//!
//! A [`Bridge`] is a [`Device`] with one port per *member* (an interface: the master's bus-1
//! port, each board's bus-1 port, …). Members are grouped into buses; every frame received on a
//! member is sent on every other member of its bus, and on nothing else. Between the two, the
//! faults of [`crate::sim`] apply under the same names: [`Bridge::bus_down`],
//! [`Bridge::disconnect`], [`Bridge::partition`], [`Bridge::set_bus_faults`],
//! [`Bridge::set_port_faults`] (drop, duplicate, delay, corrupt), [`Bridge::set_port_latency`],
//! [`Bridge::babble`]; plus [`Bridge::drop_every`] for a deterministic "every n-th frame".
//!
//! **The rule.** A frame from member `s` of bus `b` reaches member `d` of `b` (`d ≠ s`) unless
//! `b` is down, `s` or `d` is disconnected, or they are in different partition groups; then the
//! bus's faults are decided once for the frame (every receiver sees the same outcome: a dropped
//! or corrupted frame is lost for all, as an error frame destroys it on a real bus), then the
//! receiving member's own faults (drop, corrupt, duplicate, random delay, fixed latency).
//! A *detected* corruption is what a receiver's CRC check would catch: the frame is dropped, as
//! a controller drops it, and counted; an *undetected* one flips a data bit and delivers.
//!
//! **Order.** Frames to one member leave in the order the bridge received them, whatever their
//! delays: a frame's release time is never earlier than that of the frame before it to the same
//! member (a delayed frame holds the later ones back, as a gateway queue would).
//!
//! **Memory.** Each member's queue holds at most [`BridgeConfig::queue`] frames; a frame that
//! finds it full is counted in [`MemberCounters::overflow`] and dropped — the one drop the
//! bridge was not told to make, reported as such. Members are at most [`MAX_MEMBERS`].
//!
//! **Time is an input**: [`Bridge::now`] is the latest instant it was given. Under the runtime
//! the clock is real; in tests it is whatever the test says.
//!
//! ```
//! use duocan::bridge::{Bridge, BridgeConfig};
//! use duocan::machine::Device;
//! use duocan::{Duration, Frame, Id, Instant};
//!
//! // Bus 1 joins the master's port (member 0) and two boards' ports (1, 2).
//! let mut b = Bridge::new(BridgeConfig::new(&[&["vm1a", "vs1a", "vs1b"]])).unwrap();
//! let hb = Frame::from_array(Id::Standard(0x701), [0x05]);
//! b.handle_rx(Instant::ZERO, 0, &hb);
//! assert_eq!(b.poll_transmit(), Some((1, hb)));
//! assert_eq!(b.poll_transmit(), Some((2, hb)));
//! assert_eq!(b.poll_transmit(), None);
//!
//! // A fixed 2 ms latency to board 1: the frame waits for its time.
//! b.set_port_latency(1, Duration::from_millis(2));
//! b.handle_rx(Instant::ZERO, 0, &hb);
//! assert_eq!(b.poll_transmit(), Some((2, hb)));
//! assert_eq!(b.poll_transmit(), None);
//! assert_eq!(b.poll_timeout(), Some(Instant::from_millis(2)));
//! b.handle_timeout(Instant::from_millis(2));
//! assert_eq!(b.poll_transmit(), Some((1, hb)));
//! ```

mod faults;
#[cfg(test)]
mod tests;

pub use faults::MemberCounters;

use crate::frame::instant::{earliest_of, Duration, Instant};
use crate::frame::Frame;
use crate::machine::{Device, PortStatus};
use crate::sim::FaultRates;
use alloc::collections::VecDeque;
use alloc::string::String;
use alloc::vec::Vec;
use core::convert::Infallible;
use faults::Odds;

/// The most members one bridge joins (every bus together).
pub const MAX_MEMBERS: usize = 32;
/// Frames one member's queue holds unless configured otherwise: well beyond what a saturated
/// 1 Mbit/s bus delivers within a 100 ms delay.
pub const DEFAULT_QUEUE: usize = 4096;
/// The shortest babble period (a babbler faster than this would starve the bridge itself).
pub const MIN_BABBLE_PERIOD: Duration = Duration::from_micros(50);

/// What a bridge joins: the buses, each a list of member names, and its queue size and seed.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct BridgeConfig {
    /// The buses: member names (interface names), in port order across buses.
    pub buses: Vec<Vec<String>>,
    /// Frames each member's queue holds.
    pub queue: usize,
    /// Seed of the random faults (the same seed, the same decisions for the same frames).
    pub seed: u64,
}

impl BridgeConfig {
    /// The buses `buses`, each a list of member names; default queue, seed 0.
    #[must_use]
    pub fn new(buses: &[&[&str]]) -> Self {
        BridgeConfig {
            buses: buses
                .iter()
                .map(|b| b.iter().map(|m| String::from(*m)).collect())
                .collect(),
            queue: DEFAULT_QUEUE,
            seed: 0,
        }
    }
    /// With `queue` frames per member queue.
    #[must_use]
    pub fn with_queue(mut self, queue: usize) -> Self {
        self.queue = queue;
        self
    }
    /// With the random faults seeded by `seed`.
    #[must_use]
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }
}

/// Why a [`BridgeConfig`] cannot be bridged.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum BridgeError {
    /// More than [`MAX_MEMBERS`] members, or a bus with fewer than two.
    Members(String),
    /// Two members share a name.
    Duplicate(String),
    /// A queue of zero frames.
    Queue,
}

impl core::fmt::Display for BridgeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BridgeError::Members(why) => f.write_str(why),
            BridgeError::Duplicate(name) => write!(f, "{name:?} is a member twice"),
            BridgeError::Queue => f.write_str("a member queue must hold at least one frame"),
        }
    }
}

impl core::error::Error for BridgeError {}

/// One member: an interface on one bus, and what is waiting for it.
struct Member {
    name: String,
    bus: usize,
    connected: bool,
    group: u32,
    odds: Odds,
    latency: Duration,
    /// Frames for this member with their release times, never decreasing.
    queue: VecDeque<(Instant, Frame)>,
    babble: Option<(Frame, Duration, Instant)>,
    counters: MemberCounters,
}

/// One bus: its members' ports, whether it is up, its own faults.
struct Bus {
    members: Vec<usize>,
    up: bool,
    odds: Odds,
    counters: MemberCounters,
}

/// The fault bridge (see the [module docs](self)).
pub struct Bridge {
    members: Vec<Member>,
    buses: Vec<Bus>,
    queue: usize,
    rng: fastrand::Rng,
    now: Instant,
    /// Where the next `poll_transmit` starts looking (fairness across members).
    cursor: usize,
}

impl Bridge {
    /// A bridge over `cfg`'s buses, no fault set.
    pub fn new(cfg: BridgeConfig) -> Result<Bridge, BridgeError> {
        if cfg.queue == 0 {
            return Err(BridgeError::Queue);
        }
        let total: usize = cfg.buses.iter().map(Vec::len).sum();
        if total > MAX_MEMBERS {
            return Err(BridgeError::Members(alloc::format!(
                "{total} members: a bridge joins at most {MAX_MEMBERS}"
            )));
        }
        let mut members: Vec<Member> = Vec::with_capacity(total);
        let mut buses = Vec::with_capacity(cfg.buses.len());
        for (b, names) in cfg.buses.iter().enumerate() {
            if names.len() < 2 {
                return Err(BridgeError::Members(alloc::format!(
                    "bus {} has {} member(s): a bus joins at least two",
                    b + 1,
                    names.len()
                )));
            }
            let mut ids = Vec::new();
            for name in names {
                if members.iter().any(|m| &m.name == name) {
                    return Err(BridgeError::Duplicate(name.clone()));
                }
                ids.push(members.len());
                members.push(Member {
                    name: name.clone(),
                    bus: b,
                    connected: true,
                    group: 0,
                    odds: Odds::default(),
                    latency: Duration::ZERO,
                    queue: VecDeque::new(),
                    babble: None,
                    counters: MemberCounters::default(),
                });
            }
            buses.push(Bus {
                members: ids,
                up: true,
                odds: Odds::default(),
                counters: MemberCounters::default(),
            });
        }
        Ok(Bridge {
            members,
            buses,
            queue: cfg.queue,
            rng: fastrand::Rng::with_seed(cfg.seed),
            now: Instant::ZERO,
            cursor: 0,
        })
    }

    /// The latest instant the bridge was given.
    #[must_use]
    pub fn now(&self) -> Instant {
        self.now
    }
    /// The member (port index) named `name`.
    #[must_use]
    pub fn member(&self, name: &str) -> Option<usize> {
        self.members.iter().position(|m| m.name == name)
    }
    /// The name of member `m`.
    #[must_use]
    pub fn member_name(&self, m: usize) -> Option<&str> {
        self.members.get(m).map(|m| m.name.as_str())
    }
    /// The bus of member `m`.
    #[must_use]
    pub fn bus_of(&self, m: usize) -> Option<usize> {
        self.members.get(m).map(|m| m.bus)
    }
    /// Number of buses.
    #[must_use]
    pub fn bus_count(&self) -> usize {
        self.buses.len()
    }
    /// What happened to the frames member `m` received and was sent (faults on its receive
    /// side are counted here, bus-wide ones in [`Bridge::bus_counters`]).
    #[must_use]
    pub fn counters(&self, m: usize) -> Option<&MemberCounters> {
        self.members.get(m).map(|m| &m.counters)
    }
    /// What the bus's own faults did.
    #[must_use]
    pub fn bus_counters(&self, bus: usize) -> Option<&MemberCounters> {
        self.buses.get(bus).map(|b| &b.counters)
    }
    /// The random faults of bus `bus` as set.
    #[must_use]
    pub fn bus_faults(&self, bus: usize) -> Option<FaultRates> {
        self.buses.get(bus).map(|b| b.odds.rates)
    }
    /// The random faults of member `m`'s receive side as set.
    #[must_use]
    pub fn port_faults(&self, m: usize) -> Option<FaultRates> {
        self.members.get(m).map(|m| m.odds.rates)
    }
    /// Frames waiting for member `m`.
    #[must_use]
    pub fn queued(&self, m: usize) -> usize {
        self.members.get(m).map_or(0, |m| m.queue.len())
    }

    /// Cuts bus `bus`: it carries nothing until [`Bridge::bus_up`].
    pub fn bus_down(&mut self, bus: usize) {
        if let Some(b) = self.buses.get_mut(bus) {
            b.up = false;
        }
    }
    /// Repairs bus `bus`.
    pub fn bus_up(&mut self, bus: usize) {
        if let Some(b) = self.buses.get_mut(bus) {
            b.up = true;
        }
    }
    /// Unplugs member `m` from its bus: what it sends reaches nobody, it receives nothing.
    /// Frames already waiting for it are dropped (counted as cut).
    pub fn disconnect(&mut self, m: usize) {
        if let Some(m) = self.members.get_mut(m) {
            m.connected = false;
            m.counters.cut += m.queue.len() as u64;
            m.queue.clear();
        }
    }
    /// Plugs member `m` back in (into its partition group).
    pub fn reconnect(&mut self, m: usize) {
        if let Some(m) = self.members.get_mut(m) {
            m.connected = true;
        }
    }
    /// Splits bus `bus`: each listed group of members hears only its own group; members not
    /// listed form one more group. Members of other buses in a group are ignored.
    pub fn partition(&mut self, bus: usize, groups: &[&[usize]]) {
        let Some(b) = self.buses.get(bus) else { return };
        for &m in &b.members {
            self.members[m].group = 0;
        }
        for (g, group) in groups.iter().enumerate() {
            for &m in group.iter() {
                if self.members.get(m).is_some_and(|x| x.bus == bus) {
                    self.members[m].group = g as u32 + 1;
                }
            }
        }
    }
    /// Joins every partition group of bus `bus` again.
    pub fn heal(&mut self, bus: usize) {
        self.partition(bus, &[]);
    }
    /// The random faults of bus `bus`, decided once per frame for every receiver.
    pub fn set_bus_faults(&mut self, bus: usize, rates: FaultRates) {
        if let Some(b) = self.buses.get_mut(bus) {
            b.odds.rates = rates;
        }
    }
    /// The random faults of member `m`'s receive side.
    pub fn set_port_faults(&mut self, m: usize, rates: FaultRates) {
        if let Some(m) = self.members.get_mut(m) {
            m.odds.rates = rates;
        }
    }
    /// Drops every `n`-th frame member `m` would receive (0: none).
    pub fn drop_every(&mut self, m: usize, n: u32) {
        if let Some(m) = self.members.get_mut(m) {
            m.odds.every = n;
            m.odds.count = 0;
        }
    }
    /// Drops every `n`-th frame on bus `bus`, for every receiver (0: none).
    pub fn drop_every_on_bus(&mut self, bus: usize, n: u32) {
        if let Some(b) = self.buses.get_mut(bus) {
            b.odds.every = n;
            b.odds.count = 0;
        }
    }
    /// A fixed latency for every frame member `m` receives (zero removes it).
    pub fn set_port_latency(&mut self, m: usize, latency: Duration) {
        if let Some(m) = self.members.get_mut(m) {
            m.latency = latency;
        }
    }
    /// Makes member `m` babble: `frame` goes to its bus as if `m` sent it, every `period`
    /// (at least [`MIN_BABBLE_PERIOD`]) from now; `None` stops it.
    pub fn babble(&mut self, m: usize, frame: Option<Frame>, period: Duration) {
        let period = if period < MIN_BABBLE_PERIOD {
            MIN_BABBLE_PERIOD
        } else {
            period
        };
        let now = self.now;
        if let Some(m) = self.members.get_mut(m) {
            m.babble = frame.map(|f| (f, period, now));
        }
    }

    /// Forwards `frame`, received on (or babbled by) member `src`, to its bus.
    fn forward(&mut self, now: Instant, src: usize, frame: &Frame) {
        let (bus, group, connected) = {
            let m = &self.members[src];
            (m.bus, m.group, m.connected)
        };
        if !connected {
            self.members[src].counters.cut += 1;
            return;
        }
        let b = &mut self.buses[bus];
        b.counters.rx += 1;
        if !b.up {
            b.counters.cut += 1;
            return;
        }
        let Some(on_bus) = b.odds.decide(&mut self.rng, frame, &mut b.counters) else {
            return;
        };
        for i in 0..self.buses[bus].members.len() {
            let d = self.buses[bus].members[i];
            if d == src {
                continue;
            }
            let m = &mut self.members[d];
            if !m.connected {
                m.counters.cut += 1;
                continue;
            }
            if m.group != group {
                m.counters.partitioned += 1;
                continue;
            }
            let Some(fate) = m.odds.decide(&mut self.rng, &on_bus.frame, &mut m.counters) else {
                continue;
            };
            let at = now + on_bus.delay + fate.delay + m.latency;
            let copies = 1 + usize::from(on_bus.twice) + usize::from(fate.twice);
            for _ in 0..copies {
                if m.queue.len() >= self.queue {
                    m.counters.overflow += 1;
                    continue;
                }
                // Never before the frame ahead of it: order is kept per member.
                let at = m.queue.back().map_or(at, |(last, _)| at.max(*last));
                m.queue.push_back((at, fate.frame));
            }
        }
    }
}

impl Device for Bridge {
    type Event = Infallible;

    fn port_count(&self) -> usize {
        self.members.len()
    }
    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) {
        self.now = self.now.max(now);
        let Some(m) = self.members.get_mut(port) else {
            return;
        };
        m.counters.rx += 1;
        self.forward(self.now, port, frame);
    }
    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.now = self.now.max(now);
        if let Some(m) = self.members.get_mut(port) {
            match status {
                PortStatus::TxFailed(_) => m.counters.tx_failed += 1,
                PortStatus::Down(_) => m.counters.port_down += 1,
                PortStatus::TxOk | PortStatus::Error(_) | PortStatus::Up => {}
            }
        }
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.now = self.now.max(now);
        for src in 0..self.members.len() {
            while let Some((frame, period, mut due)) = self.members[src].babble {
                if due > self.now {
                    break;
                }
                // A bridge that was held up does not catch up with a burst: it babbles on from
                // now (the frames it missed were never on the wire).
                if self.now - due > period.saturating_mul(16) {
                    due = self.now;
                }
                self.members[src].babble = Some((frame, period, due + period));
                self.members[src].counters.babbled += 1;
                self.forward(due, src, &frame);
            }
        }
    }
    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        let n = self.members.len();
        for k in 0..n {
            let d = (self.cursor + k) % n;
            let m = &mut self.members[d];
            if m.queue.front().is_some_and(|(at, _)| *at <= self.now) {
                let (_, f) = m.queue.pop_front()?;
                m.counters.tx += 1;
                self.cursor = (d + 1) % n;
                return Some((d, f));
            }
        }
        None
    }
    fn poll_timeout(&self) -> Option<Instant> {
        earliest_of(self.members.iter().flat_map(|m| {
            [
                m.queue.front().map(|(at, _)| *at),
                m.babble.map(|(_, _, due)| due),
            ]
        }))
    }
    fn poll_event(&mut self) -> Option<Infallible> {
        None
    }
}
