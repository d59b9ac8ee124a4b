//! The dual-bus abstraction layer: two CAN ports below, one logical bus above.
//!
//! [`DualBus`] implements [`BusLink`], so any [`Machine`](duocan_core::Machine) — a
//! [`Node`](duocan_core::Node) of the standard stack, unchanged — runs on top of it in a
//! [`Station`](duocan_core::Station). The three redundancy modes are policies behind one type, chosen
//! by [`LinkMode`] in the [`DualBusConfig`] (from code or from the dictionary, see
//! [`crate::link::config`]). Time is an input, and a clock that steps back, jumps ahead or
//! reaches `Instant::MAX` is handled as the [layer's clock contract](crate::link#the-clock-contract)
//! says. With the feature `fd`, CAN FD frames take the same paths beside the classic ones, on
//! a layer whose ports are all FD-capable (see [`fd`]).
//!
//! ```
//! use duocan_core::{Station, Node, NodeConfig, NodeId};
//! use duocan_core::od::{comm, DynamicDictionary};
//! use duocan_redundancy_core::{DualBus, DualBusConfig};
//!
//! let od = comm::standard_dictionary(5, Default::default());
//! let node = Node::new(NodeConfig::slave(NodeId::must(5)), od);
//! let station = Station::new(DualBus::new(DualBusConfig::default()), node);
//! assert_eq!(duocan_core::Device::port_count(&station), 2);
//! ```

use crate::link::capacity::{Capacity, FunctionStorage, MergeCapacity, MergerStorage};
#[cfg(feature = "cia302-6")]
use crate::link::channel::Cia3026;
#[cfg(feature = "ecss")]
use crate::link::channel::Ecss;
use crate::link::channel::{ChannelPolicy, FrameInfo, ModeKind, Policy};
use crate::link::classify::FrameClassifier;
use crate::link::config::{ConfigError, OdLayout};
pub use crate::link::config::{DualBusConfig, LinkMode, MergePolicy};
use crate::link::events::LinkEvent;
use crate::link::health::{Health, PortHealth, PortState};
use crate::link::lag::LagMeter;
use crate::link::outbox::Outbox;
use crate::link::plausible::Plausibility;
use crate::link::reach::Reach;
use crate::link::same_function::PairError;
#[cfg(feature = "sticky")]
use crate::link::sticky::StickyMerger;
use crate::pair::{Member, PairId};
use duocan_core::frame::instant::{earliest_of, TimeWatch};
#[cfg(feature = "fd")]
use duocan_core::frame::FdFrame;
use duocan_core::machine::{BusLink, LinkRequest, PortRequest, PortStatus};
use duocan_core::od::ObjectDictionary;
use duocan_core::profile::Predefined;
use duocan_core::{Duration, Frame, Instant};

pub use crate::link::capacity::DEFAULT_MERGE_SLOTS;
#[cfg(feature = "fd")]
pub use fd::FdSendError;

/// A node on a dual bus: the common redundant slave (one board of a pair), or any node that
/// needs no supervisor.
pub type DualBusNode<D, P = Predefined> = duocan_core::Station<DualBus<P>, duocan_core::Node<D, P>>;

/// What the machine above (a redundant master's supervisor) tells the layer about the pairs of
/// the same-function merge: the layer knows of pairs only what it is told.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkCommand {
    /// Deliver the process data of `member` of `pair` (`None`: neither).
    SetActive(PairId, Option<Member>),
    /// Forget a member's latest values.
    Forget(PairId, Member),
    /// Judge the heartbeats of `node`, whose producer time is `producer_ms` milliseconds (as
    /// in 0x1017), for plausibility (zero: stop; see [`crate::link::plausible`]).
    Watch {
        /// The node.
        node: duocan_core::NodeId,
        /// Its heartbeat producer time in milliseconds.
        producer_ms: u16,
    },
}

// A machine with nothing to tell the layer (a node) runs on it as well.
impl From<core::convert::Infallible> for LinkCommand {
    fn from(never: core::convert::Infallible) -> Self {
        match never {}
    }
}

