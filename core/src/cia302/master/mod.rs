//! The CiA 302-2 master (`alloc`): network boot-up, slave identity check and configuration,
//! request NMT, and the hooks a redundancy supervisor needs (active/standby, start policy,
//! per-slave boot on demand, the per-node state view).
//!
//! [`Master`] is a [`Machine`] composing the master's own [`Node`] (dictionary, NMT, heartbeat,
//! SYNC, TIME, SDO server), an [`SdoClient`] and the boot manager. It reacts to the node's
//! events (boot-ups, heartbeats, states, writes to its own 0x1F8x entries) and to SDO results,
//! and reports [`MasterEvent`]s: its own, plus every node event and the results of SDO transfers
//! the application started, so the application still sees everything.
//!
//! # What it does (active)
//! - At [`Master::boot`]: resets communication of the slaves (one broadcast, or one command per
//!   slave when keep-alive slaves must be spared), then boots every slave in parallel as its
//!   boot-up arrives: reads 0x1000 and the 0x1018 entries 0x1F84–0x1F88 expect, writes the
//!   slave's configuration steps and its heartbeat producer time, then starts it (or leaves that
//!   to the application, [`StartPolicy::Application`]).
//! - The configuration manager (CiA 302-3, `std`): [`SlaveConfig::from_dcf`] turns a slave's
//!   DCF into its configuration steps (every value that differs from the device's default,
//!   PDOs invalid while they are remapped); a refused write is reported per object
//!   ([`MasterEventKind::ConfigWriteAborted`]) and the rest is still written
//!   ([`WriteAborts::Continue`]). With an expected configuration date and time (0x1F26/0x1F27,
//!   [`ConfigurationStamp`]) a slave whose 0x1020 holds them is not written again; one that is
//!   configured gets them in its 0x1020 and, if asked for, stores its parameters (0x1010).
//!   The same configuration as a [`ConciseDcf`] written to the master's 0x1F22 sub n is
//!   applied at node n's boot.
//! - Program download (CiA 302-3): [`Master::download_program`] replaces a slave's program
//!   (stop, clear, image by block transfer, start, 0x1F56 against 0x1F55), with progress and
//!   outcome events ([`MasterEventKind::ProgramProgress`], [`MasterEventKind::ProgramDownloaded`]).
//! - Mandatory slaves (0x1F81 bit 3) gate the network start within the boot time (0x1F89); then
//!   the master enters operational itself (0x1F80 bit 2 clear) and starts the slaves, with one
//!   broadcast (bit 1) when that cannot start a slave that is not configured.
//! - A slave that boots again (power cycle, reset) is booted again; an error control loss (E,
//!   F, K) is reported and handled per 0x1F80 bits 4/6 (mandatory) or by waiting for the slave.
//! - 0x1F82: another node writes sub n (128: all) to have the master send an NMT command; a read
//!   gives the node's state as the master knows it.
//!
//! # Standby
//! A standby master ([`Master::set_active`]) sends no NMT, no SDO, no SYNC and no TIME (it
//! clears the producer bits of 0x1005/0x1012 while standby and restores them when active). It
//! keeps tracking states from the traffic, produces its heartbeat, and guards the slaves whose
//! 0x1F81 entry gives a guard time once it hears them (both masters of a redundant pair guard,
//! each counting the other's requests so that the slave's toggle bit checks out). Becoming
//! active does not reset anything: slaves seen operational (or stopped) are adopted as they are,
//! pre-operational ones are booted (identity, configuration, start per policy) unless their boot
//! is the application's (0x1F81 bit 2 clear: adopted as they are too), silent ones are probed.
//!
//! SDO accesses of the boot processes run on the client's sessions, one per slave; when all
//! are taken, slaves wait in a bounded FIFO ([`MasterStats::jobs_queued`]).
//!
//! # Example
//! A master and one slave on one wire, run as any driver runs them (what one sends the other
//! receives, time runs to the next deadline); the slave's start is left to the application (as
//! a slave-pair supervisor does with the members of a pair).
//!
//! ```
//! use duocan_core::master::{objects, BootPhase, Master, MasterConfig, SlaveConfig};
//! use duocan_core::master::StartPolicy;
//! use duocan_core::od::comm;
//! use duocan_core::{Device, Instant, NmtState, Node, NodeConfig, NodeId, Station};
//!
//! /// Runs two devices on one wire (port 0 of each, no delay) from `now` until `until`.
//! fn run(a: &mut impl Device, b: &mut impl Device, mut now: Instant, until: Instant) {
//!     while now <= until {
//!         let mut busy = true;
//!         while busy {
//!             busy = false;
//!             while let Some((_, f)) = a.poll_transmit() { b.handle_rx(now, 0, &f); busy = true; }
//!             while let Some((_, f)) = b.poll_transmit() { a.handle_rx(now, 0, &f); busy = true; }
//!             while a.poll_event().is_some() || b.poll_event().is_some() {}
//!         }
//!         let Some(next) = a.poll_timeout().into_iter().chain(b.poll_timeout()).min() else { break };
//!         now = next;
//!         a.handle_timeout(now);
//!         b.handle_timeout(now);
//!     }
//! }
//!
//! let five = NodeId::must(5);
//! let net = MasterConfig::new().slave(
//!     SlaveConfig::new(five)
//!         .mandatory()
//!         .heartbeat(100, 250)
//!         .write_u32(0x1005, 0, 0x80)
//!         .start(StartPolicy::Application),
//! );
//! let od = objects::master_dictionary(1, comm::Identity::default());
//! let mut m = Station::single(Master::new(NodeId::must(1), od, net).unwrap());
//! let slave = Node::new(NodeConfig::slave(five), comm::standard_dictionary(5, Default::default()));
//! let mut s = Station::single(slave);
//! s.machine.boot(Instant::ZERO);
//! m.machine.boot(Instant::ZERO);
//! // Configured at once on this wire without delay; the master takes the slave's state from
//! // its first heartbeat after the configuration (0x1017 = 100 ms).
//! run(&mut m, &mut s, Instant::ZERO, Instant::from_millis(120));
//!
//! let view = m.machine.slave(five);
//! assert_eq!(view.phase, BootPhase::Ready);
//! assert_eq!(view.state, Some(NmtState::PreOperational));
//! assert!(m.machine.network_started());
//!
//! let now = Instant::from_millis(120);
//! m.machine.start_slave(now, five).unwrap();
//! run(&mut m, &mut s, now, Instant::from_millis(125));
//! assert_eq!(s.machine.nmt_state(), NmtState::Operational);
//! ```

