//! What the master is told about the network: plain data, so that a CiA 306 DCF importer can
//! fill it as well as code can.
//!
//! The CiA 302-2 objects (0x1F80 NMT startup, 0x1F81 slave assignment, 0x1F84–0x1F88 expected
//! identity, 0x1F89 boot time) are written into the master's dictionary when the master is built
//! and read from there whenever they are used, so a configuration tool writing them over SDO
//! changes the master's behaviour exactly as CiA 302-2 says. What those objects cannot say (the
//! list of SDO writes that configures a slave, its heartbeat, its start policy) is in
//! [`SlaveConfig`].
//!
//! ```
//! use duocan_core::master::{Assignment, ExpectedIdentity, MasterConfig, NmtStartup, SlaveConfig};
//! use duocan_core::NodeId;
//!
//! let net = MasterConfig::new()
//!     .startup(NmtStartup::MASTER.with(NmtStartup::START_ALL))
//!     .boot_time_ms(2_000)
//!     .slave(
//!         SlaveConfig::new(NodeId::must(5))
//!             .mandatory()
//!             .identity(ExpectedIdentity { vendor: 0x1234, product: 5, ..Default::default() })
//!             .heartbeat(100, 250)
//!             .write_u16(0x2000, 1, 500),
//!     );
//! assert_eq!(net.slaves[0].assignment.0 & Assignment::MANDATORY, Assignment::MANDATORY);
//! ```

use crate::cia301::pdo::Dir;
use crate::cia302::pdo_config::PdoConfig;
use crate::frame::cob_id::NodeId;
use crate::frame::instant::Duration;
use alloc::boxed::Box;
use alloc::vec::Vec;

/// 0x1F80 NMT startup: how the master starts itself and the network.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NmtStartup(pub u32);

impl NmtStartup {
    /// Bit 0: this device is the NMT master (clear: it manages nothing, it only observes).
    pub const MASTER: NmtStartup = NmtStartup(1 << 0);
    /// Bit 1: start the slaves with one "start all nodes" broadcast instead of one command each.
    pub const START_ALL: NmtStartup = NmtStartup(1 << 1);
    /// Bit 2: the master does not enter operational by itself (the application does).
    pub const NO_SELF_START: NmtStartup = NmtStartup(1 << 2);
    /// Bit 3: the master does not start the slaves (the application does).
    pub const NO_SLAVE_START: NmtStartup = NmtStartup(1 << 3);
    /// Bit 4: an error control event of a mandatory slave resets communication of all nodes.
    pub const RESET_ALL: NmtStartup = NmtStartup(1 << 4);
    /// Bit 5: the master takes part in flying-master negotiation (run by the supervisor).
    pub const FLYING_MASTER: NmtStartup = NmtStartup(1 << 5);
    /// Bit 6: an error control event of a mandatory slave stops all nodes.
    pub const STOP_ALL: NmtStartup = NmtStartup(1 << 6);

    /// These bits and `other`'s.
    #[must_use]
    pub const fn with(self, other: NmtStartup) -> NmtStartup {
        NmtStartup(self.0 | other.0)
    }
    /// True if every bit of `bits` is set.
    pub const fn has(self, bits: NmtStartup) -> bool {
        self.0 & bits.0 == bits.0
    }
}

impl Default for NmtStartup {
    /// An NMT master that starts itself and each slave individually.
    fn default() -> Self {
        NmtStartup::MASTER
    }
}

/// A 0x1F81 slave assignment value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Assignment(pub u32);

impl Assignment {
    /// Bit 0: the node is a slave of this master.
    pub const SLAVE: u32 = 1 << 0;
    /// Bit 2: on a boot-up or an error control event, run the boot process again by itself
    /// (clear: only report it; the first boot of the network runs regardless).
    pub const BOOT: u32 = 1 << 2;
    /// Bit 3: mandatory slave: the network is not started without it.
    pub const MANDATORY: u32 = 1 << 3;
    /// Bit 4: keep alive: never reset by the master; adopted as it is when found operational.
    pub const KEEP_ALIVE: u32 = 1 << 4;

