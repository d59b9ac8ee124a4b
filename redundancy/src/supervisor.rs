//! The supervisor: a redundant master's brain on one logical bus.
//!
//! [`Supervisor`] is a [`Machine`] composing the master's [`Node`] (heartbeat, SYNC, TIME, NMT
//! state of every node), an [`SdoClient`] for the configuration of joining slaves, the
//! [`PairSupervisor`], the [`FlyingMaster`] and the [`AuditTrail`]:
//!
//! - **Active** (strong, or weak after a takeover): produces SYNC and TIME, commands the slaves
//!   (pair supervision in [`Authority::Command`]), answers the flying-master requests.
//! - **Standby** (hot): consumes SYNC and TIME, produces its own heartbeat, follows the pair table
//!   from the heartbeats and the active master's NMT commands ([`Authority::Shadow`]), watches the
//!   active master's heartbeat. At the timeout it takes over without resetting anything: the
//!   shadow table becomes the commanding one, SYNC continues the grid it consumed (the first SYNC
//!   comes at once if one is overdue, then on the old grid), TIME continues the time base it
//!   consumed.
//!
//! Which pair member is active must reach the dual-bus layer (same-function merge): the
//! supervisor queues [`LinkCommand`]s, which [`SupervisedStation`](crate::station::SupervisedStation)
//! forwards to its [`DualBus`](crate::DualBus) after every input.
//!
//! ```
//! use duocan::od::comm;
//! use duocan::sim::{BusConfig, SimNetwork};
//! use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
//! use duocan_redundancy::pairs::PairSpec;
//! use duocan_redundancy::{DualBus, DualBusConfig, Member, PairId, SupervisedStation, Supervisor, SupervisorConfig};
//!
//! let ms = Duration::from_millis;
//! let mut sim = SimNetwork::new(1);
//! let buses = [sim.add_bus(BusConfig::new("can1", 1_000_000)), sim.add_bus(BusConfig::new("can2", 1_000_000))];
//! // A master alone (a weak peer, node 2, is declared but absent), one pair of boards.
//! let node = Node::new(NodeConfig::master(NodeId::must(1)), comm::standard_dictionary(1, Default::default()));
//! let cfg = SupervisorConfig::new(0, NodeId::must(1), ms(20), ms(50), ms(10)).with_peer(1, NodeId::must(2));
//! let mut sup = Supervisor::new(node, cfg, Instant::ZERO);
//! sup.add_pair(Instant::ZERO, PairSpec::new(NodeId::must(0x10), NodeId::must(0x50), ms(20), ms(50))).unwrap();
//! let master = sim.add_device("master", SupervisedStation::new(DualBus::new(DualBusConfig::default()), sup).unwrap(), &buses)?;
//! for id in [0x10, 0x50] {
//!     let mut n = Node::new(NodeConfig::slave(NodeId::must(id)), comm::standard_dictionary(id, Default::default()));
//!     n.boot(Instant::ZERO);
//!     sim.add_device(format!("board {id:#x}"), Station::new(DualBus::new(DualBusConfig::default()), n), &buses)?;
//! }
//! sim.run_until(Instant::from_secs(1));
//! let st = sim.device(master);
//! assert!(st.sup.is_active());
//! assert_eq!(st.sup.pair_supervisor().pair(PairId(0)).unwrap().active, Some(Member::A));
//! println!("{}", st.status(Instant::from_secs(1)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Until the CiA 302-2 boot process of the root crate is available, joining configures a slave
//! with one SDO download of its heartbeat producer time (0x1017); the [`PairCommand::Configure`]
//! requests are the hook where the master's configure process takes over.

