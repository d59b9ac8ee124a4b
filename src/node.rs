//! A CANopen node: the CiA 301 services of one node-ID composed over one logical bus.
//!
//! [`Node`] is a [`Machine`]: frames and time in; frames, deadlines and [`NodeEvent`]s out. The
//! dictionary is the node's configuration: services read their parameters from it at boot and
//! react when an entry changes (writing 0x1017 restarts the heartbeat, 0x1006 re-times SYNC, …).
//! Every write — local or from the bus — goes through the node so that those reactions happen.

use crate::abort::AbortCode;
use crate::cob_id::{CobId, NodeId};
use crate::emcy::{self, EmcyMessage, EmcyProducer};
use crate::frame::{Frame, Id};
use crate::guarding::{GuardEvent, GuardMaster, GuardSlave, LifeEvent};
use crate::heartbeat::{ConsumerEvent, ConsumerSetting, HeartbeatConsumer, HeartbeatProducer};
use crate::machine::Machine;
use crate::nmt::{self, Malformed, NmtCommand, NmtState, NmtTarget, NodeTable, NodeView};
use crate::od::{check_value, comm, Access, Entry, ObjectDictionary, OdValue};
use crate::pdo::{self, PdoEngine, PdoError, PdoEvent, RpdoStatus, TpdoStatus};
use crate::profile::{IdProfile, Predefined, ProfileFrame};
use crate::queue::Bounded;
use crate::sdo::{SdoServer, SdoServerConfig};
use crate::sync::{SyncConfig, SyncService};
use crate::time::{earliest, Duration, Instant};
use crate::time_stamp::{TimeOfDay, TimeService};
use core::fmt;

/// Heartbeat consumer capacity: CiA 301 allows 127 producers in 0x1016.
pub const HEARTBEAT_CONSUMERS: usize = 127;
/// Frames a node can hold before the driver drains them.
pub const TX_QUEUE: usize = 32;
/// Events a node can hold before the application drains them.
pub const EVENT_QUEUE: usize = 32;

/// How a node behaves beyond what its dictionary says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeConfig {
    /// The node-ID.
    pub node_id: NodeId,
    /// Enter operational by itself after boot-up (a master starting itself, 0x1F80 bit 2).
    pub auto_start: bool,
    /// Obey NMT commands from the bus. A master does not; it still reports them as events.
    pub accept_nmt: bool,
    /// Report EMCY messages of other nodes (on their default identifiers).
    pub consume_emcy: bool,
}

impl NodeConfig {
    /// A slave: waits for NMT start, obeys NMT, consumes EMCY.
    pub const fn slave(node_id: NodeId) -> Self {
        NodeConfig {
            node_id,
            auto_start: false,
            accept_nmt: true,
            consume_emcy: true,
        }
    }
    /// A master: starts itself, ignores NMT commands of others, consumes EMCY.
    pub const fn master(node_id: NodeId) -> Self {
        NodeConfig {
            node_id,
            auto_start: true,
            accept_nmt: false,
            consume_emcy: true,
        }
    }
}

/// Why the local NMT state changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StateCause {
    /// Power-on or reset: the boot-up sequence.
    Boot,
    /// An NMT command from the bus.
    Command(NmtCommand),
    /// The application asked.
    Local,
}

/// Who wrote a dictionary entry.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Writer {
    /// The application (or the stack itself).
    Local,
    /// A remote client over SDO.
    Sdo,
}

/// What happened, and when.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeEvent {
    /// When it happened (for timeouts: exactly the deadline).
    pub at: Instant,
    /// What happened.
    pub kind: NodeEventKind,
}

/// The kinds of [`NodeEvent`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeEventKind {
    /// This node's NMT state changed.
    StateChanged {
        /// Previous state.
        from: NmtState,
        /// New state.
        to: NmtState,
        /// Why.
        cause: StateCause,
    },
    /// Another node sent its boot-up message.
    BootUp {
        /// The node.
        node: NodeId,
    },
    /// Another node's state (from heartbeat or guarding) differs from what was known.
    RemoteState {
        /// The node.
        node: NodeId,
        /// Previously known state, if any.
        from: Option<NmtState>,
        /// State now.
        to: NmtState,
    },
    /// A monitored node's heartbeat stopped: fires at `last` + consumer time.
    HeartbeatTimeout {
        /// The node.
        node: NodeId,
        /// Its last heartbeat.
        last: Instant,
    },
    /// A monitored node's heartbeat came back.
    HeartbeatResumed {
        /// The node.
        node: NodeId,
    },
    /// A guarded node did not answer within its life time.
    GuardingTimeout {
        /// The node.
        node: NodeId,
    },
    /// A guarded node answers again.
    GuardingResumed {
        /// The node.
        node: NodeId,
    },
    /// A guarded node's toggle bit did not alternate.
    GuardToggleError {
        /// The node.
        node: NodeId,
    },
    /// This node's master stopped guarding it (life guarding event).
    LifeGuardingLost,
    /// Guarding requests arrive again.
    LifeGuardingResumed,
    /// SYNC produced or received.
    Sync {
        /// Its counter, if it carries one.
        counter: Option<u8>,
        /// True if this node produced it.
        produced: bool,
    },
    /// TIME received (the local clock follows it if this node consumes TIME).
    Time {
        /// The time of day received.
        tod: TimeOfDay,
    },
    /// EMCY from another node.
    Emcy {
        /// The node.
        node: NodeId,
        /// The message.
        msg: EmcyMessage,
    },
    /// A dictionary entry was written and the stack reacted.
    ObjectWritten {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Who wrote it.
        by: Writer,
    },
    /// An NMT command was seen on the bus (whether or not it addressed this node).
    NmtObserved {
        /// The command.
        cmd: NmtCommand,
        /// The addressed node-ID byte (0 = all).
        target: u8,
    },
    /// The PDO engine reports something.
    Pdo(PdoEvent),
    /// A frame was refused as malformed (nothing changed because of it).
    Malformed {
        /// Its identifier.
        id: Id,
        /// What was wrong.
        reason: Malformed,
    },
}