    /// An optional slave that is booted again whenever it boots up.
    #[must_use]
    pub const fn slave() -> Assignment {
        Assignment(Self::SLAVE | Self::BOOT)
    }
    /// True if the node is a slave of this master.
    pub const fn is_slave(self) -> bool {
        self.0 & Self::SLAVE != 0
    }
    /// True if boot-ups and error control events start the boot process again.
    pub const fn reboots(self) -> bool {
        self.0 & Self::BOOT != 0
    }
    /// True for a mandatory slave.
    pub const fn is_mandatory(self) -> bool {
        self.is_slave() && self.0 & Self::MANDATORY != 0
    }
    /// True for a keep-alive slave.
    pub const fn is_keep_alive(self) -> bool {
        self.is_slave() && self.0 & Self::KEEP_ALIVE != 0
    }
    /// Bits 8–15: node guarding retry factor (life time factor).
    pub const fn retry_factor(self) -> u8 {
        (self.0 >> 8) as u8
    }
    /// Bits 16–31: node guarding time in ms (0: the master does not guard the slave).
    pub const fn guard_time_ms(self) -> u16 {
        (self.0 >> 16) as u16
    }
    /// With node guarding every `guard_time_ms`, lost after `retry_factor` silent periods.
    #[must_use]
    pub const fn guarded(self, guard_time_ms: u16, retry_factor: u8) -> Assignment {
        Assignment((self.0 & 0xFF) | ((retry_factor as u32) << 8) | ((guard_time_ms as u32) << 16))
    }
}

/// What a slave must say it is (0x1F84–0x1F88 sub n). Zero means "not checked", as in CiA 302-2.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ExpectedIdentity {
    /// 0x1000 device type (0x1F84).
    pub device_type: u32,
    /// 0x1018 sub 1 vendor-ID (0x1F85).
    pub vendor: u32,
    /// 0x1018 sub 2 product code (0x1F86).
    pub product: u32,
    /// 0x1018 sub 3 revision number (0x1F87).
    pub revision: u32,
    /// 0x1018 sub 4 serial number (0x1F88).
    pub serial: u32,
}

/// When a slave's configuration was made (CiA 301 0x1020, CiA 302-3 0x1F26/0x1F27): a slave
/// whose 0x1020 holds both values is configured already and is not written again; after
/// writing a slave's configuration the master writes them to its 0x1020. Zero for both: not
/// checked nor written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct ConfigurationStamp {
    /// Days since 1984-01-01 (0x1020 sub 1, 0x1F26 sub n).
    pub date: u32,
    /// Milliseconds after midnight (0x1020 sub 2, 0x1F27 sub n).
    pub time: u32,
}

impl ConfigurationStamp {
    /// True when checked and written (either value non-zero).
    #[must_use]
    pub const fn is_set(self) -> bool {
        self.date != 0 || self.time != 0
    }
}

/// Who starts a slave once it is configured.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum StartPolicy {
    /// The master starts it (at the network start, or at once if the network runs already).
    #[default]
    Auto,
    /// The application starts it ([`super::Master::start_slave`]); the master reports
    /// [`super::MasterEventKind::SlaveConfigured`] and leaves it pre-operational. What a
    /// slave-pair supervisor uses, so that only the active member of a pair runs.
    Application,
}

/// What the boot process does when the slave refuses (aborts) a [`ConfigStep::Write`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum WriteAborts {
    /// The boot fails there (status J, [`super::MasterEventKind::ConfigFailed`]): the steps
    /// were written for each other, and the slave is not started half configured.
    #[default]
    Stop,
    /// The abort is reported ([`super::MasterEventKind::ConfigWriteAborted`], with the object
    /// and the abort code) and the other steps are still written: the configuration manager's
    /// way with a DCF, whose entries are independent values. A slave that does not answer
    /// still fails the boot; PDO steps ([`ConfigStep::Pdo`]) still fail it as their
    /// configurator decides.
    Continue,
}