use crate::audit::{AuditEntry, AuditTrail};
use crate::events::LinkEvent;
use crate::flying_master::{
    FlyingEvent, FlyingMaster, FlyingMasterConfig, MasterError, MasterRole, Rank, MAX_PEERS,
};
use crate::pairs::{
    Authority, PairCommand, PairSpec, PairState, PairSupervisor, PairsConfig, PairsError,
    PairsEvent,
};
use crate::pairs_merge::{Member, PairId};
use core::fmt;
use duocan::machine::Machine;
use duocan::nmt::{self, NmtTarget};
use duocan::node::{NodeEventKind, Writer};
use duocan::od::{comm, ObjectDictionary};
use duocan::queue::Bounded;
use duocan::sdo::{RequestId, SdoClient, SdoOptions};
use duocan::time::earliest;
use duocan::time_stamp::TimeOfDay;
use duocan::{Duration, Frame, Id, Instant, NmtCommand, NmtState, Node, NodeEvent, NodeId};
use heapless::Vec;

/// Frames the supervisor itself can hold (NMT commands, flying-master frames).
pub const TX_QUEUE: usize = 256;
/// Events the supervisor can hold before the application drains them.
pub const EVENT_QUEUE: usize = 256;
/// Configurations that can wait for a free SDO session.
pub const CONFIG_QUEUE: usize = 128;
/// Configurations at once.
const SDO_SESSIONS: usize = 8;

/// SYNC COB-ID as consumer / as producer.
const SYNC_CONSUME: u32 = 0x0000_0080;
const SYNC_PRODUCE: u32 = 0x4000_0080;
/// TIME COB-ID as consumer / as producer.
const TIME_CONSUME: u32 = 0x8000_0100;
const TIME_PRODUCE: u32 = 0x4000_0100;

/// How a supervisor is set up.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SupervisorConfig {
    /// Flying-master timing, rank and policy (the node-ID is the rank's).
    pub flying: FlyingMasterConfig,
    /// The other master-capable devices.
    pub peers: Vec<Rank, MAX_PEERS>,
    /// Pair supervision policy.
    pub pairs: PairsConfig,
    /// This master's heartbeat producer time.
    pub heartbeat: Duration,
    /// SYNC period while active (zero: no SYNC).
    pub sync_period: Duration,
    /// TIME period while active (zero: no periodic TIME).
    pub time_period: Duration,
    /// SDO timeout of a configuration.
    pub sdo_timeout: Duration,
}

impl SupervisorConfig {
    /// A master of `priority` at `node` with a heartbeat of `heartbeat` and a master-heartbeat
    /// timeout of `master_timeout`, SYNC every `sync_period`; the 0x1F90 defaults otherwise.
    pub fn new(
        priority: u8,
        node: NodeId,
        heartbeat: Duration,
        master_timeout: Duration,
        sync_period: Duration,
    ) -> Self {
        SupervisorConfig {
            flying: FlyingMasterConfig::new(priority, node, master_timeout),
            peers: Vec::new(),
            pairs: PairsConfig::default(),
            heartbeat,
            sync_period,
            time_period: Duration::ZERO,
            sdo_timeout: Duration::from_millis(100),
        }
    }
    /// With another master-capable device.
    pub fn with_peer(mut self, priority: u8, node: NodeId) -> Self {
        let _ = self.peers.push(Rank::new(priority, node));
        self
    }
}

/// What the supervisor asks of the dual-bus layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkCommand {
    /// Deliver the process data of `member` of `pair` (`None`: neither).
    SetActive(PairId, Option<Member>),
    /// Forget a member's latest values.
    Forget(PairId, Member),
}

/// What the supervisor tells the application.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SupervisorEvent {
    /// From the master node (SYNC ticks and local writes are not forwarded; see the counters).
    Node(NodeEvent),
    /// From the pair supervision.
    Pairs(PairsEvent),
    /// From the flying master.
    Master(FlyingEvent),
    /// A configuration failed (SDO).
    ConfigFailed {
        /// When.
        at: Instant,
        /// The node.
        node: NodeId,
        /// The SDO error.
        error: duocan::sdo::SdoError,
    },
}

/// Counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SupervisorStats {
    /// SYNC produced.
    pub sync_produced: u64,
    /// SYNC received.
    pub sync_received: u64,
    /// NMT commands sent.
    pub nmt_sent: u32,
    /// NMT commands the pair supervision asked for while this master could not command.
    pub nmt_withheld: u32,
    /// Configurations started.
    pub configs: u32,
    /// Frames dropped because the driver did not drain them.
    pub tx_dropped: u32,
    /// Events dropped because the application did not drain them.
    pub events_dropped: u32,
}

/// A planned hand-over or take-over, done between two SYNCs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Planned {
    HandOver(Option<Rank>),
    TakeOver,
}

/// A redundant master: node, configuration, pair supervision, flying master, audit trail.
pub struct Supervisor<D> {
    node: Node<D>,
    sdo: SdoClient<duocan::sdo::DefaultBuffer, SDO_SESSIONS>,
    pairs: PairSupervisor,
    fm: FlyingMaster,
    audit: AuditTrail,
    cfg: SupervisorConfig,
    tx: Bounded<Frame, TX_QUEUE>,
    events: Bounded<SupervisorEvent, EVENT_QUEUE>,
    link: Bounded<LinkCommand, 256>,
    to_configure: Bounded<(NodeId, Duration), CONFIG_QUEUE>,
    configuring: Vec<(RequestId, NodeId), SDO_SESSIONS>,
    /// Last SYNC produced or received (the grid planned switches align to).
    last_sync: Option<Instant>,
    planned: Option<(Planned, Instant)>,
    /// The SDO client may hold frames although no configuration runs.
    sdo_tail: bool,
    stats: SupervisorStats,
}

impl<D: ObjectDictionary> Supervisor<D> {
    /// A supervisor on `node` (created, not booted; a master configuration: it ignores NMT
    /// commands of others). Boots the node at `now` and starts the flying-master detection.
    pub fn new(mut node: Node<D>, cfg: SupervisorConfig, now: Instant) -> Self {
        let hb = cfg.heartbeat.as_millis().min(u16::MAX as u64) as u16;
        // Entries a master dictionary has; a missing one is reported by the node's own checks.
        let _ = node.set(now, comm::HEARTBEAT_PRODUCER, 0, hb);
        let _ = node.set(now, comm::SYNC_COB_ID, 0, SYNC_CONSUME);
        let _ = node.set(
            now,
            comm::SYNC_PERIOD,
            0,
            cfg.sync_period.as_micros() as u32,
        );
        let _ = node.set(now, comm::TIME_COB_ID, 0, TIME_CONSUME);
        node.boot(now);
        let mut fm = FlyingMaster::new(cfg.flying);
        for p in &cfg.peers {
            let _ = fm.add_peer(*p);
        }
        fm.start(now);
        let mut pairs = PairSupervisor::new(cfg.pairs);
        pairs.set_authority(now, Authority::Shadow);
        let mut s = Supervisor {
            node,
            sdo: SdoClient::with_limit(64),
            pairs,
            fm,
            audit: AuditTrail::new(),
            cfg,
            tx: Bounded::new(),
            events: Bounded::new(),
            link: Bounded::new(),
            to_configure: Bounded::new(),
            configuring: Vec::new(),
            last_sync: None,
            planned: None,
            sdo_tail: false,
            stats: SupervisorStats::default(),
        };
        s.pump(now);
        s
    }

    /// Adds a slave pair to supervise.
    pub fn add_pair(&mut self, now: Instant, spec: PairSpec) -> Result<PairId, PairsError> {
        self.pairs.add_pair(now, spec)
    }

    // ----- application API -----

