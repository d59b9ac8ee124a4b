//! A CANopen node: the CiA 301 services of one node-ID composed over one logical bus.
//!
//! [`Node`] is a [`Machine`]: frames and time in; frames, deadlines and [`NodeEvent`]s out. The
//! dictionary is the node's configuration: services read their parameters from it at boot and
//! react when an entry changes (writing 0x1017 restarts the heartbeat, 0x1006 re-times SYNC, …).
//! Every write — local or from the bus — goes through the node so that those reactions happen.
//!
//! ```
//! use duocan_core::node::StateCause;
//! use duocan_core::nmt::{command_frame, NmtCommand, NmtState, NmtTarget};
//! use duocan_core::od::comm;
//! use duocan_core::{Frame, Id, Instant, Machine, Node, NodeConfig, NodeEventKind, NodeId};
//!
//! let five = NodeId::must(5);
//! let mut node = Node::new(NodeConfig::slave(five), comm::standard_dictionary(5, Default::default()));
//! node.set(Instant::ZERO, comm::HEARTBEAT_PRODUCER, 0, 100u16)?; // a heartbeat every 100 ms
//! node.boot(Instant::ZERO);
//! assert_eq!(node.poll_transmit(), Some(Frame::from_array(Id::Standard(0x705), [0x00]))); // boot-up
//! assert_eq!(node.nmt_state(), NmtState::PreOperational);
//! # while node.poll_event().is_some() {}
//!
//! // The master starts it.
//! let start = command_frame(Id::Standard(0x000), NmtCommand::Start, NmtTarget::Node(five));
//! node.handle_frame(Instant::from_millis(40), &start);
//! assert_eq!(node.nmt_state(), NmtState::Operational);
//! let events: Vec<_> = std::iter::from_fn(|| node.poll_event()).map(|e| e.kind).collect();
//! let started = NodeEventKind::StateChanged {
//!     from: NmtState::PreOperational,
//!     to: NmtState::Operational,
//!     cause: StateCause::Command(NmtCommand::Start),
//! };
//! assert!(events.contains(&started));
//!
//! // The change is announced at once by a heartbeat saying "operational" (0x05), and the
//! // heartbeat grid restarts from there: the next deadline is 100 ms later.
//! let operational = Frame::from_array(Id::Standard(0x705), [0x05]);
//! assert_eq!(node.poll_transmit(), Some(operational));
//! let t = node.poll_timeout().unwrap();
//! assert_eq!(t, Instant::from_millis(140));
//! node.handle_timeout(t);
//! assert_eq!(node.poll_transmit(), Some(operational));
//! # Ok::<(), duocan_core::AbortCode>(())
//! ```

#[cfg(feature = "fd")]
use crate::cia1301::usdo::UsdoServer;
use crate::cia301::emcy::EmcyProducer;
use crate::cia301::guarding::{GuardMaster, GuardSlave};
use crate::cia301::heartbeat::{HeartbeatConsumer, HeartbeatProducer};
use crate::cia301::nmt::{self, NmtCommand, NmtState, NmtTarget, NodeTable, NodeView};
use crate::cia301::pdo::{self, PdoEngine, PdoError, RpdoStatus, TpdoStatus};
use crate::cia301::sdo::{SdoServer, SdoServerConfig};
use crate::cia301::sync::SyncService;
use crate::cia301::time_stamp::{TimeOfDay, TimeService};
use crate::cia304::srdo::{SrdoSet, NODE_SRDOS};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest, Duration, Instant, TimeWatch};
use crate::frame::queue::Bounded;
use crate::frame::storage::{Inline, Storage};
#[cfg(feature = "fd")]
use crate::frame::FdFrame;
use crate::frame::Frame;
use crate::machine::{LinkRequest, Machine};
use crate::od::abort::AbortCode;
use crate::od::parameters::{ParameterGroup, StorageError};
use crate::od::{ObjectDictionary, OdValue};
use crate::profile::{IdProfile, Predefined};