mod boot;
mod boot_run;
mod concise;
mod config;
#[cfg(feature = "std")]
mod dcf;
mod drive;
mod error_control;
mod events;
mod inputs;
mod network;
pub mod objects;
mod own;
use own::check_slave;
mod program;
mod program_run;
mod slaves;
mod slot_table;
mod srdo;
#[cfg(all(test, feature = "std"))]
mod usdo_tests;

pub use boot::{BootError, BootPhase, ErrorStatus, IdentityMismatch};
pub use concise::{
    validate as validate_concise, ConciseDcf, ConciseEntry, ConciseError, ConciseErrorKind,
    MAX_CONCISE_BYTES, MAX_CONCISE_ENTRIES,
};
pub use config::{
    Assignment, ConfigStep, ConfigurationStamp, ExpectedIdentity, MasterConfig, NmtStartup,
    SlaveConfig, StartPolicy, WriteAborts,
};
pub use events::{MasterError, MasterEvent, MasterEventKind, MasterStats, SlaveView};
pub use program::{
    ProgramAccess, ProgramDownload, ProgramDownloadError, ProgramErrorKind, ProgramReport,
    ProgramStep,
};

use crate::cia301::nmt::{NmtCommand, NmtState, NmtTarget};
use crate::cia301::pdo::Dir;
use crate::cia301::sdo::{DefaultBuffer, SdoClient, DEFAULT_LIMIT};
use crate::frame::cob_id::NodeId;
use crate::frame::instant::{earliest_of, Duration, Instant, TimeWatch};
use crate::frame::storage::Heap;
use crate::frame::Frame;
use crate::machine::Machine;
use crate::node::{Node, NodeConfig, ALL_NODES};
use crate::od::{comm, ObjectDictionary};
use crate::profile::{IdProfile, Predefined};
use alloc::collections::VecDeque;
use network::Network;
use slot_table::SlotTable;

/// NMT commands the master holds before the driver drains them, by default
/// ([`MasterConfig::nmt_queue`]).
pub const NMT_QUEUE: usize = 256;
/// Events the master holds before the application drains them, by default
/// ([`MasterConfig::event_queue`]).
pub const EVENT_QUEUE: usize = 1024;