    /// This master's role.
    pub fn role(&self) -> MasterRole {
        self.fm.role()
    }
    /// True when active.
    pub fn is_active(&self) -> bool {
        self.fm.is_active()
    }
    /// The flying master (rank, peers, active master).
    pub fn flying_master(&self) -> &FlyingMaster {
        &self.fm
    }
    /// The pair table.
    pub fn pairs(&self) -> impl Iterator<Item = (PairId, &PairState)> + '_ {
        self.pairs.pairs()
    }
    /// The pair supervision.
    pub fn pair_supervisor(&self) -> &PairSupervisor {
        &self.pairs
    }
    /// The master node (states of every node heard: [`Node::remotes`]).
    pub fn node(&self) -> &Node<D> {
        &self.node
    }
    /// The master node, for the application's own use (its writes go through the node).
    pub fn node_mut(&mut self) -> &mut Node<D> {
        &mut self.node
    }
    /// The audit trail.
    pub fn audit(&self) -> &AuditTrail {
        &self.audit
    }
    /// Counters.
    pub fn stats(&self) -> SupervisorStats {
        SupervisorStats {
            tx_dropped: self.tx.dropped(),
            events_dropped: self.events.dropped(),
            ..self.stats
        }
    }
    /// Sets the network time (the active master then produces TIME from it).
    pub fn set_time(&mut self, now: Instant, tod: TimeOfDay) {
        self.node.set_time(now, tod);
    }
    /// Makes `to` the active member of `pair` by hand (active master only).
    pub fn switch_over(
        &mut self,
        now: Instant,
        pair: PairId,
        to: Member,
    ) -> Result<(), PairsError> {
        self.pairs.switch_over(now, pair, to)?;
        self.pump(now);
        Ok(())
    }
    /// Puts this (active) master in standby by hand: the role is handed to the best live
    /// master between two SYNCs.
    pub fn set_standby(&mut self, now: Instant) -> Result<(), MasterError> {
        if !self.fm.is_active() {
            return Err(MasterError::WrongRole(self.fm.role()));
        }
        if !self.fm.peers().iter().any(|p| {
            p.last
                .is_some_and(|l| l + self.cfg.flying.master_timeout > now)
        }) {
            return Err(MasterError::NoSuccessor);
        }
        self.plan(now, Planned::HandOver(None));
        Ok(())
    }
    /// Makes this (standby) master active by hand, between two SYNCs.
    pub fn set_active(&mut self, now: Instant) -> Result<(), MasterError> {
        if self.fm.is_active() {
            return Err(MasterError::WrongRole(self.fm.role()));
        }
        self.plan(now, Planned::TakeOver);
        Ok(())
    }
    /// Drains the next command for the dual-bus layer.
    pub fn poll_link_command(&mut self) -> Option<LinkCommand> {
        self.link.pop()
    }
    /// Records a dual-bus event in the audit trail if it is a switch, toggle or port change.
    pub fn audit_link(&mut self, e: &LinkEvent) {
        if AuditEntry::link_worth_recording(e) {
            self.audit.record(e.at, AuditEntry::Link(*e));
        }
    }

    // ----- internals -----

    /// Half a SYNC period after the last SYNC (now if there is no SYNC).
    fn plan(&mut self, now: Instant, what: Planned) {
        let p = self.cfg.sync_period;
        let at = match self.last_sync {
            Some(g) if !p.is_zero() => {
                let mut t = g + Duration::from_micros(p.as_micros() / 2);
                while t < now {
                    t += p;
                }
                t
            }
            _ => now,
        };
        self.planned = Some((what, at));
    }

    fn run_planned(&mut self, now: Instant) {
        let Some((what, at)) = self.planned else {
            return;
        };
        if at > now {
            return;
        }
        self.planned = None;
        let _ = match what {
            Planned::HandOver(to) => self.fm.hand_over(now, to).map(|_| ()),
            Planned::TakeOver => self.fm.take_over(now),
        };
    }

    fn heartbeat_frame(frame: &Frame) -> Option<(NodeId, NmtState)> {
        let Id::Standard(id) = frame.id() else {
            return None;
        };
        if !(0x701..=0x77F).contains(&id) || frame.is_remote() {
            return None;
        }
        let node = NodeId::new((id - 0x700) as u8)?;
        let (state, _) = nmt::parse_error_control(frame).ok()?;
        Some((node, state))
    }

    /// Moves every output of the parts to where it belongs.
    fn pump(&mut self, now: Instant) {
        loop {
            let mut progressed = false;
            while let Some(f) = self.fm.poll_transmit() {
                self.tx.push(f);
            }
            while let Some(e) = self.fm.poll_event() {
                progressed = true;
                self.master_event(now, e);
            }
            self.sync_authority(now);
            while let Some(c) = self.pairs.poll_command() {
                progressed = true;
                self.pair_command(now, c);
            }
            while let Some(e) = self.pairs.poll_event() {
                if let PairsEvent::Role(r) = e {
                    self.audit.record(r.at, AuditEntry::Pair(r));
                }
                self.events.push(SupervisorEvent::Pairs(e));
            }
            while let Some(e) = self.node.poll_event() {
                progressed = true;
                self.node_event(now, e);
            }
            while let Some(e) = if self.configuring.is_empty() {
                None
            } else {
                self.sdo.poll_event()
            } {
                progressed = true;
                // A finished transfer may leave a frame (an abort) to send.
                self.sdo_tail = true;
                self.configuring.retain(|(r, _)| *r != e.request);
                let ok = e.result.is_ok();
                if let Err(error) = e.result {
                    self.events.push(SupervisorEvent::ConfigFailed {
                        at: e.at,
                        node: e.node,
                        error,
                    });
                }
                self.pairs.configured(e.at, e.node, ok);
            }
            self.start_configurations(now);
            if !progressed {
                break;
            }
        }
    }

    /// Pair supervision commands only while this master may command.
    fn sync_authority(&mut self, now: Instant) {
        let want = if self.fm.may_command(now) {
            Authority::Command
        } else {
            Authority::Shadow
        };
        if self.pairs.authority() != want {
            if want == Authority::Shadow {
                // Whatever was waiting for a session is the new commander's business.
                self.to_configure.clear();
            }
            self.pairs.set_authority(now, want);
        }
    }

    fn master_event(&mut self, now: Instant, e: FlyingEvent) {
        match e {
            FlyingEvent::Role(r) => {
                self.audit.record(r.at, AuditEntry::Master(r));
                if r.to.is_active() && !r.from.is_active() {
                    self.become_producer(now, true);
                } else if r.from.is_active() && !r.to.is_active() {
                    self.become_producer(now, false);
                    self.planned = None;
                }
            }
            FlyingEvent::Suspended { at, until } => {
                self.audit.record(at, AuditEntry::Suspended { until });
            }
        }
        self.events.push(SupervisorEvent::Master(e));
    }

    /// SYNC and TIME production follow the role; the services keep their grid and time base.
    fn become_producer(&mut self, now: Instant, on: bool) {
        let (sync, time) = if on {
            (SYNC_PRODUCE, TIME_PRODUCE)
        } else {
            (SYNC_CONSUME, TIME_CONSUME)
        };
        let _ = self.node.set(now, comm::SYNC_COB_ID, 0, sync);
        let _ = self.node.set(now, comm::TIME_COB_ID, 0, time);
        if on && !self.cfg.time_period.is_zero() {
            self.node.set_time_period(now, self.cfg.time_period);
            self.node.send_time(now);
        }
    }

    fn pair_command(&mut self, now: Instant, c: PairCommand) {
        match c {
            PairCommand::Nmt { cmd, node } => {
                if self.fm.may_command(now) {
                    let f = nmt::command_frame(Id::Standard(0), cmd, NmtTarget::Node(node));
                    self.tx.push(f);
                    self.stats.nmt_sent += 1;
                    if matches!(cmd, NmtCommand::ResetNode | NmtCommand::ResetCommunication) {
                        self.node.forget_remote(node);
                    }
                } else {
                    self.stats.nmt_withheld += 1;
                }
            }
            PairCommand::Configure {
                node,
                producer_time,
            } => {
                if self.fm.may_command(now) {
                    self.to_configure.push((node, producer_time));
                }
            }
            PairCommand::SetActive { pair, member } => {
                self.link.push(LinkCommand::SetActive(pair, member));
            }
            PairCommand::Forget { pair, member } => {
                self.link.push(LinkCommand::Forget(pair, member));
            }
        }
    }

    fn start_configurations(&mut self, now: Instant) {
        while !self.configuring.is_full() {
            let Some((node, hb)) = self.to_configure.pop() else {
                return;
            };
            let ms = hb.as_millis().min(u16::MAX as u64) as u16;
            let opts = SdoOptions {
                timeout: self.cfg.sdo_timeout,
                ..SdoOptions::default()
            };
            match self.sdo.download(
                now,
                node,
                comm::HEARTBEAT_PRODUCER,
                0,
                &ms.to_le_bytes(),
                opts,
            ) {
                Ok(r) => {
                    self.stats.configs += 1;
                    let _ = self.configuring.push((r, node));
                }
                Err(error) => {
                    self.events.push(SupervisorEvent::ConfigFailed {
                        at: now,
                        node,
                        error,
                    });
                    self.pairs.configured(now, node, false);
                }
            }
        }
    }

    fn node_event(&mut self, now: Instant, e: NodeEvent) {
        match e.kind {
            NodeEventKind::Sync { produced, .. } => {
                self.last_sync = Some(e.at);
                if produced {
                    self.stats.sync_produced += 1;
                } else {
                    self.stats.sync_received += 1;
                    self.fm.foreign_activity(now);
                }
                return;
            }
            NodeEventKind::NmtObserved { cmd, target } => {
                self.fm.foreign_activity(now);
                self.pairs.nmt_observed(e.at, cmd, target);
            }
            NodeEventKind::ObjectWritten {
                by: Writer::Local, ..
            } => return,
            _ => {}
        }
        self.events.push(SupervisorEvent::Node(e));
    }
}