/// Heartbeat consumer capacity: CiA 301 allows 127 producers in 0x1016.
pub const HEARTBEAT_CONSUMERS: usize = 127;
/// Frames a node can hold before the driver drains them.
pub const TX_QUEUE: usize = 32;
/// Events a node can hold before the application drains them.
pub const EVENT_QUEUE: usize = 32;
/// CAN FD frames (PDOs, EMCY) a node on a CANopen FD network can hold before the driver drains
/// them (feature `fd`): fewer than the classic queue, each holding 64 bytes.
#[cfg(feature = "fd")]
pub const FD_TX_QUEUE: usize = 8;

/// The CAN FD transmit queue of a node on a CANopen FD network: on the heap where there is one,
/// so that a node built with `fd` but on a classic network carries one pointer, not ~600 bytes
/// of frames; in place without an allocator.
#[cfg(all(feature = "fd", feature = "alloc"))]
type FdTxHolder = alloc::boxed::Box<Bounded<FdFrame, FD_TX_QUEUE>>;
#[cfg(all(feature = "fd", not(feature = "alloc")))]
type FdTxHolder = Bounded<FdFrame, FD_TX_QUEUE>;

/// How many nodes a node can guard as an NMT master unless told otherwise: every node-ID.
pub const ALL_NODES: usize = 127;

/// A slave node: it guards nobody (no node-guarding master table), and runs the default four
/// TPDOs and four RPDOs.
pub type SlaveNode<D, P = Predefined> = Node<D, P, 0>;

/// How a node behaves beyond what its dictionary says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct NodeConfig {
    /// The node-ID.
    pub node_id: NodeId,
    /// Enter operational by itself after boot-up (a master starting itself, 0x1F80 bit 2).
    pub auto_start: bool,
    /// Obey NMT commands from the bus. A master does not; it still reports them as events.
    pub accept_nmt: bool,
    /// Report EMCY messages of other nodes (on their default identifiers).
    pub consume_emcy: bool,
    /// A listener that is no node on the bus (the front door's observer): it never sends with
    /// its node-ID, so the heartbeats, boot-ups, guarding answers and EMCY that carry it are
    /// another node's, tracked and reported as any other's. Off: they are taken for a
    /// configuration fault elsewhere (someone else using this node's identifier) and dropped.
    /// With `std` only: a bare-metal node is always a node on the bus.
    #[cfg(feature = "std")]
    pub observer: bool,
    /// Tell the bus when a consumed heartbeat (0x1016) is lost: EMCY 0x8130 with the
    /// communication bit of 0x1001, recorded in 0x1003, and the error reset when the producer
    /// is heard again (CiA 301, what a slave does so that every master learns of it). A master
    /// handles its lost slaves itself (CiA 302-2) and does not announce them.
    pub heartbeat_loss_emcy: bool,
    /// The node is on a CANopen FD network (CiA 1301; feature `fd`): it serves USDO requests
    /// (CAN FD frames on 0x600 + the client's node-ID) from its dictionary and answers in CAN
    /// FD frames on 0x580 + its node-ID, beside the classic SDO server (see
    /// [`Node::usdo_server`] for why both); its PDOs carry up to 64 bytes and go (and are
    /// taken) as CAN FD frames, its EMCY too (`cia301::pdo`, `cia301::emcy` say how), and it
    /// decodes other nodes' CAN FD EMCY. Off (the default): CAN FD frames are ignored, PDOs
    /// and EMCY are classic. Read at build: a node does not change networks.
    #[cfg(feature = "fd")]
    pub fd: bool,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl NodeConfig {
    /// The configuration with [`auto_start`](Self::auto_start) replaced.
    #[must_use]
    pub fn with_auto_start(mut self, auto_start: bool) -> Self {
        self.auto_start = auto_start;
        self
    }
    /// The configuration with [`accept_nmt`](Self::accept_nmt) replaced.
    #[must_use]
    pub fn with_accept_nmt(mut self, accept_nmt: bool) -> Self {
        self.accept_nmt = accept_nmt;
        self
    }
    /// The configuration with [`consume_emcy`](Self::consume_emcy) replaced.
    #[must_use]
    pub fn with_consume_emcy(mut self, consume_emcy: bool) -> Self {
        self.consume_emcy = consume_emcy;
        self
    }
    /// The configuration with [`observer`](Self::observer) replaced.
    #[cfg(feature = "std")]
    #[must_use]
    pub fn with_observer(mut self, observer: bool) -> Self {
        self.observer = observer;
        self
    }
    /// The configuration with [`fd`](Self::fd) replaced.
    #[cfg(feature = "fd")]
    #[must_use]
    pub fn with_fd(mut self, fd: bool) -> Self {
        self.fd = fd;
        self
    }
    /// The configuration with [`heartbeat_loss_emcy`](Self::heartbeat_loss_emcy) replaced.
    #[must_use]
    pub fn with_heartbeat_loss_emcy(mut self, heartbeat_loss_emcy: bool) -> Self {
        self.heartbeat_loss_emcy = heartbeat_loss_emcy;
        self
    }
}