/// One step of a slave's configuration.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ConfigStep {
    /// An SDO download of `data` (little-endian, as a DCF `ParameterValue` encodes) to
    /// (`index`, `sub`).
    Write {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The value's bytes.
        data: Vec<u8>,
    },
    /// One of the slave's PDOs, configured by a [`PdoConfigurator`](crate::cia302::pdo_config::PdoConfigurator)
    /// (CiA 301 order: disable, parameters, mapping, enable; the fallback a published embedded master used for devices
    /// that refuse to disable a PDO already configured as wanted).
    Pdo {
        /// The slave's side: [`Dir::Transmit`] for one of its TPDOs.
        dir: Dir,
        /// PDO number, 1–512 (TPDO1 is 0x1800/0x1A00).
        pdo: u16,
        /// What it must become (boxed: a full mapping is 64 entries, a write step a few bytes).
        config: Box<PdoConfig>,
    },
}

/// Everything the master does to one slave beyond what its 0x1F8x entries say.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct SlaveConfig {
    /// The slave.
    pub node: NodeId,
    /// Its 0x1F81 value.
    pub assignment: Assignment,
    /// Its 0x1F84–0x1F88 values.
    pub identity: ExpectedIdentity,
    /// Producer heartbeat time written to the slave's 0x1017 after the other steps; `None`
    /// leaves 0x1017 alone.
    pub heartbeat_producer_ms: Option<u16>,
    /// The master's consumer time for it (its 0x1016 entry); 0: use the network default.
    pub heartbeat_consumer_ms: u16,
    /// The configuration, in order.
    pub steps: Vec<ConfigStep>,
    /// Who starts it.
    pub start: StartPolicy,
    /// What a refused write does to the boot.
    pub write_aborts: WriteAborts,
    /// Its 0x1F26/0x1F27 values: the configuration's date and time.
    pub stamp: ConfigurationStamp,
    /// After writing the configuration (and the stamp), have the slave store it (0x1010 sub 1
    /// "save"), so that it comes back configured after a reset or power cycle.
    pub store: bool,
}

impl SlaveConfig {
    /// An optional slave, identity unchecked, nothing configured, started by the master.
    #[must_use]
    pub const fn new(node: NodeId) -> SlaveConfig {
        SlaveConfig {
            node,
            assignment: Assignment::slave(),
            identity: ExpectedIdentity {
                device_type: 0,
                vendor: 0,
                product: 0,
                revision: 0,
                serial: 0,
            },
            heartbeat_producer_ms: None,
            heartbeat_consumer_ms: 0,
            steps: Vec::new(),
            start: StartPolicy::Auto,
            write_aborts: WriteAborts::Stop,
            stamp: ConfigurationStamp { date: 0, time: 0 },
            store: false,
        }
    }
    /// Mandatory: the network does not start without it.
    #[must_use]
    pub fn mandatory(mut self) -> SlaveConfig {
        self.assignment.0 |= Assignment::MANDATORY;
        self
    }
    /// Keep alive: never reset; adopted when found operational.
    #[must_use]
    pub fn keep_alive(mut self) -> SlaveConfig {
        self.assignment.0 |= Assignment::KEEP_ALIVE;
        self
    }
    /// The whole 0x1F81 entry at once (bits set by [`SlaveConfig::mandatory`] and
    /// [`SlaveConfig::keep_alive`] included): for guarding and other bits without a builder.
    #[must_use]
    pub fn with_assignment(mut self, assignment: Assignment) -> SlaveConfig {
        self.assignment = assignment;
        self
    }
    /// The identity to check.
    #[must_use]
    pub fn identity(mut self, identity: ExpectedIdentity) -> SlaveConfig {
        self.identity = identity;
        self
    }
    /// The slave produces a heartbeat every `producer_ms`; the master expects one within
    /// `consumer_ms`.
    #[must_use]
    pub fn heartbeat(mut self, producer_ms: u16, consumer_ms: u16) -> SlaveConfig {
        self.heartbeat_producer_ms = Some(producer_ms);
        self.heartbeat_consumer_ms = consumer_ms;
        self
    }
    /// Who starts it.
    #[must_use]
    pub fn start(mut self, policy: StartPolicy) -> SlaveConfig {
        self.start = policy;
        self
    }
    /// What a refused write does to the boot.
    #[must_use]
    pub fn with_write_aborts(mut self, policy: WriteAborts) -> SlaveConfig {
        self.write_aborts = policy;
        self
    }
    /// The configuration's date and time (0x1F26/0x1F27): a slave whose 0x1020 holds them is
    /// not written again; one that is configured gets them in its 0x1020.
    #[must_use]
    pub fn with_stamp(mut self, stamp: ConfigurationStamp) -> SlaveConfig {
        self.stamp = stamp;
        self
    }
    /// Has the slave store its configuration (0x1010 sub 1 "save") once written.
    #[must_use]
    pub fn with_store(mut self, store: bool) -> SlaveConfig {
        self.store = store;
        self
    }
    /// Adds an SDO write of raw bytes.
    #[must_use]
    pub fn write(mut self, index: u16, sub: u8, data: &[u8]) -> SlaveConfig {
        self.steps.push(ConfigStep::Write {
            index,
            sub,
            data: data.to_vec(),
        });
        self
    }
    /// Adds an SDO write of an UNSIGNED8.
    #[must_use]
    pub fn write_u8(self, index: u16, sub: u8, v: u8) -> SlaveConfig {
        self.write(index, sub, &[v])
    }
    /// Adds an SDO write of an UNSIGNED16.
    #[must_use]
    pub fn write_u16(self, index: u16, sub: u8, v: u16) -> SlaveConfig {
        self.write(index, sub, &v.to_le_bytes())
    }
    /// Adds an SDO write of an UNSIGNED32.
    #[must_use]
    pub fn write_u32(self, index: u16, sub: u8, v: u32) -> SlaveConfig {
        self.write(index, sub, &v.to_le_bytes())
    }
    /// Configures the slave's TPDO `pdo` (1–512).
    #[must_use]
    pub fn tpdo(mut self, pdo: u16, config: PdoConfig) -> SlaveConfig {
        self.steps.push(ConfigStep::Pdo {
            dir: Dir::Transmit,
            pdo,
            config: Box::new(config),
        });
        self
    }
    /// Configures the slave's RPDO `pdo` (1–512).
    #[must_use]
    pub fn rpdo(mut self, pdo: u16, config: PdoConfig) -> SlaveConfig {
        self.steps.push(ConfigStep::Pdo {
            dir: Dir::Receive,
            pdo,
            config: Box::new(config),
        });
        self
    }
}