impl<D: ObjectDictionary> Machine for Supervisor<D> {
    type Event = SupervisorEvent;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        if self.fm.handle_frame(now, frame) {
            return self.pump(now);
        }
        if let Some((node, state)) = Self::heartbeat_frame(frame) {
            self.fm
                .heartbeat(now, node, state == NmtState::Initialising);
            self.pairs.heartbeat(now, node, state);
        }
        self.node.handle_frame(now, frame);
        // The client only serves configurations: idle, it has nothing to do with a frame.
        if !self.configuring.is_empty() {
            self.sdo.handle_frame(now, frame);
        }
        self.pump(now);
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.fm.handle_timeout(now);
        if let Some(to) = self.fm.take_handback() {
            self.plan(now, Planned::HandOver(Some(to)));
        }
        // Role changes first: a takeover makes the node a producer before its timers run.
        self.pump(now);
        self.run_planned(now);
        self.pump(now);
        self.pairs.handle_timeout(now);
        self.node.handle_timeout(now);
        if !self.configuring.is_empty() {
            self.sdo.handle_timeout(now);
        }
        self.pump(now);
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        if let Some(f) = self.tx.pop() {
            return Some(f);
        }
        if let Some(f) = self.node.poll_transmit() {
            return Some(f);
        }
        if self.configuring.is_empty() && !self.sdo_tail {
            return None;
        }
        let f = self.sdo.poll_transmit();
        if f.is_none() {
            self.sdo_tail = false;
        }
        f
    }

    fn poll_timeout(&self) -> Option<Instant> {
        let mut t = earliest(self.fm.poll_timeout(), self.pairs.poll_timeout());
        t = earliest(t, self.node.poll_timeout());
        if !self.configuring.is_empty() {
            t = earliest(t, self.sdo.poll_timeout());
        }
        earliest(t, self.planned.map(|p| p.1))
    }

    fn poll_event(&mut self) -> Option<SupervisorEvent> {
        self.events.pop()
    }
}

impl<D> fmt::Debug for Supervisor<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Supervisor")
            .field("fm", &self.fm)
            .field("pairs", &self.pairs)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}