/// Counters a node keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeStats {
    /// Frames handed to the node.
    pub rx_frames: u64,
    /// Frames the node produced.
    pub tx_frames: u64,
    /// Frames refused as malformed.
    pub malformed: u64,
    /// Frames no service of this node handles.
    pub unhandled: u64,
    /// Frames dropped because the transmit queue was full.
    pub tx_dropped: u32,
    /// Events dropped because the application did not drain them.
    pub events_dropped: u32,
}

/// The transmit queue is full: the driver has not drained it. Retry after draining.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueueFull;

impl fmt::Display for QueueFull {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "node transmit queue full ({TX_QUEUE} frames): drain poll_transmit and retry"
        )
    }
}

/// What protocol servers (SDO, PDO) use to reach a node's dictionary: bus-side access rights
/// and checks, and the stack's reactions to writes.
pub trait ObjectAccess {
    /// Finds an entry (no access check).
    fn entry(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode>;
    /// Reads as a remote client may.
    fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode>;
    /// Writes as a remote client may; the stack reacts as to any write.
    fn write(&mut self, now: Instant, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode>;
    /// The node's NMT state (SDO is refused in stopped).
    fn nmt_state(&self) -> NmtState;
}

/// Everything of a node but the SDO server: dictionary, NMT, error control, SYNC, TIME, EMCY,
/// PDO.
pub struct NodeCore<
    D,
    P = Predefined,
    const G: usize = 127,
    const TPDOS: usize = 4,
    const RPDOS: usize = 4,
> {
    od: D,
    profile: P,
    cfg: NodeConfig,
    state: NmtState,
    hb: HeartbeatProducer,
    consumer: HeartbeatConsumer<HEARTBEAT_CONSUMERS>,
    guard: GuardSlave,
    guard_master: GuardMaster<G>,
    sync: SyncService,
    time: TimeService,
    emcy: EmcyProducer,
    history_slots: u8,
    nodes: NodeTable,
    pdo: PdoEngine<TPDOS, RPDOS>,
    tx: Bounded<Frame, TX_QUEUE>,
    events: Bounded<NodeEvent, EVENT_QUEUE>,
    stats: NodeStats,
    /// Boot-ups so far: the SDO server re-reads its channel when this changes.
    boots: u32,
}

/// A CANopen node on one logical bus.
///
/// `D` is the dictionary, `P` the identifier profile, `G` how many nodes it can guard as a
/// master (0 for a plain slave), `TPDOS`/`RPDOS` how many TPDOs and RPDOs it runs (a master
/// mirroring many slaves' TPDOs needs hundreds of RPDOs: `Node::<_, _, 127, 4, 512>::with_profile`).
pub struct Node<
    D,
    P = Predefined,
    const G: usize = 127,
    const TPDOS: usize = 4,
    const RPDOS: usize = 4,
> {
    core: NodeCore<D, P, G, TPDOS, RPDOS>,
    sdo: SdoServer,
    sdo_boots: u32,
}

impl<D: ObjectDictionary> Node<D, Predefined, 127> {
    /// A node with the predefined connection set. Nothing is sent until [`Node::boot`].
    pub fn new(cfg: NodeConfig, od: D) -> Self {
        Node::with_profile(cfg, od, Predefined)
    }
}

impl<D: ObjectDictionary, P: IdProfile, const G: usize, const TPDOS: usize, const RPDOS: usize>
    Node<D, P, G, TPDOS, RPDOS>
{
    /// A node with a custom identifier profile.
    pub fn with_profile(cfg: NodeConfig, od: D, profile: P) -> Self {
        Node {
            core: NodeCore {
                od,
                profile,
                cfg,
                state: NmtState::Initialising,
                hb: HeartbeatProducer::default(),
                consumer: HeartbeatConsumer::new(),
                guard: GuardSlave::default(),
                guard_master: GuardMaster::new(),
                sync: SyncService::default(),
                time: TimeService::default(),
                emcy: EmcyProducer::default(),
                history_slots: 0,
                nodes: NodeTable::default(),
                pdo: PdoEngine::new(),
                tx: Bounded::new(),
                events: Bounded::new(),
                stats: NodeStats::default(),
                boots: 0,
            },
            sdo: SdoServer::new(SdoServerConfig::default()),
            sdo_boots: 0,
        }
    }

    /// Power-on: configure the services from the dictionary, send boot-up, enter
    /// pre-operational (or operational with `auto_start`).
    pub fn boot(&mut self, now: Instant) {
        self.core.boot(now);
        self.sdo_follow_core();
    }

    /// The SDO server (channel from 0x1200, configuration, counters).
    pub fn sdo_server(&self) -> &SdoServer {
        &self.sdo
    }
    /// The SDO server, to change its configuration. Its channel is re-read from 0x1200 at boot
    /// and reset communication.
    pub fn sdo_server_mut(&mut self) -> &mut SdoServer {
        &mut self.sdo
    }

    /// After anything that may have reset the node or left the SDO states: re-read the channel
    /// (boot, reset communication), drop a transfer the state no longer allows.
    fn sdo_follow_core(&mut self) {
        if self.core.boots != self.sdo_boots {
            self.sdo_boots = self.core.boots;
            let id = self.core.id();
            self.sdo.configure_from(&self.core.od, id);
        }
        if !self.core.state.services().sdo {
            self.sdo.cancel();
        }
    }

    /// The node-ID.
    pub fn id(&self) -> NodeId {
        self.core.cfg.node_id
    }
    /// The local NMT state.
    pub fn nmt_state(&self) -> NmtState {
        self.core.state
    }
    /// The dictionary, for reading.
    pub fn od(&self) -> &D {
        &self.core.od
    }
    /// The dictionary, for structural changes (inserting or removing entries of a dynamic
    /// dictionary). Value writes belong in [`Node::write`], so that the stack reacts to them.
    pub fn od_mut(&mut self) -> &mut D {
        &mut self.core.od
    }
    /// The identifier profile.
    pub fn profile(&self) -> &P {
        &self.core.profile
    }
    /// Counters.
    pub fn stats(&self) -> NodeStats {
        NodeStats {
            tx_dropped: self.core.tx.dropped(),
            events_dropped: self.core.events.dropped(),
            ..self.core.stats
        }
    }
    /// Mutable access to the parts (for protocol servers composed beside the node).
    pub fn core_mut(&mut self) -> &mut NodeCore<D, P, G, TPDOS, RPDOS> {
        &mut self.core
    }
    /// The parts.
    pub fn core(&self) -> &NodeCore<D, P, G, TPDOS, RPDOS> {
        &self.core
    }

    /// Writes an entry as the device itself (read-only entries included, `const` ones not), with
    /// the stack's reactions (0x1017 restarts the heartbeat, …).
    pub fn write(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), AbortCode> {
        self.core
            .write_checked(now, index, sub, data, Writer::Local)
    }
    /// Typed [`Node::write`].
    pub fn set<T: OdValue>(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        v: T,
    ) -> Result<(), AbortCode> {
        let mut buf = [0u8; 8];
        let n = v.encode(&mut buf);
        self.write(now, index, sub, &buf[..n])
    }

    /// Changes the local state as the application (a master starting itself, …).
    pub fn set_nmt_state(&mut self, now: Instant, state: NmtState) {
        self.core.enter(now, state, StateCause::Local);
        self.sdo_follow_core();
    }

    /// Sends an NMT module-control command (master).
    pub fn nmt_command(
        &mut self,
        now: Instant,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), QueueFull> {
        let _ = now;
        let f = nmt::command_frame(self.core.profile.nmt(), cmd, target);
        self.core.send(f)
    }

    /// Starts guarding `node` (master): requests every `guard_time`, timeout after
    /// `guard_time × factor`. Returns false when the guarding table is full.
    pub fn guard_node(
        &mut self,
        now: Instant,
        node: NodeId,
        guard_time: Duration,
        factor: u8,
    ) -> bool {
        self.core.guard_master.guard(now, node, guard_time, factor)
    }
    /// Stops guarding `node`.
    pub fn unguard_node(&mut self, node: NodeId) {
        self.core.guard_master.unguard(node);
    }

    /// What this node knows of another node's state.
    pub fn remote(&self, node: NodeId) -> Option<NodeView> {
        self.core.nodes.get(node)
    }
    /// Every node whose state is known.
    pub fn remotes(&self) -> impl Iterator<Item = (NodeId, NodeView)> + '_ {
        self.core.nodes.iter()
    }
    /// Forgets a node's state (after resetting it, before its boot-up).
    pub fn forget_remote(&mut self, node: NodeId) {
        self.core.nodes.forget(node);
    }
    /// True if `node` is monitored by the heartbeat consumer and currently timed out.
    pub fn heartbeat_lost(&self, node: NodeId) -> bool {
        self.core.consumer.is_lost(node)
    }

    /// Raises an error: error register, history (0x1003) and an EMCY message.
    pub fn emcy_raise(&mut self, now: Instant, code: u16, register_bits: u8, data: [u8; 5]) {
        self.core.emcy_raise(now, code, register_bits, data);
    }
    /// Clears an error; clearing the last one sends the error-reset EMCY.
    pub fn emcy_clear(&mut self, now: Instant, code: u16) {
        self.core.emcy_clear(now, code);
    }

    /// Sets the local clock (time of day at `now`).
    pub fn set_time(&mut self, now: Instant, tod: TimeOfDay) {
        self.core.time.set(now, tod);
    }
    /// The local time of day at `now`, if the clock is set.
    pub fn time_of_day(&self, now: Instant) -> Option<TimeOfDay> {
        self.core.time.base().map(|b| b.at(now))
    }
    /// Sends TIME now (producer only). Returns false if this node is not the producer, has no
    /// clock or is in a state without TIME.
    pub fn send_time(&mut self, now: Instant) -> bool {
        if !self.core.state.services().time {
            return false;
        }
        match self.core.time.frame(now) {
            Some(f) => self.core.send(f).is_ok(),
            None => false,
        }
    }
    /// Produce TIME every `period` while producer (zero: only on request).
    pub fn set_time_period(&mut self, now: Instant, period: Duration) {
        self.core.time.set_period(now, period);
    }

    /// Asks TPDO `pdo` (1-based) to be sent: types 254/255 at once (or when the inhibit time
    /// ends), type 0 at the next SYNC. Writing a mapped entry does the same by itself.
    pub fn tpdo_request(&mut self, now: Instant, pdo: u16) -> Result<(), PdoError> {
        let (engine, mut io) = self.core.pdo_io();
        engine.request(now, pdo, &mut io)
    }
    /// What TPDO `pdo` (1-based) is doing; `None` beyond the node's capacity.
    pub fn tpdo_status(&self, pdo: u16) -> Option<TpdoStatus> {
        self.core.pdo.tpdo_status(pdo)
    }
    /// What RPDO `pdo` (1-based) is doing; `None` beyond the node's capacity.
    pub fn rpdo_status(&self, pdo: u16) -> Option<RpdoStatus> {
        self.core.pdo.rpdo_status(pdo)
    }
    /// Report every RPDO applied ([`PdoEvent::RpdoReceived`]; on by default). Off, the
    /// application reads the dictionary or [`Node::rpdo_status`] instead, and a high PDO rate
    /// cannot crowd other events out of the bounded queue.
    pub fn set_rpdo_events(&mut self, on: bool) {
        self.core.pdo.set_rx_events(on);
    }
    /// Re-reads every PDO's parameters, restarting those that changed: after structural changes
    /// through [`Node::od_mut`] (entries a mapping refers to inserted or removed).
    pub fn reload_pdos(&mut self, now: Instant) {
        let (engine, mut io) = self.core.pdo_io();
        for slot in 0..TPDOS as u16 {
            engine.reload(now, pdo::Dir::Transmit, slot, &mut io);
        }
        for slot in 0..RPDOS as u16 {
            engine.reload(now, pdo::Dir::Receive, slot, &mut io);
        }
        self.core.pdo_emcy(now);
    }
}

impl<D: ObjectDictionary, P: IdProfile, const G: usize, const TPDOS: usize, const RPDOS: usize>
    NodeCore<D, P, G, TPDOS, RPDOS>
{
    fn id(&self) -> NodeId {
        self.cfg.node_id
    }

    fn event(&mut self, at: Instant, kind: NodeEventKind) {
        self.events.push(NodeEvent { at, kind });
    }

    fn pdo_io(&mut self) -> (&mut PdoEngine<TPDOS, RPDOS>, pdo::Io<'_, D>) {
        let io = pdo::Io {
            od: &mut self.od,
            tx: &mut self.tx,
            stats: &mut self.stats,
            events: &mut self.events,
        };
        (&mut self.pdo, io)
    }

    fn pdo_emcy(&mut self, now: Instant) {
        while let Some(a) = self.pdo.take_emcy() {
            match a {
                pdo::EmcyAction::Raise(code, data) => {
                    self.emcy_raise(now, code, emcy::register::COMMUNICATION, data)
                }
                pdo::EmcyAction::Clear(code) => self.emcy_clear(now, code),
            }
        }
    }

    fn pdo_sync(&mut self, now: Instant, counter: Option<u8>) {
        let (engine, mut io) = self.pdo_io();
        engine.on_sync(now, counter, &mut io);
        self.pdo_emcy(now);
    }

    /// A write landed: PDO parameters reload their PDO, other entries may trigger TPDOs.
    fn pdo_written(&mut self, now: Instant, index: u16, sub: u8) {
        let (engine, mut io) = self.pdo_io();
        match pdo::classify(index) {
            Some((dir, _, slot)) => engine.reload(now, dir, slot, &mut io),
            None => engine.written(now, index, sub, &mut io),
        }
        self.pdo_emcy(now);
    }

    fn send(&mut self, f: Frame) -> Result<(), QueueFull> {
        if self.tx.push(f) {
            self.stats.tx_frames += 1;
            Ok(())
        } else {
            Err(QueueFull)
        }
    }

    /// Queues a frame for the bus (for protocol servers composed with the node).
    pub fn transmit(&mut self, f: Frame) -> Result<(), QueueFull> {
        self.send(f)
    }

    /// Reports a malformed frame.
    pub fn malformed(&mut self, now: Instant, id: Id, reason: Malformed) {
        self.stats.malformed += 1;
        self.event(now, NodeEventKind::Malformed { id, reason });
    }

    /// The dictionary.
    pub fn od(&self) -> &D {
        &self.od
    }
    /// The node-ID.
    pub fn node_id(&self) -> NodeId {
        self.cfg.node_id
    }
    /// The identifier profile.
    pub fn profile(&self) -> &P {
        &self.profile
    }

    fn boot(&mut self, now: Instant) {
        self.boots = self.boots.wrapping_add(1);
        let from = self.state;
        self.state = NmtState::Initialising;
        self.apply_config(now);
        let boot_up = Frame::from_array(
            self.profile.heartbeat(self.id()),
            [NmtState::Initialising.code()],
        );
        let _ = self.send(boot_up);
        if from != NmtState::Initialising {
            self.event(
                now,
                NodeEventKind::StateChanged {
                    from,
                    to: NmtState::Initialising,
                    cause: StateCause::Boot,
                },
            );
        }
        self.enter(now, NmtState::PreOperational, StateCause::Boot);
        if self.cfg.auto_start {
            self.enter(now, NmtState::Operational, StateCause::Boot);
        }
    }

    fn enter(&mut self, now: Instant, to: NmtState, cause: StateCause) {
        let from = self.state;
        if from == to {
            return;
        }
        self.state = to;
        self.event(now, NodeEventKind::StateChanged { from, to, cause });
        if to == NmtState::Operational {
            let (engine, mut io) = self.pdo_io();
            engine.start(now, &mut io);
        } else if from == NmtState::Operational {
            self.pdo.stop();
        }
        self.pdo_emcy(now);
    }

    fn u16_of(&self, index: u16) -> u16 {
        self.od.get_u32(index, 0).unwrap_or(0) as u16
    }

    fn sync_config(&self) -> SyncConfig {
        SyncConfig {
            cob_id: CobId(
                self.od
                    .get_u32(comm::SYNC_COB_ID, 0)
                    .unwrap_or(CobId::INVALID),
            ),
            period: Duration::from_micros(self.od.get_u32(comm::SYNC_PERIOD, 0).unwrap_or(0) as u64),
            window: Duration::from_micros(self.od.get_u32(comm::SYNC_WINDOW, 0).unwrap_or(0) as u64),
            overflow: self.od.get_u32(comm::SYNC_OVERFLOW, 0).unwrap_or(0) as u8,
        }
    }

    fn guard_params(&self) -> (Duration, u8) {
        (
            Duration::from_millis(self.u16_of(comm::GUARD_TIME) as u64),
            self.od.get_u32(comm::LIFE_TIME_FACTOR, 0).unwrap_or(0) as u8,
        )
    }

    fn emcy_params(&self) -> (CobId, u16) {
        let default = crate::cob_id::CobId::from_id(self.profile.emcy(self.id()));
        (
            CobId(self.od.get_u32(comm::EMCY_COB_ID, 0).unwrap_or(default.0)),
            self.u16_of(comm::EMCY_INHIBIT),
        )
    }

    /// Reads every service's parameters from the dictionary (boot, reset communication).
    fn apply_config(&mut self, now: Instant) {
        self.hb.restart(
            now,
            Duration::from_millis(self.u16_of(comm::HEARTBEAT_PRODUCER) as u64),
        );
        self.consumer.clear();
        let subs = self
            .od
            .get_u32(comm::HEARTBEAT_CONSUMER, 0)
            .unwrap_or(0)
            .min(127) as u8;
        for sub in 1..=subs {
            if let Some(v) = self.od.get_u32(comm::HEARTBEAT_CONSUMER, sub) {
                // A dictionary holding two entries for one node keeps the first (CiA 301 would
                // have refused the second write).
                let _ = self.consumer.configure(sub, ConsumerSetting::from_u32(v));
            }
        }
        self.guard.reset();
        let (gt, lf) = self.guard_params();
        self.guard.configure(now, gt, lf);
        self.sync.reset(now, self.sync_config());
        self.time.configure(
            now,
            CobId(
                self.od
                    .get_u32(comm::TIME_COB_ID, 0)
                    .unwrap_or(CobId::INVALID),
            ),
        );
        let (cob, inhibit) = self.emcy_params();
        self.emcy.configure(cob, inhibit);
        self.history_slots = (1..=254u8)
            .take_while(|s| self.od.get(comm::ERROR_HISTORY, *s).is_ok())
            .count() as u8;
        let (engine, mut io) = self.pdo_io();
        engine.load_all(now, &mut io);
        self.pdo_emcy(now);
    }

    /// Bus-side or local write with CiA 301 checks, the communication objects' own rules, and
    /// the services' reactions.
    fn write_checked(
        &mut self,
        now: Instant,
        index: u16,
        sub: u8,
        data: &[u8],
        by: Writer,
    ) -> Result<(), AbortCode> {
        let e = self.od.get(index, sub)?;
        let allowed = match by {
            Writer::Sdo => e.def.access.writable(),
            Writer::Local => e.def.access != Access::Const,
        };
        if !allowed {
            return Err(AbortCode::READ_ONLY);
        }
        check_value(e.def, data)?;
        self.validate_comm(index, sub, data)?;
        self.od.store(index, sub, data)?;
        self.on_written(now, index, sub, by);
        Ok(())
    }

    /// Rules of communication objects that depend on other entries or on running services.
    fn validate_comm(&self, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        pdo::check_write(&self.od, index, sub, data)?;
        let new = || {
            let mut b = [0u8; 4];
            let n = data.len().min(4);
            b[..n].copy_from_slice(&data[..n]);
            u32::from_le_bytes(b)
        };
        match index {
            comm::HEARTBEAT_CONSUMER if sub >= 1 => {
                self.consumer.check(sub, ConsumerSetting::from_u32(new()))
            }
            // CiA 301: the overflow value may only change while SYNC production is off.
            comm::SYNC_OVERFLOW if self.od.get_u32(comm::SYNC_PERIOD, 0).unwrap_or(0) != 0 => {
                Err(AbortCode::DEVICE_STATE)
            }
            // The identifier of an active producer (bit 30) must not change under way.
            comm::SYNC_COB_ID => {
                let old = CobId(self.od.get_u32(index, 0).unwrap_or(0));
                let new = CobId(new());
                if old.bit30() && new.bit30() && (old.0 & 0x3FFF_FFFF) != (new.0 & 0x3FFF_FFFF) {
                    Err(AbortCode::VALUE_RANGE)
                } else {
                    Ok(())
                }
            }
            // A valid EMCY COB-ID must be invalidated before its identifier changes.
            comm::EMCY_COB_ID => {
                let old = CobId(self.od.get_u32(index, 0).unwrap_or(0));
                let new = CobId(new());
                if old.is_valid() && new.is_valid() && old.0 != new.0 {
                    Err(AbortCode::VALUE_RANGE)
                } else {
                    Ok(())
                }
            }
            _ => Ok(()),
        }
    }

    fn on_written(&mut self, now: Instant, index: u16, sub: u8, by: Writer) {
        self.pdo_written(now, index, sub);
        match index {
            comm::HEARTBEAT_PRODUCER => self.hb.restart(
                now,
                Duration::from_millis(self.u16_of(comm::HEARTBEAT_PRODUCER) as u64),
            ),
            comm::HEARTBEAT_CONSUMER if sub >= 1 => {
                let v = self.od.get_u32(index, sub).unwrap_or(0);
                let _ = self.consumer.configure(sub, ConsumerSetting::from_u32(v));
            }
            comm::GUARD_TIME | comm::LIFE_TIME_FACTOR => {
                let (gt, lf) = self.guard_params();
                self.guard.configure(now, gt, lf);
            }
            comm::SYNC_COB_ID | comm::SYNC_PERIOD | comm::SYNC_WINDOW | comm::SYNC_OVERFLOW => {
                self.sync.configure(now, self.sync_config())
            }
            comm::TIME_COB_ID => self.time.configure(
                now,
                CobId(self.od.get_u32(index, 0).unwrap_or(CobId::INVALID)),
            ),
            comm::EMCY_COB_ID | comm::EMCY_INHIBIT => {
                let (cob, inhibit) = self.emcy_params();
                self.emcy.configure(cob, inhibit);
            }
            comm::ERROR_HISTORY if sub == 0 => {
                for s in 1..=self.history_slots {
                    let _ = self.od.store(index, s, &0u32.to_le_bytes());
                }
            }
            _ => {}
        }
        self.event(now, NodeEventKind::ObjectWritten { index, sub, by });
    }

    fn emcy_raise(&mut self, now: Instant, code: u16, register_bits: u8, data: [u8; 5]) {
        let Some(msg) = self.emcy.raise(code, register_bits, data) else {
            return;
        };
        let _ = self.od.store(comm::ERROR_REGISTER, 0, &[msg.register]);
        if self.history_slots > 0 {
            let count = (self.od.get_u32(comm::ERROR_HISTORY, 0).unwrap_or(0) as u8)
                .min(self.history_slots);
            for s in (1..count.min(self.history_slots - 1) + 1).rev() {
                if let Some(v) = self.od.get_u32(comm::ERROR_HISTORY, s) {
                    let _ = self.od.store(comm::ERROR_HISTORY, s + 1, &v.to_le_bytes());
                }
            }
            let _ = self
                .od
                .store(comm::ERROR_HISTORY, 1, &(code as u32).to_le_bytes());
            let _ = self.od.store(
                comm::ERROR_HISTORY,
                0,
                &[(count + 1).min(self.history_slots)],
            );
        }
        self.flush_emcy(now);
    }

    fn emcy_clear(&mut self, now: Instant, code: u16) {
        if self.emcy.clear(code) {
            let _ = self
                .od
                .store(comm::ERROR_REGISTER, 0, &[self.emcy.register()]);
            self.flush_emcy(now);
        }
    }

    fn flush_emcy(&mut self, now: Instant) {
        if !self.state.services().emcy {
            return;
        }
        while let Some(f) = self.emcy.poll_frame(now) {
            let _ = self.send(f);
        }
    }

    fn nmt_received(&mut self, now: Instant, frame: &Frame) {
        let (cmd, target) = match nmt::parse_command(frame) {
            Ok(x) => x,
            Err(reason) => return self.malformed(now, frame.id(), reason),
        };
        self.event(now, NodeEventKind::NmtObserved { cmd, target });
        if !self.cfg.accept_nmt || (target != 0 && target != self.id().raw()) {
            return;
        }
        let cause = StateCause::Command(cmd);
        match cmd {
            NmtCommand::Start | NmtCommand::Stop | NmtCommand::EnterPreOperational => {
                self.enter(now, cmd.resulting_state(), cause)
            }
            NmtCommand::ResetNode => {
                self.od.reset_range(0x1000..=0xFFFF);
                self.emcy = EmcyProducer::default();
                self.boot(now);
            }
            NmtCommand::ResetCommunication => {
                self.od.reset_range(0x1000..=0x1FFF);
                self.boot(now);
            }
        }
    }

    fn error_control_received(&mut self, now: Instant, node: NodeId, frame: &Frame) {
        if node == self.id() {
            // Our own identifier from someone else: a configuration fault elsewhere; not ours.
            self.stats.unhandled += 1;
            return;
        }
        let (state, toggle) = match nmt::parse_error_control(frame) {
            Ok(x) => x,
            Err(reason) => return self.malformed(now, frame.id(), reason),
        };
        let changed = self.nodes.observe(node, state, now);
        if state == NmtState::Initialising {
            // Every boot-up is news, also a second one with no heartbeat in between (a slave
            // without a producer that reboots again): a master reconfigures on each.
            self.event(now, NodeEventKind::BootUp { node });
        } else if let Some(from) = changed {
            self.event(
                now,
                NodeEventKind::RemoteState {
                    node,
                    from,
                    to: state,
                },
            );
        }
        if state == NmtState::Initialising {
            self.guard_master.booted(node);
        }
        if let Some(ConsumerEvent::Resumed { node }) = self.consumer.heard(node, now) {
            self.event(now, NodeEventKind::HeartbeatResumed { node });
        }
        let mut evs: heapless::Vec<GuardEvent, 2> = heapless::Vec::new();
        self.guard_master.answer(now, node, state, toggle, |e| {
            let _ = evs.push(e);
        });
        for e in evs {
            self.guard_event(now, e);
        }
    }

    fn guard_event(&mut self, now: Instant, e: GuardEvent) {
        let kind = match e {
            // The state itself was recorded from the frame already.
            GuardEvent::State { .. } => return,
            GuardEvent::Timeout { node } => NodeEventKind::GuardingTimeout { node },
            GuardEvent::Resumed { node } => NodeEventKind::GuardingResumed { node },
            GuardEvent::ToggleError { node, .. } => NodeEventKind::GuardToggleError { node },
        };
        self.event(now, kind);
    }

    fn guard_request(&mut self, now: Instant, frame: &Frame) {
        if !frame.is_remote() {
            return self.malformed(now, frame.id(), Malformed::UnexpectedData);
        }
        let (byte, resumed) = self.guard.request(now, self.state);
        let _ = self.send(Frame::from_array(self.profile.guarding(self.id()), [byte]));
        if resumed.is_some() {
            self.emcy_clear(now, emcy::code::LIFE_GUARD);
            self.event(now, NodeEventKind::LifeGuardingResumed);
        }
    }

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.stats.rx_frames += 1;
        if self.state == NmtState::Initialising {
            return;
        }
        let services = self.state.services();
        let id = frame.id();
        if Some(id) == self.sync.id() {
            if !services.sync {
                return;
            }
            match self.sync.received(now, frame) {
                Ok(tick) => {
                    self.event(
                        now,
                        NodeEventKind::Sync {
                            counter: tick.counter,
                            produced: false,
                        },
                    );
                    self.pdo_sync(now, tick.counter);
                }
                Err(reason) => {
                    self.malformed(now, id, reason);
                    self.emcy_raise(
                        now,
                        emcy::code::SYNC_LENGTH,
                        emcy::register::COMMUNICATION,
                        [0; 5],
                    );
                }
            }
            return;
        }
        if Some(id) == self.time.id() {
            if !services.time {
                return;
            }
            match self.time.received(now, frame) {
                Ok(tod) => self.event(now, NodeEventKind::Time { tod }),
                Err(reason) => self.malformed(now, id, reason),
            }
            return;
        }
        let (engine, mut io) = self.pdo_io();
        if engine.handle_frame(now, frame, &mut io) {
            self.pdo_emcy(now);
            return;
        }
        match self.profile.classify(id, frame.is_remote()) {
            Some(ProfileFrame::Nmt) => self.nmt_received(now, frame),
            Some(ProfileFrame::Heartbeat(n)) => {
                if frame.is_remote() {
                    // Shared identifier: a remote frame here is a guarding request.
                    if n == self.id() {
                        self.guard_request(now, frame);
                    } else {
                        self.stats.unhandled += 1;
                    }
                } else {
                    self.error_control_received(now, n, frame);
                }
            }
            Some(ProfileFrame::Guarding(n)) => {
                if n == self.id() {
                    self.guard_request(now, frame);
                } else if frame.is_remote() {
                    self.stats.unhandled += 1;
                } else {
                    self.error_control_received(now, n, frame);
                }
            }
            Some(ProfileFrame::Emcy(n)) => {
                if n == self.id() || !services.emcy || !self.cfg.consume_emcy {
                    self.stats.unhandled += 1;
                    return;
                }
                match EmcyMessage::from_frame(frame) {
                    Ok(msg) => self.event(now, NodeEventKind::Emcy { node: n, msg }),
                    Err(reason) => self.malformed(now, id, reason),
                }
            }
            None => self.stats.unhandled += 1,
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        if self.state == NmtState::Initialising {
            return;
        }
        let services = self.state.services();
        if self.hb.due(now) && services.error_control {
            let _ = self.send(Frame::from_array(
                self.profile.heartbeat(self.id()),
                [self.state.code()],
            ));
        }
        let events = &mut self.events;
        self.consumer.handle_timeout(now, |e| {
            if let ConsumerEvent::Timeout { node, last } = e {
                events.push(NodeEvent {
                    at: now,
                    kind: NodeEventKind::HeartbeatTimeout { node, last },
                });
            }
        });
        if self.guard.handle_timeout(now) == Some(LifeEvent::Lost) {
            self.event(now, NodeEventKind::LifeGuardingLost);
            self.emcy_raise(
                now,
                emcy::code::LIFE_GUARD,
                emcy::register::COMMUNICATION,
                [0; 5],
            );
        }
        let mut requests: heapless::Vec<NodeId, G> = heapless::Vec::new();
        let mut gevs: heapless::Vec<GuardEvent, G> = heapless::Vec::new();
        self.guard_master.handle_timeout(
            now,
            |n| {
                let _ = requests.push(n);
            },
            |e| {
                let _ = gevs.push(e);
            },
        );
        for e in gevs {
            self.guard_event(now, e);
        }
        for n in requests {
            if let Ok(f) = Frame::remote(self.profile.guarding(n), 1) {
                let _ = self.send(f);
            }
        }
        if let Some((f, tick)) = self.sync.handle_timeout(now) {
            if services.sync {
                let _ = self.send(f);
                self.event(
                    now,
                    NodeEventKind::Sync {
                        counter: tick.counter,
                        produced: true,
                    },
                );
                self.pdo_sync(now, tick.counter);
            }
        }
        if let Some(f) = self.time.handle_timeout(now) {
            if services.time {
                let _ = self.send(f);
            }
        }
        let (engine, mut io) = self.pdo_io();
        engine.handle_timeout(now, &mut io);
        self.pdo_emcy(now);
        self.flush_emcy(now);
    }

    fn poll_timeout(&self) -> Option<Instant> {
        if self.state == NmtState::Initialising {
            return None;
        }
        let mut t = earliest(self.hb.poll_timeout(), self.consumer.poll_timeout());
        t = earliest(t, self.guard.poll_timeout());
        t = earliest(t, self.guard_master.poll_timeout());
        t = earliest(t, self.sync.poll_timeout());
        t = earliest(t, self.time.poll_timeout());
        t = earliest(t, self.pdo.poll_timeout());
        if self.state.services().emcy {
            t = earliest(t, self.emcy.poll_timeout());
        }
        t
    }
}

impl<D: ObjectDictionary, P: IdProfile, const G: usize, const TPDOS: usize, const RPDOS: usize>
    ObjectAccess for NodeCore<D, P, G, TPDOS, RPDOS>
{
    fn entry(&self, index: u16, sub: u8) -> Result<Entry<'_>, AbortCode> {
        self.od.get(index, sub)
    }
    fn read(&self, index: u16, sub: u8) -> Result<&[u8], AbortCode> {
        self.od.read(index, sub)
    }
    fn write(&mut self, now: Instant, index: u16, sub: u8, data: &[u8]) -> Result<(), AbortCode> {
        self.write_checked(now, index, sub, data, Writer::Sdo)
    }
    fn nmt_state(&self) -> NmtState {
        self.state
    }
}

impl<D: ObjectDictionary, P: IdProfile, const G: usize, const TPDOS: usize, const RPDOS: usize>
    Machine for Node<D, P, G, TPDOS, RPDOS>
{
    type Event = NodeEvent;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        if Some(frame.id()) == self.sdo.rx_id() && self.core.state.services().sdo {
            self.core.stats.rx_frames += 1;
            if let Err(reason) = self.sdo.handle_frame(now, frame, &mut self.core) {
                self.core.malformed(now, frame.id(), reason);
            }
            return;
        }
        self.core.handle_frame(now, frame);
        self.sdo_follow_core();
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.core.handle_timeout(now);
        self.sdo_follow_core();
        self.sdo.handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<Frame> {
        if let Some(f) = self.core.tx.pop() {
            return Some(f);
        }
        let f = self.sdo.poll_transmit()?;
        self.core.stats.tx_frames += 1;
        Some(f)
    }
    fn poll_timeout(&self) -> Option<Instant> {
        earliest(self.core.poll_timeout(), self.sdo.poll_timeout())
    }
    fn poll_event(&mut self) -> Option<NodeEvent> {
        self.core.events.pop()
    }
}