/// TPDOs of a master's own node by default ([`MasterConfig::tpdos`]).
pub const TPDOS: usize = 4;
/// RPDOs of a master's own node by default ([`MasterConfig::rpdos`]): room for mirroring the
/// TPDOs of its slaves ([`crate::cia302::pdo_config::mirror`]), two for each board of a rack of
/// sixteen.
pub const RPDOS: usize = 64;
/// SDO client sessions of a master by default ([`MasterConfig::sdo_sessions`]): how many slaves
/// it configures at once (the others wait in its queue).
pub const SESSIONS: usize = 8;

/// The node inside a [`Master`]: it guards every node-ID (0x1F81 guard times); its PDO tables
/// are allocated once when the master is built, [`MasterConfig::tpdos`] TPDOs and
/// [`MasterConfig::rpdos`] RPDOs ([`TPDOS`] and [`RPDOS`] by default).
pub type MasterNode<D, P = Predefined> = Node<D, P, ALL_NODES, TPDOS, RPDOS, Heap>;

/// The SDO client inside a [`Master`], with the default buffers: its sessions are allocated
/// once, [`MasterConfig::sdo_sessions`] of them ([`SESSIONS`] by default).
pub type MasterSdoClient = SdoClient<DefaultBuffer, SESSIONS, Heap>;

/// A master on the railway 29-bit identifier profile, with a dictionary built at run time.
pub type RailwayMaster =
    Master<crate::od::DynamicDictionary, crate::profile::railway::RailwayProfile>;

/// A CiA 302-2 NMT master on one logical bus. `D` is its dictionary, `P` its identifier profile;
/// its node is a [`MasterNode`], its SDO client a [`MasterSdoClient`]. Their capacities are
/// configuration values ([`MasterConfig`]), allocated once when the master is built, so that
/// every master, supervisor and network type is spelled with these two parameters only.
pub struct Master<D, P = Predefined> {
    node: MasterNode<D, P>,
    sdo: MasterSdoClient,
    /// The client has no transfer running and nothing to send: it is left out of the frame
    /// path (a master of a hundred slaves mostly hears heartbeats).
    sdo_idle: bool,
    /// Per-node state, [`MasterConfig::max_slaves`] slots at most.
    slots: SlotTable,
    /// A lower bound of every slot's timers (probe, keep-alive wait, K watchdog).
    slot_timer: Option<Instant>,
    network: Network,
    active: bool,
    booted: bool,
    /// SYNC and TIME production wanted (0x1005/0x1012 bit 30) while active.
    produce_sync: bool,
    produce_time: bool,
    waiting: VecDeque<NodeId>,
    nmt_out: VecDeque<Frame>,
    nmt_capacity: usize,
    events: VecDeque<MasterEvent>,
    event_capacity: usize,
    stats: MasterStats,
    sdo_timeout: Duration,
    probe_interval: Duration,
    default_consumer_ms: u16,
    /// Program downloads under way.
    programs: usize,
    /// Notices the caller's clock stepping back (the clock contract).
    clock: TimeWatch,
}

impl<D: ObjectDictionary> Master<D> {
    /// A master with node-ID `node_id` on the predefined connection set and a 64 KiB SDO
    /// transfer limit. `od` must hold the master objects ([`objects::master_dictionary`]);
    /// `config`'s values are written into it.
    pub fn new(node_id: NodeId, od: D, config: MasterConfig) -> Result<Self, MasterError> {
        Master::with_parts(
            NodeConfig::master(node_id),
            od,
            Predefined,
            MasterSdoClient::with_sessions(DEFAULT_LIMIT, config.sdo_sessions),
            config,
        )
    }
}

impl<D: ObjectDictionary, P: IdProfile> Master<D, P> {
    /// A master from its parts: the node's configuration (its `auto_start` and `accept_nmt` are
    /// overridden: the master starts itself per 0x1F80 and obeys no NMT master), dictionary,
    /// identifier profile and SDO client (its transfer limit and the channels of that profile;
    /// its session table is allocated for [`MasterConfig::sdo_sessions`], so a client of
    /// another size is built anew with the same limit and channels).
    pub fn with_parts(
        node: NodeConfig,
        od: D,
        profile: P,
        sdo: MasterSdoClient,
        config: MasterConfig,
    ) -> Result<Self, MasterError> {
        let mut m = Master::unconfigured(node, od, profile, sdo, &config);
        m.configure(config)?;
        Ok(m)
    }