/// The whole network as the master sees it.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct MasterConfig {
    /// 0x1F80.
    pub startup: NmtStartup,
    /// 0x1F89: how long mandatory slaves have to boot, in ms (0: no limit).
    pub boot_time_ms: u32,
    /// Start as the active master (false: a standby that only observes until
    /// [`super::Master::set_active`]).
    pub active: bool,
    /// How long the master waits for each SDO answer of a slave.
    pub sdo_timeout: Duration,
    /// How often the master asks an assigned slave that has not been heard (reads 0x1000), in
    /// case its boot-up was lost or it was reset by someone else; zero: never.
    pub probe_interval: Duration,
    /// Consumer heartbeat time for slaves whose [`SlaveConfig`] gives none (0: not monitored).
    pub default_consumer_ms: u16,
    /// The slaves.
    pub slaves: Vec<SlaveConfig>,
    /// Events the master holds before the application drains them (default
    /// [`EVENT_QUEUE`](super::EVENT_QUEUE)); allocated once when the master is built, never
    /// grown: an event beyond it is dropped and counted.
    pub event_queue: usize,
    /// NMT commands the master holds before the driver drains them (default
    /// [`NMT_QUEUE`](super::NMT_QUEUE)); allocated once, never grown.
    pub nmt_queue: usize,
    /// TPDOs of the master's own node (default [`TPDOS`](super::TPDOS), at most 512); allocated
    /// once when the master is built, never grown.
    pub tpdos: usize,
    /// RPDOs of the master's own node, room for mirroring its slaves' TPDOs
    /// ([`crate::cia302::pdo_config::mirror`]; default [`RPDOS`](super::RPDOS), at most 512);
    /// allocated once, never grown.
    pub rpdos: usize,
    /// SDO client sessions: how many slaves the master configures at once, the others waiting
    /// in its queue, and how many transfers the application can run beside them (default
    /// [`SESSIONS`](super::SESSIONS), at least 1); allocated once, never grown.
    pub sdo_sessions: usize,
    /// Nodes the master keeps a slot for (its configuration, boot process and timers, about
    /// 250 bytes each), at most 127 (the default: every node-ID, slave or not). Below, only
    /// slaves get one, and a slave beyond it is refused ([`MasterError::TooManySlaves`]);
    /// allocated once when the master is built, never grown.
    ///
    /// [`MasterError::TooManySlaves`]: super::MasterError::TooManySlaves
    pub max_slaves: usize,
}