impl NodeConfig {
    /// A slave: waits for NMT start, obeys NMT, consumes EMCY, announces a lost heartbeat.
    #[must_use]
    pub const fn slave(node_id: NodeId) -> Self {
        NodeConfig {
            node_id,
            auto_start: false,
            accept_nmt: true,
            consume_emcy: true,
            #[cfg(feature = "std")]
            observer: false,
            heartbeat_loss_emcy: true,
            #[cfg(feature = "fd")]
            fd: false,
        }
    }
    /// A master: starts itself, ignores NMT commands of others, consumes EMCY, handles lost
    /// heartbeats itself.
    #[must_use]
    pub const fn master(node_id: NodeId) -> Self {
        NodeConfig {
            node_id,
            auto_start: true,
            accept_nmt: false,
            consume_emcy: true,
            #[cfg(feature = "std")]
            observer: false,
            heartbeat_loss_emcy: false,
            #[cfg(feature = "fd")]
            fd: false,
        }
    }
}

mod config;
mod dispatch;
mod error_control;
mod events;
#[cfg(test)]
mod left_out;
pub mod lss;
mod safety;
#[cfg(all(test, feature = "std"))]
pub(crate) mod usdo_tests;

pub use safety::SrdoMarkError;
mod parameters;

pub use events::{
    NodeEvent, NodeEventKind, NodeStats, QueueFull, StateCause, StorageAction, Writer,
};
pub use lss::{LssNode, LssNodeEvent};

/// Everything of a node but the SDO server: dictionary, NMT, error control, SYNC, TIME, EMCY,
/// PDO.
pub struct NodeCore<
    D,
    P = Predefined,
    const GUARDED: usize = ALL_NODES,
    const TPDOS: usize = 4,
    const RPDOS: usize = 4,
    S: Storage = Inline,
> {
    od: D,
    profile: P,
    cfg: NodeConfig,
    state: NmtState,
    hb: HeartbeatProducer,
    consumer: HeartbeatConsumer<HEARTBEAT_CONSUMERS>,
    guard: GuardSlave,
    guard_master: GuardMaster<GUARDED>,
    sync: SyncService,
    time: TimeService,
    emcy: EmcyProducer,
    history_slots: u8,
    nodes: NodeTable,
    pdo: PdoEngine<TPDOS, RPDOS, S>,
    srdo: SrdoSet<NODE_SRDOS>,
    tx: Bounded<Frame, TX_QUEUE>,
    /// The CAN FD frames of a node on a CANopen FD network (PDOs, EMCY), drained after the
    /// classic ones.
    #[cfg(feature = "fd")]
    tx_fd: Option<FdTxHolder>,
    events: Bounded<NodeEvent, EVENT_QUEUE>,
    stats: NodeStats,
    /// Boot-ups so far: the SDO server re-reads its channel when this changes.
    boots: u32,
    /// Notices the caller's clock stepping back (the clock contract).
    clock: TimeWatch,
}