    /// [`Master::with_parts`] in two steps: the master with `config`'s capacities (queues,
    /// slots, SDO sessions, PDO tables) and settings (active, timeouts), nothing checked or
    /// written yet; [`Master::configure`] does the rest, before boot.
    ///
    /// Why two: this step cannot fail, so it returns the master itself, not a `Result`, and a
    /// caller can build it where it is to live. On a microcontroller a master is tens of
    /// kilobytes, and every move of it out of a `Result` is a copy on the stack at start-up;
    /// built in place inside its supervisor, there is none.
    pub fn unconfigured(
        node: NodeConfig,
        od: D,
        profile: P,
        sdo: MasterSdoClient,
        config: &MasterConfig,
    ) -> Self {
        let sessions = config.sdo_sessions.max(1);
        let sdo = if sdo.sessions() == sessions {
            sdo
        } else {
            MasterSdoClient::with_sessions(sdo.limit(), sessions).with_channels(sdo.channels())
        };
        let node_cfg = NodeConfig {
            auto_start: false,
            accept_nmt: false,
            ..node
        };
        Master {
            // More PDOs than CiA 301 has are cut to its maximum here; `configure` refuses them.
            node: MasterNode::with_pdo_capacity(node_cfg, od, profile, config.tpdos, config.rpdos),
            sdo,
            sdo_idle: false,
            // The slots, allocated once at their final size (`slot_table.rs`).
            slots: SlotTable::new(config.max_slaves),
            slot_timer: None,
            network: Network::Idle,
            active: config.active,
            booted: false,
            produce_sync: false,
            produce_time: false,
            waiting: VecDeque::with_capacity(127),
            // Allocated once here; the queues check their capacity before every push, so they
            // never grow (bounded memory on a heap-backed master too).
            nmt_out: VecDeque::with_capacity(config.nmt_queue.max(1)),
            nmt_capacity: config.nmt_queue.max(1),
            events: VecDeque::with_capacity(config.event_queue.max(1)),
            event_capacity: config.event_queue.max(1),
            stats: MasterStats::default(),
            sdo_timeout: config.sdo_timeout,
            probe_interval: config.probe_interval,
            default_consumer_ms: config.default_consumer_ms,
            programs: 0,
            clock: TimeWatch::new(),
        }
    }

    /// Checks `config` and writes it into the master's dictionary, once, before boot: the
    /// master objects must be there, the PDO counts within CiA 301's; the NMT start-up, boot
    /// time and each slave's assignment, expected identity and configuration stamp are
    /// written, and each slave gets its slot, as do the slaves the dictionary assigns (0x1F81)
    /// that `config` does not name, with their heartbeat consumers. `config` is the one given
    /// to [`Master::unconfigured`]: its capacities and settings were taken there.
    ///
    /// Everything that can be checked without writing is checked first (objects, PDO counts,
    /// each slave); a dictionary that then refuses a value, or a slave beyond the slots
    /// ([`MasterError::Refused`]) leaves what was written before it: build the master anew.
    /// After boot: [`MasterError::AlreadyBooted`].
    pub fn configure(&mut self, config: MasterConfig) -> Result<(), MasterError> {
        use objects::*;
        if self.booted {
            return Err(MasterError::AlreadyBooted);
        }
        for (index, sub) in [
            (NMT_STARTUP, 0),
            (BOOT_TIME, 0),
            (SLAVE_ASSIGNMENT, 127),
            (REQUEST_NMT, REQUEST_ALL),
            (DEVICE_TYPE_ID, 127),
            (VENDOR_ID, 127),
            (PRODUCT_CODE, 127),
            (REVISION_NUMBER, 127),
            (SERIAL_NUMBER, 127),
        ] {
            if self.node.od().get(index, sub).is_err() {
                return Err(MasterError::MissingObject { index, sub });
            }
        }
        let max = crate::cia301::pdo::params::MAX_PDOS as usize;
        for (dir, count) in [(Dir::Transmit, config.tpdos), (Dir::Receive, config.rpdos)] {
            if count > max {
                return Err(MasterError::TooManyPdos { dir, count });
            }
        }
        let own = self.node.id();
        for s in &config.slaves {
            check_slave(s, own)?;
        }
        let od = self.node.od_mut();
        let mut put = |index: u16, sub: u8, v: u32| {
            od.write_local(index, sub, &v.to_le_bytes())
                .map_err(|code| MasterError::Refused { index, sub, code })
        };
        put(NMT_STARTUP, 0, config.startup.0)?;
        put(BOOT_TIME, 0, config.boot_time_ms)?;
        for s in &config.slaves {
            let n = s.node.raw();
            put(SLAVE_ASSIGNMENT, n, s.assignment.0)?;
            put(DEVICE_TYPE_ID, n, s.identity.device_type)?;
            put(VENDOR_ID, n, s.identity.vendor)?;
            put(PRODUCT_CODE, n, s.identity.product)?;
            put(REVISION_NUMBER, n, s.identity.revision)?;
            put(SERIAL_NUMBER, n, s.identity.serial)?;
            if s.stamp.is_set() {
                put(EXPECTED_CONFIG_DATE, n, s.stamp.date)?;
                put(EXPECTED_CONFIG_TIME, n, s.stamp.time)?;
            }
        }
        for s in config.slaves {
            let n = s.node;
            self.slots.claim(n)?.cfg = s;
        }
        let producer = |od: &D, index| {
            od.get_u32(index, 0)
                .is_some_and(|v| v & crate::frame::cob_id::CobId::BIT30 != 0)
        };
        self.produce_sync = producer(self.node.od(), comm::SYNC_COB_ID);
        self.produce_time = producer(self.node.od(), comm::TIME_COB_ID);
        // Before boot the node reads its dictionary at boot, so plain stores suffice.
        for n in (1..=127u8).filter_map(NodeId::new) {
            if self.assignment(n).is_slave() {
                // Slaves the dictionary assigns that the configuration does not name need
                // their slot too.
                self.slots.claim(n)?;
                self.set_consumer(Instant::ZERO, n, true)?;
            }
        }
        if !self.active {
            self.set_producers(Instant::ZERO, false);
        }
        Ok(())
    }