impl Default for MasterConfig {
    fn default() -> Self {
        MasterConfig {
            startup: NmtStartup::default(),
            boot_time_ms: 0,
            active: true,
            sdo_timeout: Duration::from_millis(500),
            probe_interval: Duration::from_millis(1_000),
            default_consumer_ms: 0,
            slaves: Vec::new(),
            event_queue: super::EVENT_QUEUE,
            nmt_queue: super::NMT_QUEUE,
            tpdos: super::TPDOS,
            rpdos: super::RPDOS,
            sdo_sessions: super::SESSIONS,
            max_slaves: 127,
        }
    }
}

impl MasterConfig {
    /// An active NMT master with no slaves (see [`Default`]).
    #[must_use]
    pub fn new() -> MasterConfig {
        MasterConfig::default()
    }
    /// Sets 0x1F80.
    #[must_use]
    pub fn startup(mut self, startup: NmtStartup) -> MasterConfig {
        self.startup = startup;
        self
    }
    /// Sets 0x1F89.
    #[must_use]
    pub fn boot_time_ms(mut self, ms: u32) -> MasterConfig {
        self.boot_time_ms = ms;
        self
    }
    /// Starts as a standby master.
    #[must_use]
    pub fn standby(mut self) -> MasterConfig {
        self.active = false;
        self
    }
    /// Sets the SDO timeout.
    #[must_use]
    pub fn sdo_timeout(mut self, t: Duration) -> MasterConfig {
        self.sdo_timeout = t;
        self
    }
    /// Sets the probe interval.
    #[must_use]
    pub fn probe_interval(mut self, t: Duration) -> MasterConfig {
        self.probe_interval = t;
        self
    }
    /// Sets the default consumer heartbeat time.
    #[must_use]
    pub fn default_consumer_ms(mut self, ms: u16) -> MasterConfig {
        self.default_consumer_ms = ms;
        self
    }
    /// Sets the event queue's capacity (at least 1).
    #[must_use]
    pub fn event_queue(mut self, capacity: usize) -> MasterConfig {
        self.event_queue = capacity;
        self
    }
    /// Sets the NMT command queue's capacity (at least 1).
    #[must_use]
    pub fn nmt_queue(mut self, capacity: usize) -> MasterConfig {
        self.nmt_queue = capacity;
        self
    }
    /// Sets how many TPDOs the master's own node runs (at most 512).
    #[must_use]
    pub fn with_tpdos(mut self, tpdos: usize) -> MasterConfig {
        self.tpdos = tpdos;
        self
    }
    /// Sets how many RPDOs the master's own node runs (at most 512).
    #[must_use]
    pub fn with_rpdos(mut self, rpdos: usize) -> MasterConfig {
        self.rpdos = rpdos;
        self
    }
    /// Sets how many SDO transfers the master runs at once (at least 1).
    #[must_use]
    pub fn with_sdo_sessions(mut self, sessions: usize) -> MasterConfig {
        self.sdo_sessions = sessions;
        self
    }
    /// Sets how many nodes the master keeps a slot for (at most 127): the slaves a small
    /// master runs, so that its heap holds no slots for node-IDs it never uses.
    #[must_use]
    pub fn max_slaves(mut self, slots: usize) -> MasterConfig {
        self.max_slaves = slots;
        self
    }
    /// Adds (or replaces) a slave.
    #[must_use]
    pub fn slave(mut self, slave: SlaveConfig) -> MasterConfig {
        self.slaves.retain(|s| s.node != slave.node);
        self.slaves.push(slave);
        self
    }
}