/// A CANopen node on one logical bus.
///
/// `D` is the dictionary, `P` the identifier profile, `GUARDED` how many nodes it can guard as a
/// master (0 for a plain slave: [`SlaveNode`]), `TPDOS`/`RPDOS` how many TPDOs and RPDOs it runs
/// (a master mirroring many slaves' TPDOs needs hundreds of RPDOs). The capacities are part of
/// the type so that a node needs no allocator; spell a shape once as a type alias:
///
/// ```
/// use duocan_core::node::{Node, ALL_NODES};
/// use duocan_core::od::DynamicDictionary;
/// use duocan_core::profile::Predefined;
///
/// /// A concentrator mirroring the TPDOs of many boards.
/// type Concentrator = Node<DynamicDictionary, Predefined, ALL_NODES, 4, 512>;
/// ```
///
/// `S` is where the PDO tables live: [`Inline`] (the default) holds `TPDOS` and `RPDOS` inside
/// the node; [`Heap`](crate::frame::storage::Heap) (`alloc`) allocates them once when the node is
/// built, as many as [`Node::with_pdo_capacity`] asks for (`TPDOS`/`RPDOS` are then only what
/// the other constructors allocate). The master's node is one
/// ([`MasterNode`](crate::master::MasterNode)): its PDO counts are configuration values.
pub struct Node<
    D,
    P = Predefined,
    const GUARDED: usize = ALL_NODES,
    const TPDOS: usize = 4,
    const RPDOS: usize = 4,
    S: Storage = Inline,
> {
    core: NodeCore<D, P, GUARDED, TPDOS, RPDOS, S>,
    sdo: SdoServer,
    sdo_boots: u32,
    /// The USDO server of a node on a CANopen FD network ([`NodeConfig::fd`]); `None` on a
    /// classic one.
    #[cfg(feature = "fd")]
    usdo: Option<UsdoHolder>,
}

/// Where a node keeps its USDO server: on the heap where there is one, so that a classic node
/// does not carry its frames and sessions (about 1 KB) inline; in place without an allocator.
#[cfg(all(feature = "fd", feature = "alloc"))]
type UsdoHolder = alloc::boxed::Box<UsdoServer>;
#[cfg(all(feature = "fd", not(feature = "alloc")))]
type UsdoHolder = UsdoServer;

impl<D: ObjectDictionary> Node<D, Predefined, ALL_NODES> {
    /// A node with the predefined connection set. Nothing is sent until [`Node::boot`].
    #[must_use]
    pub fn new(cfg: NodeConfig, od: D) -> Self {
        Node::with_profile(cfg, od, Predefined)
    }
}

#[cfg(feature = "alloc")]
impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
    > Node<D, P, GUARDED, TPDOS, RPDOS, crate::frame::storage::Heap>
{
    /// A node whose PDO tables are allocated now for `tpdos` TPDOs and `rpdos` RPDOs (at most
    /// 512 each, the numbers CiA 301 has; more are cut to 512). They never grow.
    #[must_use]
    pub fn with_pdo_capacity(
        cfg: NodeConfig,
        od: D,
        profile: P,
        tpdos: usize,
        rpdos: usize,
    ) -> Self {
        let max = pdo::params::MAX_PDOS as usize;
        Self::build(cfg, od, profile, tpdos.min(max), rpdos.min(max))
    }
}

impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
        S: Storage,
    > Node<D, P, GUARDED, TPDOS, RPDOS, S>
{
    /// A node with a custom identifier profile.
    #[must_use]
    pub fn with_profile(cfg: NodeConfig, od: D, profile: P) -> Self {
        Self::build(cfg, od, profile, TPDOS, RPDOS)
    }

    fn build(cfg: NodeConfig, od: D, profile: P, tpdos: usize, rpdos: usize) -> Self {
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
                pdo: {
                    #[allow(unused_mut)] // set only with `fd`
                    let mut engine = PdoEngine::new(tpdos, rpdos);
                    #[cfg(feature = "fd")]
                    engine.set_fd(cfg.fd);
                    engine
                },
                srdo: SrdoSet::new(),
                tx: Bounded::new(),
                #[cfg(feature = "fd")]
                tx_fd: cfg.fd.then(|| {
                    #[cfg(feature = "alloc")]
                    return alloc::boxed::Box::new(Bounded::new());
                    #[cfg(not(feature = "alloc"))]
                    Bounded::new()
                }),
                events: Bounded::new(),
                stats: NodeStats::default(),
                boots: 0,
                clock: TimeWatch::new(),
            },
            sdo: SdoServer::new(SdoServerConfig::default()),
            sdo_boots: 0,
            #[cfg(feature = "fd")]
            usdo: None,
        }
    }

    /// Power-on: what the dictionary holds now becomes its power-on image (the values the NMT
    /// resets restore), the stored parameters are loaded over it, then the services are
    /// configured from the dictionary, the boot-up is sent and the node enters
    /// pre-operational (or operational with `auto_start`).
    ///
    /// So the application configures the node before calling this (writes, `od_mut`), and
    /// that configuration survives reset-communication and reset-node; values written later
    /// (over SDO or locally) are volatile unless stored (0x1010).
    pub fn boot(&mut self, now: Instant) {
        self.watch_clock(now);
        let _ = self.capture_power_on(now);
        self.core.load_stored(now, 0x1000..=0xFFFF);
        self.core.boot(now);
        self.sdo_follow_core();
    }

    /// Takes the dictionary's current values as its power-on image, as [`Node::boot`] does: for
    /// an application that reconfigures the node after boot and wants the resets to keep it. A
    /// dictionary without room for it keeps its previous image and says so (here and as
    /// [`NodeEventKind::StorageFailed`]).
    pub fn capture_power_on(&mut self, now: Instant) -> Result<(), StorageError> {
        let r = self.core.od.capture_power_on();
        if let Err(error) = r {
            self.core.event(
                now,
                NodeEventKind::StorageFailed {
                    action: StorageAction::CapturePowerOn,
                    error,
                },
            );
        }
        r
    }

    /// Stores `group`'s current parameters on the dictionary's medium, as a 0x1010 `"save"`
    /// does ([`NodeEventKind::ParametersStored`] or [`NodeEventKind::StorageFailed`]).
    pub fn store_parameters(
        &mut self,
        now: Instant,
        group: ParameterGroup,
    ) -> Result<(), StorageError> {
        self.core.storage_command(now, true, group, Writer::Local)
    }

    /// Removes `group` from the stored parameters, as a 0x1011 `"load"` does: its defaults (the
    /// power-on image) apply from the next reset that reloads it.
    pub fn restore_defaults(
        &mut self,
        now: Instant,
        group: ParameterGroup,
    ) -> Result<(), StorageError> {
        self.core.storage_command(now, false, group, Writer::Local)
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

    /// The USDO server (CiA 1301), if the node is on a CANopen FD network ([`NodeConfig::fd`]):
    /// its counters. It is built at boot (and rebuilt at every reset communication, with the
    /// node-ID then in force) with the SDO server's timeout and transfer limit, so one
    /// configuration ([`Node::sdo_server_mut`]) bounds both.
    ///
    /// **Why beside SDO, not instead of it.** A USDO request and an SDO request can carry the
    /// same identifier (0x600 + the client's node-ID, 0x600 + the server's), but one is a CAN
    /// FD frame and the other a classic one, so the two never mix. Keeping the classic server
    /// lets tools that speak only SDO (and the transfers USDO has no counterpart for here:
    /// block transfer) still reach the node; a network where every node is FD-capable may
    /// carry both.
    #[cfg(feature = "fd")]
    pub fn usdo_server(&self) -> Option<&UsdoServer> {
        self.usdo.as_ref().map(core::borrow::Borrow::borrow)
    }

    /// The clock contract ([`crate::frame::instant`]): on every input that carries a time, a step
    /// back of the caller's clock moves every time the node holds back with it. Public for an
    /// owner that watches the clock itself and must have the node measure the same step without
    /// anything else happening (no timer runs).
    #[inline]
    pub fn watch_clock(&mut self, now: Instant) {
        if let Some(by) = self.core.clock.step_back(now) {
            self.core.step_back(by);
            self.sdo.step_back(by);
            #[cfg(feature = "fd")]
            if let Some(u) = &mut self.usdo {
                u.step_back(by);
            }
        }
    }

    /// After anything that may have reset the node or left the SDO states: re-read the channel
    /// (boot, reset communication), drop a transfer the state no longer allows.
    fn sdo_follow_core(&mut self) {
        if self.core.boots != self.sdo_boots {
            self.sdo_boots = self.core.boots;
            let id = self.core.id();
            self.sdo.configure_from(&self.core.od, id);
            #[cfg(feature = "fd")]
            if self.core.cfg.fd {
                let cfg = self.sdo.config();
                let server = UsdoServer::new(id, cfg.timeout, cfg.max_transfer);
                #[cfg(feature = "alloc")]
                let server = alloc::boxed::Box::new(server);
                self.usdo = Some(server);
            }
        }
        if !self.core.state.services().sdo {
            self.sdo.cancel();
            #[cfg(feature = "fd")]
            if let Some(u) = &mut self.usdo {
                u.cancel();
            }
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
    pub fn core_mut(&mut self) -> &mut NodeCore<D, P, GUARDED, TPDOS, RPDOS, S> {
        &mut self.core
    }
    /// The parts.
    pub fn core(&self) -> &NodeCore<D, P, GUARDED, TPDOS, RPDOS, S> {
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
        self.watch_clock(now);
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
    /// clock or is in a state without TIME. A build without the crate feature `time` has no
    /// TIME service: it never produces or consumes TIME (0x1012 is a plain entry there), so
    /// this is always false; the local clock ([`Node::set_time`]) still runs.
    pub fn send_time(&mut self, now: Instant) -> bool {
        if !self.core.state.services().time {
            return false;
        }
        match self.core.time.frame(now) {
            Some(f) => self.core.send(f).is_ok(),
            None => false,
        }
    }
    /// As SYNC producer, produce the next SYNC at `now` if this node has neither sent nor
    /// received one since its reset (a master taking over without a grid to continue); see
    /// [`SyncService::start_at_once`].
    pub fn sync_at_once(&mut self, now: Instant) {
        self.core.sync.start_at_once(now);
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
    /// Sends a destination-address MPDO on TPDO `pdo` (1-based; its mapping count is 0xFF):
    /// `data` (up to 4 bytes, little-endian) for (`index`, `sub`) of node `dest`, 0 for every
    /// node ([`crate::cia301::mpdo`]).
    #[cfg(feature = "mpdo")]
    pub fn mpdo_send_dam(
        &mut self,
        now: Instant,
        pdo: u16,
        dest: u8,
        index: u16,
        sub: u8,
        data: &[u8],
    ) -> Result<(), crate::cia301::mpdo::MpdoError> {
        let (engine, mut io) = self.core.pdo_io();
        engine.send_dam(now, pdo, dest, index, sub, data, &mut io)
    }
    /// Sends this node's (`index`, `sub`) as a source-address MPDO on TPDO `pdo` (its mapping
    /// count is 0xFE), if the object scanner list (0x1FA0–0x1FCF) covers it
    /// ([`crate::cia301::mpdo`]).
    #[cfg(feature = "mpdo")]
    pub fn mpdo_send_sam(
        &mut self,
        now: Instant,
        pdo: u16,
        index: u16,
        sub: u8,
    ) -> Result<(), crate::cia301::mpdo::MpdoError> {
        let (engine, mut io) = self.core.pdo_io();
        engine.send_sam(now, pdo, index, sub, &mut io)
    }
    /// What the node's MPDO consumer did with the MPDOs it received.
    #[cfg(feature = "mpdo")]
    pub fn mpdo_stats(&self) -> crate::cia301::mpdo::MpdoStats {
        self.core.pdo.mpdo_stats()
    }
    /// TPDOs the node runs: TPDO1 up to this number (`TPDOS`, or what the heap storage was
    /// built with). It never changes.
    pub fn tpdo_capacity(&self) -> usize {
        self.core.pdo.tpdo_capacity()
    }
    /// RPDOs the node runs: RPDO1 up to this number. It never changes.
    pub fn rpdo_capacity(&self) -> usize {
        self.core.pdo.rpdo_capacity()
    }
    /// Payloads of synchronous CAN FD PDOs beyond 8 bytes dropped because the PDO engine's
    /// table of them ([`pdo::WIDE_PAYLOADS`]) was full (feature `fd`); 0 on a classic network.
    #[cfg(feature = "fd")]
    pub fn pdo_wide_dropped(&self) -> u32 {
        self.core.pdo.wide_dropped()
    }
    /// What TPDO `pdo` (1-based) is doing; `None` beyond the node's capacity.
    pub fn tpdo_status(&self, pdo: u16) -> Option<TpdoStatus> {
        self.core.pdo.tpdo_status(pdo)
    }
    /// What RPDO `pdo` (1-based) is doing; `None` beyond the node's capacity.
    pub fn rpdo_status(&self, pdo: u16) -> Option<RpdoStatus> {
        self.core.pdo.rpdo_status(pdo)
    }
    /// Report every RPDO applied ([`PdoEvent::RpdoReceived`](crate::cia301::pdo::PdoEvent::RpdoReceived); on by default). Off, the
    /// application reads the dictionary or [`Node::rpdo_status`] instead, and a high PDO rate
    /// cannot crowd other events out of the bounded queue.
    pub fn set_rpdo_events(&mut self, on: bool) {
        self.core.pdo.set_rx_events(on);
    }
    /// Re-reads every PDO's parameters, restarting those that changed: after structural changes
    /// through [`Node::od_mut`] (entries a mapping refers to inserted or removed).
    pub fn reload_pdos(&mut self, now: Instant) {
        let (engine, mut io) = self.core.pdo_io();
        for slot in 0..engine.tpdo_capacity() as u16 {
            engine.reload(now, pdo::Dir::Transmit, slot, &mut io);
        }
        for slot in 0..engine.rpdo_capacity() as u16 {
            engine.reload(now, pdo::Dir::Receive, slot, &mut io);
        }
        self.core.pdo_emcy(now);
    }
}

impl<D, P, const GUARDED: usize, const TPDOS: usize, const RPDOS: usize, S: Storage>
    NodeCore<D, P, GUARDED, TPDOS, RPDOS, S>
{
    /// The local NMT state.
    pub fn nmt_state(&self) -> NmtState {
        self.state
    }
}

impl<
        D: ObjectDictionary,
        P: IdProfile,
        const GUARDED: usize,
        const TPDOS: usize,
        const RPDOS: usize,
        S: Storage,
    > Machine for Node<D, P, GUARDED, TPDOS, RPDOS, S>
{
    type Event = NodeEvent;
    type LinkCommand = core::convert::Infallible;

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.watch_clock(now);
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
        self.watch_clock(now);
        self.core.handle_timeout(now);
        self.sdo_follow_core();
        self.sdo.handle_timeout(now);
        #[cfg(feature = "fd")]
        if let Some(u) = &mut self.usdo {
            u.handle_timeout(now);
        }
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
        let t = earliest(self.core.poll_timeout(), self.sdo.poll_timeout());
        #[cfg(feature = "fd")]
        let t = earliest(t, self.usdo.as_ref().and_then(|u| u.poll_timeout()));
        t
    }
    /// On a CANopen FD network: an RPDO of this node, another node's EMCY (when EMCY is
    /// consumed), or a USDO request (CiA 1301), served while the NMT state allows SDO
    /// (pre-operational and operational), as SDO requests are; other CAN FD frames are ignored.
    #[cfg(feature = "fd")]
    fn handle_frame_fd(&mut self, now: Instant, frame: &FdFrame) {
        self.watch_clock(now);
        if self.core.cfg.fd && self.core.handle_frame_fd(now, frame) {
            self.sdo_follow_core();
            return;
        }
        let Some(usdo) = &mut self.usdo else {
            return;
        };
        if !self.core.state.services().sdo {
            return;
        }
        self.core.stats.rx_frames += 1;
        if let Err(reason) = usdo.handle_frame(now, frame, &mut self.core) {
            self.core.malformed(now, frame.id(), reason);
        }
    }
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<FdFrame> {
        if let Some(f) = self.core.tx_fd.as_mut().and_then(|q| q.pop()) {
            return Some(f);
        }
        let f = self.usdo.as_mut()?.poll_transmit()?;
        self.core.stats.tx_frames += 1;
        Some(f)
    }
    fn poll_event(&mut self) -> Option<NodeEvent> {
        self.core.events.pop()
    }
    fn handle_link_request(&mut self, now: Instant, req: LinkRequest) {
        match req {
            LinkRequest::EnterPreOperational => {
                if matches!(self.nmt_state(), NmtState::Operational | NmtState::Stopped) {
                    self.set_nmt_state(now, NmtState::PreOperational);
                }
            }
            LinkRequest::SetStatus { index, sub, value } => {
                // Through the node, so that a PDO mapping the entry sees the change; a
                // dictionary without the entry simply does not show it.
                let _ = self.write(now, index, sub, &[value]);
            }
            // About a remote node: a node acts on its own heartbeat consumers' timeouts only.
            LinkRequest::NodeSuspect { .. } => {}
        }
    }
}