    /// Powers the master on: boots its node and, if active, the network.
    pub fn boot(&mut self, now: Instant) {
        self.watch_own_clock(now);
        self.booted = true;
        self.node.boot(now);
        if self.acting() {
            self.boot_network(now);
        } else {
            self.self_start(now);
            let slaves: heapless::Vec<NodeId, 127> = self.assigned().collect();
            for n in slaves {
                self.slot_mut(n).phase = BootPhase::Observed;
            }
        }
        self.pump(now);
    }

    /// Makes the master active (it manages the network) or standby (it observes). Becoming
    /// active resets nothing: operational and stopped slaves are adopted, pre-operational ones
    /// booted without a reset (adopted if their boot is the application's, 0x1F81 bit 2 clear),
    /// silent ones probed. Becoming standby abandons the boot processes
    /// (transfers under way are aborted at once) and stops SYNC and TIME production.
    pub fn set_active(&mut self, now: Instant, active: bool) {
        if active == self.active {
            return;
        }
        self.active = active;
        self.emit(now, MasterEventKind::ActiveChanged { active });
        self.set_producers(now, active);
        if self.booted {
            if active {
                self.take_over(now);
            } else {
                self.stand_by(now);
            }
        }
        self.pump(now);
    }

    /// True if the master is active.
    pub fn is_active(&self) -> bool {
        self.active
    }

    /// Whether the master produces SYNC and TIME while active (bit 30 of 0x1005 and 0x1012
    /// follows the role; the identifiers, period and time base stay as configured). What a
    /// redundancy supervisor sets before the first takeover.
    pub fn set_production(&mut self, now: Instant, sync: bool, time: bool) {
        self.produce_sync = sync;
        self.produce_time = time;
        self.set_producers(now, self.active);
    }

    /// True if the network was started (every mandatory slave booted, or forced).
    pub fn network_started(&self) -> bool {
        matches!(self.network, Network::Started)
    }

    /// Starts the network now, whether or not every mandatory slave has booted: the master
    /// enters operational (0x1F80 bit 2 clear) and starts every configured slave.
    pub fn start_network(&mut self, now: Instant) -> Result<(), MasterError> {
        if !self.acting() {
            return Err(MasterError::Standby);
        }
        if !self.network_started() {
            self.start_network_now(now);
        }
        self.pump(now);
        Ok(())
    }

    /// Sends an NMT command. The boot processes follow: a reset slave is booted again when its
    /// boot-up arrives; a started slave is marked started.
    pub fn nmt(
        &mut self,
        now: Instant,
        cmd: NmtCommand,
        target: NmtTarget,
    ) -> Result<(), MasterError> {
        if !self.acting() {
            return Err(MasterError::Standby);
        }
        if target == NmtTarget::Node(self.node.id()) {
            return Err(MasterError::OwnNode(self.node.id()));
        }
        self.command(now, cmd, target)?;
        self.pump(now);
        Ok(())
    }