/// Counters of the layer itself.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Frames received on a port index other than 0 and 1 (ignored).
    pub bad_port: u64,
    /// Frames delivered upward.
    pub delivered: u64,
    /// Standby frames of pairs kept but not delivered.
    pub standby: u64,
    /// Frames for the ports dropped because the driver did not drain them.
    pub tx_dropped: u32,
    /// Events dropped because the application did not drain them.
    pub events_dropped: u32,
    /// Requests dropped because the driver did not drain them.
    pub requests_dropped: u32,
    /// Error-control frames dropped because their bus carried the node's heartbeats far faster
    /// than its period allows ([plausibility](crate::link::plausible), rule 1).
    pub implausible: u64,
    /// Heartbeats of watched nodes the merge delivered after a newer one of the same node and
    /// not handed up ([plausibility](crate::link::plausible), "Order").
    pub superseded: u64,
    /// Watches refused because the plausibility table was full.
    pub watch_refused: u32,
    /// CAN FD frames the machine above gave to send ([`BusLink::send_fd`]) while a port was
    /// classic-only, dropped (see [`fd`]).
    #[cfg(feature = "fd")]
    pub fd_refused: u32,
}

/// The dual-bus layer. `C` classifies frames (heartbeats, senders, functions; the predefined
/// connection set by default); `K` is its capacity: the merger's slots and the room for
/// (pair, function) values of the same-function merge, part of the type so that the layer
/// needs no allocator ([`Capacity<SLOTS, FUNCTIONS>`](Capacity), the defaults unless a small
/// target sizes them to its network: see [`crate::link::capacity`]).
pub struct DualBus<C = Predefined, K: MergeCapacity = Capacity> {
    classifier: C,
    policy: Policy,
    merger: K::Merger,
    /// The sticky merge, when configured (active-active only): it judges instead of `merger`.
    #[cfg(feature = "sticky")]
    sticky: Option<StickyMerger>,
    lag: LagMeter,
    /// A late sample waiting to be measured ([`rx::LateSample`]).
    late: Option<rx::LateSample>,
    health: Health,
    /// Per port: its frames come with receive timestamps (`handle_rx_at`).
    stamped: [bool; 2],
    reach: Reach,
    reach_enabled: bool,
    plausible: Plausibility,
    pairs: K::Functions,
    out: Outbox,
    stats: LinkStats,
    /// The latest instant any method was given (hand-over time of frames for the stall rule),
    /// and the step back of the caller's clock it notices (the clock contract, see
    /// [`crate::link`]).
    clock: TimeWatch,
    layout: OdLayout,
    /// The status values last written to the node's dictionary.
    shown: Status,
    /// Per port: FD-capable, as the driver says ([`DualBus::set_port_fd`]).
    #[cfg(feature = "fd")]
    fd: [bool; 2],
}

/// The status entries of `policy`'s mode.
fn status_of(policy: &Policy) -> Status {
    match policy {
        #[cfg(feature = "cia302-6")]
        Policy::Cia302_6(c) => Status {
            counter: c.error_counter(),
            ..Status::default()
        },
        #[cfg(feature = "ecss")]
        Policy::EcssToggle(e) => Status {
            bdefault: e.bdefault(),
            ctoggle: e.ctoggle(),
            ..Status::default()
        },
        Policy::ActiveActive(_) => Status::default(),
    }
}

/// The mode's status entries, as last shown in the dictionary.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Status {
    bdefault: u8,
    ctoggle: u8,
    counter: u8,
}

impl DualBus {
    /// A layer for the predefined connection set.
    #[must_use]
    pub fn new(cfg: DualBusConfig) -> Self {
        DualBus::with_classifier(cfg, Predefined)
    }
    /// A layer for the predefined connection set, configured by a dictionary (see
    /// [`DualBusConfig::from_od`]).
    pub fn from_od<D: ObjectDictionary>(od: &D, layout: &OdLayout) -> Result<Self, ConfigError> {
        Ok(DualBus::new(DualBusConfig::from_od(od, layout)?))
    }
}

