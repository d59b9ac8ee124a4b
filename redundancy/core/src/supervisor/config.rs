//! How a [`Supervisor`](super::Supervisor) is set up.

use crate::pair::MAX_PAIRS;
use crate::supervisor::audit::AUDIT_CAPACITY;
use crate::supervisor::flying_master::{FlyingMasterConfig, Rank, MAX_PEERS};
use crate::supervisor::pairs::{PairsConfig, COMMAND_QUEUE};
use duocan_core::{Duration, NodeId};
use heapless::Vec;

/// Events the supervisor can hold before the application drains them, by default
/// ([`SupervisorConfig::event_queue`]).
pub const EVENT_QUEUE: usize = 1024;

/// How a supervisor is set up. The master's own settings (0x1F80, SDO timeout, probe
/// interval, the slaves that are no pair members) are the
/// [`MasterConfig`](duocan_core::master::MasterConfig) it was built with.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
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
    /// TIME period while active (zero: TIME once at each takeover only).
    pub time_period: Duration,
    /// Events the supervisor holds before the application drains them (default 1,024);
    /// allocated once when the supervisor is built, never grown: an event beyond it is dropped
    /// and counted.
    pub event_queue: usize,
    /// Pairs the supervisor takes (default and most [`MAX_PAIRS`]); the pair table is
    /// allocated once for them when the supervisor is built.
    pub pair_capacity: usize,
    /// Commands and events the pair table holds between two drains (default
    /// [`pairs::COMMAND_QUEUE`](crate::supervisor::pairs::COMMAND_QUEUE), enough for every
    /// member of [`MAX_PAIRS`] pairs failing at one instant); allocated once, never grown.
    pub pair_queue: usize,
    /// Records the audit trail keeps before it overwrites the oldest (default
    /// [`AUDIT_CAPACITY`]); allocated once, never grown.
    pub audit_capacity: usize,
    /// How often the active supervisor looks for a replacement board that arrived without a
    /// node-ID while a pair member is missing (LSS identify non-configured, then fastscan);
    /// `None` (the default): never, no LSS frame is sent.
    pub lss_period: Option<Duration>,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl SupervisorConfig {
    /// The configuration with [`flying`](Self::flying) replaced.
    #[must_use]
    pub fn with_flying(mut self, flying: FlyingMasterConfig) -> Self {
        self.flying = flying;
        self
    }
    /// The configuration with [`pairs`](Self::pairs) replaced.
    #[must_use]
    pub fn with_pairs(mut self, pairs: PairsConfig) -> Self {
        self.pairs = pairs;
        self
    }
    /// The configuration with [`heartbeat`](Self::heartbeat) replaced.
    #[must_use]
    pub fn with_heartbeat(mut self, heartbeat: Duration) -> Self {
        self.heartbeat = heartbeat;
        self
    }
    /// The configuration with [`sync_period`](Self::sync_period) replaced.
    #[must_use]
    pub fn with_sync_period(mut self, sync_period: Duration) -> Self {
        self.sync_period = sync_period;
        self
    }
    /// The configuration with [`time_period`](Self::time_period) replaced.
    #[must_use]
    pub fn with_time_period(mut self, time_period: Duration) -> Self {
        self.time_period = time_period;
        self
    }
    /// The configuration with [`lss_period`](Self::lss_period) set: board replacement by LSS.
    #[must_use]
    pub fn with_lss(mut self, period: Duration) -> Self {
        self.lss_period = Some(period);
        self
    }
    /// The configuration with [`event_queue`](Self::event_queue) replaced (at least 1).
    #[must_use]
    pub fn with_event_queue(mut self, capacity: usize) -> Self {
        self.event_queue = capacity;
        self
    }
    /// The configuration with [`pair_capacity`](Self::pair_capacity) replaced (at most
    /// [`MAX_PAIRS`]).
    #[must_use]
    pub fn with_pair_capacity(mut self, pairs: usize) -> Self {
        self.pair_capacity = pairs;
        self
    }
    /// The configuration with [`pair_queue`](Self::pair_queue) replaced (at least 1).
    #[must_use]
    pub fn with_pair_queue(mut self, capacity: usize) -> Self {
        self.pair_queue = capacity;
        self
    }
    /// The configuration with [`audit_capacity`](Self::audit_capacity) replaced (at least 1).
    #[must_use]
    pub fn with_audit_capacity(mut self, records: usize) -> Self {
        self.audit_capacity = records;
        self
    }
}

impl SupervisorConfig {
    /// A master of `priority` at `node` with a heartbeat of `heartbeat` and a master-heartbeat
    /// timeout of `master_timeout`, SYNC every `sync_period`; the 0x1F90 defaults otherwise.
    #[must_use]
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
            // The supervisor sees the active master's SDO confirmations: a board's own default
            // heartbeat is no sign of its configuration.
            pairs: PairsConfig {
                shadow_join_on_heartbeat: false,
                ..PairsConfig::default()
            },
            heartbeat,
            sync_period,
            time_period: Duration::ZERO,
            event_queue: EVENT_QUEUE,
            pair_capacity: MAX_PAIRS,
            pair_queue: COMMAND_QUEUE,
            audit_capacity: AUDIT_CAPACITY,
            lss_period: None,
        }
    }
    /// With another master-capable device.
    #[must_use]
    pub fn with_peer(mut self, priority: u8, node: NodeId) -> Self {
        let _ = self.peers.push(Rank::new(priority, node));
        self
    }
}