    /// Starts one slave (NMT start).
    pub fn start_slave(&mut self, now: Instant, node: NodeId) -> Result<(), MasterError> {
        self.nmt(now, NmtCommand::Start, NmtTarget::Node(node))
    }

    /// Resets one slave (NMT reset node); its boot process runs again at its boot-up.
    pub fn reset_slave(&mut self, now: Instant, node: NodeId) -> Result<(), MasterError> {
        self.nmt(now, NmtCommand::ResetNode, NmtTarget::Node(node))
    }

    /// Runs the boot process of one slave now, without resetting it: identity, configuration,
    /// then start per its policy.
    pub fn boot_slave(&mut self, now: Instant, node: NodeId) -> Result<(), MasterError> {
        if !self.acting() {
            return Err(MasterError::Standby);
        }
        if !self.assignment(node).is_slave() {
            return Err(MasterError::NotAssigned(node));
        }
        self.begin(now, node);
        self.pump(now);
        Ok(())
    }

    /// Adds or replaces a slave at run time: writes its 0x1F81/0x1F84–0x1F88 entries and its
    /// heartbeat consumer entry. An active master probes it at once (it is booted when it
    /// answers or sends its boot-up).
    pub fn add_slave(&mut self, now: Instant, cfg: SlaveConfig) -> Result<(), MasterError> {
        use objects::*;
        let n = cfg.node;
        check_slave(&cfg, self.node.id())?;
        self.slots.claim(n)?;
        let id = cfg.identity;
        let assignment = cfg.assignment.0;
        let stamp = cfg.stamp;
        self.slot_mut(n).cfg = cfg;
        if stamp.is_set() {
            self.write_own(now, EXPECTED_CONFIG_DATE, n.raw(), stamp.date)?;
            self.write_own(now, EXPECTED_CONFIG_TIME, n.raw(), stamp.time)?;
        }
        for (index, v) in [
            (DEVICE_TYPE_ID, id.device_type),
            (VENDOR_ID, id.vendor),
            (PRODUCT_CODE, id.product),
            (REVISION_NUMBER, id.revision),
            (SERIAL_NUMBER, id.serial),
            (SLAVE_ASSIGNMENT, assignment),
        ] {
            self.write_own(now, index, n.raw(), v)?;
        }
        self.pump(now);
        Ok(())
    }

    /// Changes who starts a slave once configured.
    pub fn set_start_policy(&mut self, node: NodeId, policy: StartPolicy) {
        self.slot_mut(node).cfg.start = policy;
    }

    /// What the master knows of one node (any node-ID, assigned or not).
    pub fn slave(&self, node: NodeId) -> SlaveView {
        let s = self.slot(node);
        SlaveView {
            node,
            assignment: self.assignment(node),
            state: self.view_state(node),
            missing: s.missing,
            phase: s.phase,
            last_error: s.last_error,
            boot_ups: s.boot_ups,
            start: s.cfg.start,
        }
    }

    /// Every assigned slave.
    pub fn slaves(&self) -> impl Iterator<Item = SlaveView> + '_ {
        self.assigned().map(|n| self.slave(n))
    }

    /// The master's configuration of a node, if it has a slot: every node-ID with
    /// [`MasterConfig::max_slaves`] at 127 (the default, a blank configuration for the nodes
    /// not configured), else the slaves only.
    pub fn slave_config(&self, node: NodeId) -> Option<&SlaveConfig> {
        self.slots.get(node).map(|s| &s.cfg)
    }

    /// The master's own node.
    pub fn node(&self) -> &MasterNode<D, P> {
        &self.node
    }
    /// The master's own node, for the application's own use (its dictionary, EMCY, TIME). NMT
    /// commands belong in [`Master::nmt`], so that the boot processes follow them.
    pub fn node_mut(&mut self) -> &mut MasterNode<D, P> {
        &mut self.node
    }
    /// The SDO client.
    pub fn sdo(&self) -> &MasterSdoClient {
        &self.sdo
    }
    /// The SDO client, for the application's own transfers; their results arrive as
    /// [`MasterEventKind::Sdo`]. A transfer to a slave being booted waits for the boot's.
    pub fn sdo_mut(&mut self) -> &mut MasterSdoClient {
        self.sdo_idle = false;
        &mut self.sdo
    }
    /// Counters.
    pub fn stats(&self) -> MasterStats {
        self.stats
    }
}