impl<C: FrameClassifier, K: MergeCapacity> DualBus<C, K> {
    /// A layer with a custom frame classifier (identifier scheme).
    #[must_use]
    pub fn with_classifier(cfg: DualBusConfig, classifier: C) -> Self {
        // Each mode and merge policy may adjust the port-health rules.
        #[cfg_attr(
            not(any(feature = "cia302-6", feature = "ecss", feature = "sticky")),
            allow(unused_mut)
        )]
        let mut health = cfg.health;
        let (policy, reach_enabled) = match cfg.mode {
            LinkMode::ActiveActive => (Policy::ActiveActive(Default::default()), true),
            #[cfg(feature = "cia302-6")]
            LinkMode::Cia302_6(c) => {
                // One channel carries the traffic: flushing it would lose frames (302-6 has
                // its own transmit-delay rule).
                health.tx_stall = Duration::ZERO;
                (Policy::Cia302_6(Cia3026::new(c)), true)
            }
            #[cfg(feature = "ecss")]
            LinkMode::EcssToggle(c) => {
                // The inactive bus is quiet by design: silence and reachability mean nothing.
                health.silence_detection = false;
                health.tx_stall = Duration::ZERO;
                (Policy::EcssToggle(Ecss::new(c)), false)
            }
        };
        #[cfg(feature = "sticky")]
        let sticky = match (cfg.mode, cfg.merge) {
            (LinkMode::ActiveActive, MergePolicy::Sticky { timeout }) => {
                // Copies stamped within the skew window are the layer's premise anyway.
                let timeout = timeout.max(cfg.skew_window);
                // A frame stalled on one port reaches the receivers late: the sticky merge
                // stands a lag up to its timeout, not more.
                if !health.tx_stall.is_zero() {
                    health.tx_stall = health.tx_stall.max(timeout);
                }
                Some(StickyMerger::new(timeout))
            }
            _ => None,
        };
        // A lag is forgotten after the silence limit: the time in which a port hears something
        // anyway.
        let lag = LagMeter::new(cfg.skew_window, cfg.max_skew_window, health.silence_limit);
        // The dictionary starts with the configured values: only changes are written.
        let shown = status_of(&policy);
        DualBus {
            classifier,
            policy,
            merger: K::Merger::with_horizon(cfg.skew_window, lag.horizon()),
            #[cfg(feature = "sticky")]
            sticky,
            lag,
            late: None,
            health: Health::new(health, cfg.skew_window),
            stamped: [true; 2],
            reach: Reach::new(cfg.reach_timeout, cfg.skew_window),
            reach_enabled,
            // Rule 2 needs both buses listened to, as reachability does.
            plausible: Plausibility::with_capacity(
                reach_enabled.then_some(cfg.reach_timeout),
                cfg.watch_capacity,
            )
            .with_frame_time(cfg.frame_time)
            .with_one_bus_members(cfg.one_bus_members),
            pairs: K::Functions::new(cfg.discrepancy_time),
            out: Outbox::new(),
            stats: LinkStats::default(),
            clock: TimeWatch::new(),
            layout: cfg.od_layout,
            shown,
            #[cfg(feature = "fd")]
            fd: [false; 2],
        }
    }

    fn status(&self) -> Status {
        status_of(&self.policy)
    }

    /// Queues a [`LinkRequest::SetStatus`] for every status value that changed.
    #[inline]
    fn show_status(&mut self) {
        // Active-active has no status entries: the frame path only tests the mode.
        if !matches!(self.policy, Policy::ActiveActive(_)) {
            self.show_mode_status();
        }
    }

    fn show_mode_status(&mut self) {
        let now = self.status();
        let (red, tog) = (self.layout.redundancy, self.layout.toggle);
        for (index, sub, old, new) in [
            (red, 5, self.shown.counter, now.counter),
            (tog, 1, self.shown.bdefault, now.bdefault),
            (tog, 4, self.shown.ctoggle, now.ctoggle),
        ] {
            if old != new {
                self.out.machine(LinkRequest::SetStatus {
                    index,
                    sub,
                    value: new,
                });
            }
        }
        self.shown = now;
    }

    /// The scheme running.
    pub fn mode(&self) -> ModeKind {
        self.policy.kind()
    }
    /// The policy, for mode-specific status (302-6 error counter, ECSS Ctoggle, …).
    pub fn policy(&self) -> &Policy {
        &self.policy
    }
    /// The CiA 302-6 policy (error counter, evaluation), in that mode.
    #[cfg(feature = "cia302-6")]
    pub fn cia302_6(&self) -> Option<&Cia3026> {
        match &self.policy {
            Policy::Cia302_6(p) => Some(p),
            _ => None,
        }
    }
    /// The ECSS policy (Bdefault, Ctoggle), in that mode.
    #[cfg(feature = "ecss")]
    pub fn ecss(&self) -> Option<&Ecss> {
        match &self.policy {
            Policy::EcssToggle(p) => Some(p),
            _ => None,
        }
    }
    /// The active channel (302-6 and ECSS); `None` in active-active mode.
    pub fn active_channel(&self) -> Option<usize> {
        self.policy.active()
    }
    /// Makes `port` the active channel by command (302-6: with the 0x7F indication). False in
    /// active-active mode.
    pub fn select_channel(&mut self, now: Instant, port: usize) -> bool {
        self.watch_clock(now);
        self.policy.select(now, port, &mut self.out)
    }
    /// Health of both ports.
    pub fn health(&self) -> &Health {
        &self.health
    }
    /// One port's health.
    pub fn port(&self, p: usize) -> &PortHealth {
        self.health.port(p)
    }
    /// One port's state.
    pub fn port_state(&self, p: usize) -> PortState {
        self.health.port(p).state()
    }
    /// The receive merger (the exact merge: idle when the sticky merge is configured).
    pub fn merger(&self) -> &K::Merger {
        &self.merger
    }
    /// The sticky merge, if configured ([`MergePolicy::Sticky`], active-active mode).
    #[cfg(feature = "sticky")]
    pub fn sticky(&self) -> Option<&StickyMerger> {
        self.sticky.as_ref()
    }
    /// Each port's measured lag and the correction the merger's stamps get.
    pub fn lag(&self) -> &LagMeter {
        &self.lag
    }
    /// Per-node, per-bus reachability.
    pub fn reach(&self) -> &Reach {
        &self.reach
    }
    /// Heartbeat plausibility of the watched nodes.
    pub fn plausibility(&self) -> &Plausibility {
        &self.plausible
    }
    /// Judges the heartbeats of `node`, whose producer time is `period`, for plausibility
    /// (zero: stop). False if the table is full (or the crate has no `alloc` feature). For the
    /// supervisor ([`LinkCommand::Watch`]).
    pub fn watch(&mut self, node: duocan_core::NodeId, period: Duration) -> bool {
        self.plausible.watch(node, period)
    }
    /// The pair table and the members' latest values.
    pub fn pairs(&self) -> &K::Functions {
        &self.pairs
    }
    /// Configures an A/B pair for the same-function merge.
    pub fn add_pair(
        &mut self,
        a: duocan_core::NodeId,
        b: duocan_core::NodeId,
        active: Option<Member>,
    ) -> Result<PairId, PairError> {
        self.pairs.add_pair(a, b, active)
    }
    /// Makes `member` the pair member whose process data is delivered (`None`: neither). For
    /// the supervisor.
    pub fn set_active(&mut self, pair: PairId, member: Option<Member>) -> bool {
        self.pairs.set_active(pair, member)
    }
    /// Forgets a member's latest values (after resetting it).
    pub fn forget_member(&mut self, pair: PairId, member: Member) {
        self.pairs.forget(pair, member);
    }
    /// The number of the logical frame the latest [`send`](BusLink::send) queued copies of
    /// (wrapping): each send takes the next number, and every copy of it has that number.
    pub fn frame_number(&self) -> u32 {
        self.out.frame_number()
    }
    /// As [`BusLink::poll_transmit`], with the number of the logical frame the copy is of (see
    /// [`frame_number`](Self::frame_number)): a copy a port's pending re-initialisation held
    /// back comes out after later frames' copies for the other port, and the number tells
    /// whose it is.
    pub fn poll_numbered(&mut self) -> Option<(usize, Frame, u32)> {
        let (p, f, n) = self.out.pop_numbered()?;
        self.health.count_tx(self.clock.latest(), p, n);
        self.plausible.on_handed(self.clock.latest(), p);
        Some((p, f, n))
    }
    /// The classifier.
    pub fn classifier(&self) -> &C {
        &self.classifier
    }
    /// Counters.
    pub fn stats(&self) -> LinkStats {
        LinkStats {
            tx_dropped: self.out.frames_dropped(),
            events_dropped: self.out.events.dropped(),
            requests_dropped: self.out.requests.dropped(),
            watch_refused: self.plausible.refused(),
            ..self.stats
        }
    }

    fn info(&self, frame: &Frame) -> FrameInfo {
        FrameInfo {
            heartbeat: self.classifier.heartbeat_of(frame),
        }
    }
}

impl<C: FrameClassifier, K: MergeCapacity> BusLink for DualBus<C, K> {
    type Event = LinkEvent;
    type Command = LinkCommand;

    fn port_count(&self) -> usize {
        2
    }

    fn handle_rx(&mut self, now: Instant, port: usize, frame: &Frame) -> Option<Frame> {
        // A driver without receive timestamps: the frame is stamped now.
        self.rx(now, port, frame, now, false)
    }

    fn handle_rx_at(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        at: Instant,
    ) -> Option<Frame> {
        self.rx(now, port, frame, at, true)
    }

    fn handle_port_status(&mut self, now: Instant, port: usize, status: PortStatus) {
        self.watch_clock(now);
        if port > 1 {
            return;
        }
        self.health.on_status(now, port, status, &mut self.out);
        self.plausible.on_status(now, port, status, &self.health);
        self.policy.on_status(now, port, status, &mut self.out);
        self.show_status();
    }

    fn send(&mut self, now: Instant, frame: &Frame) {
        self.watch_clock(now);
        // A watched node reset, or its producer time downloaded, by this station.
        #[cfg(feature = "alloc")]
        self.plausible.on_command(frame);
        let info = self.info(frame);
        self.out.next_frame();
        let mask = self
            .policy
            .route_tx(now, frame, &info, &self.health, &mut self.out);
        self.show_status();
        for p in 0..2 {
            if mask & (1 << p) != 0 {
                self.out.frame(p, *frame);
            }
        }
    }

    fn poll_transmit(&mut self) -> Option<(usize, Frame)> {
        self.poll_numbered().map(|(p, f, _)| (p, f))
    }

    fn poll_port_request(&mut self) -> Option<(usize, PortRequest)> {
        self.out.requests.pop()
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.watch_clock(now);
        self.health.handle_timeout(now, &mut self.out);
        if self.reach_enabled {
            self.reach.handle_timeout(now, &mut self.out);
        }
        self.plausible
            .handle_timeout(now, &self.health, &mut self.out);
        self.policy.handle_timeout(now, &mut self.out);
        self.show_status();
        self.pairs.handle_timeout(now, &mut self.out);
        self.merger.expire(now);
    }

    #[inline]
    fn poll_timeout(&self) -> Option<Instant> {
        earliest_of([
            self.health.poll_timeout(),
            if self.reach_enabled {
                self.reach.poll_timeout()
            } else {
                None
            },
            self.policy.poll_timeout(),
            self.pairs.poll_timeout(),
            self.plausible.poll_timeout(),
        ])
    }

    fn poll_event(&mut self) -> Option<LinkEvent> {
        self.out.events.pop()
    }

    fn poll_machine_request(&mut self) -> Option<LinkRequest> {
        self.out.machine.pop()
    }

    // Commands use no time: the one given is not taken for the clock (a caller may pass any).
    fn handle_command(&mut self, _now: Instant, cmd: LinkCommand) {
        match cmd {
            LinkCommand::SetActive(p, m) => {
                self.set_active(p, m);
            }
            LinkCommand::Forget(p, m) => self.forget_member(p, m),
            LinkCommand::Watch { node, producer_ms } => {
                self.watch(node, Duration::from_millis(producer_ms as u64));
            }
        }
    }

    // CAN FD frames take the paths of `fd` (the inherent methods, which these call).
    #[cfg(feature = "fd")]
    fn fd_capable(&self) -> bool {
        Self::fd_capable(self)
    }

    #[cfg(feature = "fd")]
    fn handle_rx_fd(
        &mut self,
        now: Instant,
        port: usize,
        frame: &FdFrame,
        at: Instant,
    ) -> Option<FdFrame> {
        self.handle_rx_fd_at(now, port, frame, at)
    }

    #[cfg(feature = "fd")]
    fn send_fd(&mut self, now: Instant, frame: &FdFrame) {
        if Self::send_fd(self, now, frame).is_err() {
            self.stats.fd_refused = self.stats.fd_refused.saturating_add(1);
        }
    }

    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<(usize, FdFrame)> {
        Self::poll_transmit_fd(self)
    }
}

impl<C, K: MergeCapacity> core::fmt::Debug for DualBus<C, K> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let mut d = f.debug_struct("DualBus");
        #[cfg(feature = "sticky")]
        d.field("sticky", &self.sticky);
        d.field("mode", &self.policy.kind())
            .field("active", &self.policy.active())
            .field(
                "ports",
                &[self.health.port(0).state(), self.health.port(1).state()],
            )
            .field("merger", &self.merger)
            .field("lag", &[self.lag.lag(0), self.lag.lag(1)])
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

mod clock;
#[cfg(feature = "fd")]
pub mod fd;
#[cfg(all(test, feature = "fd"))]
mod fd_tests;
mod rx;
#[cfg(test)]
mod tests;
