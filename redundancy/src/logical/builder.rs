//! Building a redundant network from named settings.
//!
//! [`RedundantNetworkBuilder`] gathers what a redundant master needs (its node-ID and priority,
//! its heartbeat, the master-heartbeat timeout, the SYNC period, the board pairs and the other
//! masters) and builds the whole stack under a [`LogicalNetwork`] in one call: the CiA 302-2
//! master with its dictionary, the [`Supervisor`], the [`DualBus`] and the
//! [`SupervisedStation`]. Every setting has a default; every bad one is a [`RedundantError`]
//! naming it, found before anything is built.
//!
//! The identifier profile is a setting too ([`RedundantNetworkBuilder::profile`]): the network
//! [`build`](RedundantNetworkBuilder::build) returns names the predefined set in its type, as
//! every caller that never chose one expects; [`build_profiled`](RedundantNetworkBuilder::build_profiled)
//! (what the async handle runs) returns one on a [`NetProfile`], whichever it holds. On the
//! railway 29-bit scheme the master's dictionary gets the railway communication entries and
//! its SDO client the railway channels of each node.

use super::error::{RedundantError, Role};
use super::{LogicalNetwork, NetProfile};
use crate::link::config::DualBusConfig;
use crate::link::dual_bus::DualBus;
use crate::pair::{PairSpec, MAX_PAIRS};
use crate::station::SupervisedStation;
use crate::supervisor::flying_master::MAX_PEERS;
use crate::supervisor::pairs::PairsConfig;
use crate::supervisor::{Supervisor, SupervisorConfig};
use crate::{FrameClassifier, LinkMode};
use alloc::boxed::Box;
use alloc::vec::Vec;
use duocan::master::{objects, Master, MasterConfig, MasterSdoClient, SlaveConfig};
use duocan::od::{comm, DynamicDictionary};
use duocan::profile::{IdProfile, Predefined};
use duocan::sdo::{Channel, DEFAULT_LIMIT};
use duocan::{Duration, Instant, NodeConfig, NodeId};

/// This master's heartbeat unless [`RedundantNetworkBuilder::heartbeat`] says otherwise.
pub const DEFAULT_HEARTBEAT: Duration = Duration::from_millis(100);
/// The master-heartbeat timeout unless [`RedundantNetworkBuilder::master_timeout`] says
/// otherwise: a standby takes over when the active master was silent this long.
pub const DEFAULT_MASTER_TIMEOUT: Duration = Duration::from_millis(300);

/// The named settings of a redundant network (times as `duocan::Duration` or
/// `std::time::Duration`, whichever the caller has); start with
/// [`LogicalNetwork::builder`] (or `RedundantNetwork::builder()` with the `tokio` feature),
/// finish with [`build`](Self::build) (the sans-IO [`LogicalNetwork`], for the simulator or an
/// embedded driver) or, with `tokio`, `open` / `open_named` (an async handle).
///
/// | setting | default | what it is |
/// | --- | --- | --- |
/// | [`node_id`](Self::node_id) | 1 | this master's node-ID |
/// | [`priority`](Self::priority) | 0 | its flying-master priority (lower wins; then the lower node-ID) |
/// | [`heartbeat`](Self::heartbeat) | 100 ms | its heartbeat producer time |
/// | [`master_timeout`](Self::master_timeout) | 300 ms | silence of the active master after which a standby takes over |
/// | [`sync`](Self::sync) | none | SYNC period while active |
/// | [`time`](Self::time) | none | TIME period while active (this machine's clock) |
/// | [`pair`](Self::pair) | none | an A/B board pair |
/// | [`pair_heartbeat`](Self::pair_heartbeat) | 100 ms | heartbeat configured into every pair member |
/// | [`pair_timeout`](Self::pair_timeout) | 300 ms | silence of a member after which it has failed |
/// | [`boot_timeout`](Self::boot_timeout) | 5 s | a member not heard at all this long after power-on or a reset is reported (`NotHeard`) |
/// | [`peer_master`](Self::peer_master) | none | another master-capable device |
/// | [`member_config`](Self::member_config) | heartbeat only | what the master configures into a pair member at boot (a DCF's values: `SlaveConfig::from_dcf`) |
/// | [`link`](Self::link) | active-active, guard period = the shorter heartbeat | the dual-bus layer |
/// | [`master`](Self::master) | `MasterConfig::new()` | the CiA 302-2 master's own settings (other slaves, SDO timeout, queues) |
/// | [`profile`](Self::profile) | the predefined set | the identifier profile ([`NetProfile`]: the predefined set or the railway 29-bit scheme) |
/// | [`with_fd`](Self::with_fd) (feature `fd`) | classic | a CANopen FD network: both ports CAN FD, the master serving USDO, the door's reads and writes over USDO from the client node-ID given; heartbeats only |
///
/// ```
/// use duocan::Duration;
/// use duocan_redundancy::{LogicalNetwork, RedundantError, Role};
///
/// let ms = Duration::from_millis;
/// let net = LogicalNetwork::builder()
///     .node_id(1)
///     .heartbeat(ms(20))
///     .master_timeout(ms(50))
///     .sync(ms(10))
///     .pair(0x10, 0x50)
///     .peer_master(2)
///     .build()?;
/// assert_eq!(net.pairs().count(), 1);
/// // Bad settings are errors, found before anything is built.
/// let e = LogicalNetwork::builder().pair(0x10, 0x10).build().unwrap_err();
/// assert!(matches!(e, RedundantError::NodeTwice { second: Role::PairMember, .. }));
/// # Ok::<(), RedundantError>(())
/// ```
#[derive(Clone, Debug)]
#[must_use]
pub struct RedundantNetworkBuilder {
    node_id: u8,
    priority: u8,
    heartbeat: Duration,
    master_timeout: Duration,
    sync: Option<Duration>,
    time: Option<Duration>,
    pair_heartbeat: Duration,
    pair_timeout: Duration,
    boot_timeout: Duration,
    pairs: Vec<(u8, u8)>,
    peers: Vec<(u8, u8)>,
    members: Vec<SlaveConfig>,
    link: Option<DualBusConfig>,
    master: MasterConfig,
    profile: NetProfile,
    /// A CANopen FD network: the door's USDO client node-ID.
    fd: Option<u8>,
}

impl Default for RedundantNetworkBuilder {
    fn default() -> Self {
        RedundantNetworkBuilder {
            node_id: 1,
            priority: 0,
            heartbeat: DEFAULT_HEARTBEAT,
            master_timeout: DEFAULT_MASTER_TIMEOUT,
            sync: None,
            time: None,
            pair_heartbeat: DEFAULT_HEARTBEAT,
            pair_timeout: DEFAULT_MASTER_TIMEOUT,
            boot_timeout: PairsConfig::default().boot_timeout,
            pairs: Vec::new(),
            peers: Vec::new(),
            members: Vec::new(),
            link: None,
            master: MasterConfig::new(),
            profile: NetProfile::predefined(),
            fd: None,
        }
    }
}

impl LogicalNetwork<DynamicDictionary, Predefined> {
    /// The builder of a redundant network, every setting at its default.
    pub fn builder() -> RedundantNetworkBuilder {
        RedundantNetworkBuilder::default()
    }
}

impl RedundantNetworkBuilder {
    /// This master's node-ID (1–127; default 1).
    pub fn node_id(mut self, id: u8) -> Self {
        self.node_id = id;
        self
    }
    /// This master's flying-master priority (0x1F90 sub 3; lower wins, default 0).
    pub fn priority(mut self, priority: u8) -> Self {
        self.priority = priority;
        self
    }
    /// This master's heartbeat producer time (default 100 ms).
    pub fn heartbeat(mut self, period: impl Into<Duration>) -> Self {
        self.heartbeat = period.into();
        self
    }
    /// How long the active master may be silent before a standby takes over (default 300 ms;
    /// longer than the heartbeat).
    pub fn master_timeout(mut self, timeout: impl Into<Duration>) -> Self {
        self.master_timeout = timeout.into();
        self
    }
    /// The SYNC period while this master is active (default: no SYNC).
    pub fn sync(mut self, period: impl Into<Duration>) -> Self {
        self.sync = Some(period.into());
        self
    }
    /// The TIME period while this master is active (CiA 301 TIME, 0x1012), from its takeover on:
    /// the time of day of its clock, set from this machine's wall clock (UTC) when the network
    /// is built, or continued from the TIME it consumed as a standby. Default: no TIME.
    pub fn time(mut self, period: impl Into<Duration>) -> Self {
        self.time = Some(period.into());
        self
    }
    /// An A/B board pair: node `a` is member A, node `b` member B.
    pub fn pair(mut self, a: u8, b: u8) -> Self {
        self.pairs.push((a, b));
        self
    }
    /// The heartbeat configured into every pair member (default 100 ms).
    pub fn pair_heartbeat(mut self, period: impl Into<Duration>) -> Self {
        self.pair_heartbeat = period.into();
        self
    }
    /// How long a pair member may be silent before it has failed (default 300 ms; longer
    /// than the pair heartbeat).
    pub fn pair_timeout(mut self, timeout: impl Into<Duration>) -> Self {
        self.pair_timeout = timeout.into();
        self
    }
    /// Another master-capable device, with this master's priority (so the lower node-ID of
    /// the two wins the negotiation).
    pub fn peer_master(self, node: u8) -> Self {
        let p = self.priority;
        self.peer_master_with_priority(node, p)
    }
    /// How long a pair member may stay unheard (no boot-up, no heartbeat) after power-on or
    /// after a reset before it is reported: a board, or its buses, dead from the start, which
    /// heartbeat monitoring (it starts at the first heartbeat) never reports.
    pub fn boot_timeout(mut self, timeout: impl Into<Duration>) -> Self {
        self.boot_timeout = timeout.into();
        self
    }
    /// Another master-capable device with its own priority (lower wins).
    pub fn peer_master_with_priority(mut self, node: u8, priority: u8) -> Self {
        self.peers.push((node, priority));
        self
    }
    /// How the master configures pair member `cfg.node` when it boots (identity check,
    /// configuration writes, PDOs: a DCF's values with `SlaveConfig::from_dcf`); the pair
    /// supervisor overrides what supervision needs (heartbeat, start, assignment: see
    /// [`Supervisor::add_pair_with`]). Default: the member's heartbeat only. A second config for
    /// one node replaces the first; one for a node that is no pair member is not used.
    pub fn member_config(mut self, cfg: SlaveConfig) -> Self {
        self.members.retain(|c| c.node != cfg.node);
        self.members.push(cfg);
        self
    }
    /// The dual-bus layer's configuration (default: active-active, health timing from the
    /// shorter of the two heartbeats).
    pub fn link(mut self, cfg: DualBusConfig) -> Self {
        self.link = Some(cfg);
        self
    }
    /// The CiA 302-2 master's own settings: the slaves that are no pair members, the SDO
    /// timeout, queue sizes (default `MasterConfig::new()`).
    pub fn master(mut self, cfg: MasterConfig) -> Self {
        self.master = cfg;
        self
    }

    /// The identifier profile (default: the CiA 301 predefined connection set;
    /// `NetProfile::railway29()` for the railway 29-bit scheme, on which every device of the
    /// network, this master, its peers and the pair members, must run). A network on another
    /// profile than the predefined set is built with [`build_profiled`](Self::build_profiled)
    /// or opened (`open`, `open_named`).
    pub fn profile(mut self, profile: NetProfile) -> Self {
        self.profile = profile;
        self
    }
    /// The identifier profile as set.
    #[must_use]
    pub fn id_profile(&self) -> &NetProfile {
        &self.profile
    }

    /// A CANopen FD network (CiA 1301; feature `fd`), as duocan's `NetOptions::with_fd` opens
    /// one on a single port or two: both ports of the dual-bus layer carry CAN FD (each FD
    /// frame on both buses, merged once received), the master's node serves USDO from its
    /// dictionary, and the front door (`RedundantNetwork`) reads and writes the nodes'
    /// dictionaries over USDO with the same calls as over SDO, its requests going out from
    /// `client` (1–127, a node-ID no device of the network has: USDO names its clients by
    /// node-ID). The master itself still configures its slaves over SDO.
    ///
    /// **Heartbeats only.** CAN FD has no remote frames, so node guarding cannot run there: a
    /// slave the master guards (a guard time in its 0x1F81 entry) or whose configuration sets
    /// its life guarding (0x100C/0x100D) is refused by [`build`](Self::build)
    /// ([`RedundantError::GuardingOnFd`], naming the node). Pair supervision, the flying master
    /// and the dual-bus layer's port diagnosis judge heartbeats, as on classic buses.
    ///
    /// Every node on both buses must speak CAN FD and serve USDO (a duocan node with
    /// `NodeConfig::with_fd`), and the ports must be opened for CAN FD.
    #[cfg(feature = "fd")]
    pub fn with_fd(mut self, client: u8) -> Self {
        self.fd = Some(client);
        self
    }
    /// The USDO client node-ID of a CANopen FD network ([`with_fd`](Self::with_fd)); `None`
    /// on a classic one.
    #[must_use]
    pub fn fd_client(&self) -> Option<u8> {
        self.fd
    }

    /// This master's node-ID as set (checked by [`build`](Self::build)).
    #[must_use]
    pub fn this_node(&self) -> u8 {
        self.node_id
    }
    /// The pairs declared, `(a, b)`.
    #[must_use]
    pub fn pairs(&self) -> &[(u8, u8)] {
        &self.pairs
    }
    /// The peer masters declared, `(node, priority)`.
    #[must_use]
    pub fn peers(&self) -> &[(u8, u8)] {
        &self.peers
    }
    /// The pair heartbeat as set.
    #[must_use]
    pub fn pair_heartbeat_period(&self) -> Duration {
        self.pair_heartbeat
    }

    /// The settings of peer master `node` on the same network: the same timing and pairs,
    /// with this master declared as its peer (what a simulated peer runs).
    pub fn as_peer(&self, node: u8) -> Self {
        let mut b = self.clone();
        b.peers.clear();
        b.peers.push((self.node_id, self.priority));
        for &(n, p) in &self.peers {
            if n == node {
                b.node_id = n;
                b.priority = p;
            } else {
                b.peers.push((n, p));
            }
        }
        b
    }

    /// Checks every setting (the errors [`build`](Self::build) returns, without building).
    pub fn check(&self) -> Result<(), RedundantError> {
        let mut seen: Vec<(u8, Role)> = Vec::new();
        let mut claim = |id: u8, role: Role| -> Result<NodeId, RedundantError> {
            let node = NodeId::new(id).ok_or(RedundantError::BadNodeId { role, id })?;
            if let Some(&(_, first)) = seen.iter().find(|(n, _)| *n == id) {
                return Err(RedundantError::NodeTwice {
                    node,
                    first,
                    second: role,
                });
            }
            seen.push((id, role));
            Ok(node)
        };
        claim(self.node_id, Role::ThisMaster)?;
        if self.peers.len() > MAX_PEERS {
            return Err(RedundantError::TooMany {
                what: "peer masters",
                max: MAX_PEERS,
            });
        }
        for &(n, _) in &self.peers {
            claim(n, Role::PeerMaster)?;
        }
        if self.pairs.len() > MAX_PAIRS {
            return Err(RedundantError::TooMany {
                what: "pairs",
                max: MAX_PAIRS,
            });
        }
        for &(a, b) in &self.pairs {
            claim(a, Role::PairMember)?;
            claim(b, Role::PairMember)?;
        }
        if let Some(client) = self.fd {
            claim(client, Role::UsdoClient)?;
            self.check_fd()?;
        }
        let periods = [
            ("heartbeat", self.heartbeat),
            ("master_timeout", self.master_timeout),
            ("pair_heartbeat", self.pair_heartbeat),
            ("pair_timeout", self.pair_timeout),
            ("boot_timeout", self.boot_timeout),
        ];
        let optional = [("sync", self.sync), ("time", self.time)];
        let optional = optional.into_iter().filter_map(|(s, d)| d.map(|d| (s, d)));
        for (setting, d) in periods.into_iter().chain(optional) {
            if d == Duration::ZERO {
                return Err(RedundantError::ZeroDuration { setting });
            }
        }
        for (setting, value) in [
            ("heartbeat", self.heartbeat),
            ("pair_heartbeat", self.pair_heartbeat),
            ("pair_timeout", self.pair_timeout),
        ] {
            if value.as_millis() > u64::from(u16::MAX) || value.as_micros() % 1000 != 0 {
                return Err(RedundantError::TooLong { setting, value });
            }
        }
        for (setting, timeout, period) in [
            ("master_timeout", self.master_timeout, self.heartbeat),
            ("pair_timeout", self.pair_timeout, self.pair_heartbeat),
        ] {
            if timeout <= period {
                return Err(RedundantError::TimeoutTooShort {
                    setting,
                    timeout,
                    period,
                });
            }
        }
        Ok(())
    }

    /// Heartbeats only on a CANopen FD network: no slave of the master, pair member or not,
    /// configured for guarding (the master's or its own life guarding).
    #[cfg(feature = "fd")]
    fn check_fd(&self) -> Result<(), RedundantError> {
        use crate::supervisor::fd_guarding::{GuardingOnFd, GuardingSource};
        let members = self.members.iter().filter(|c| {
            self.pairs
                .iter()
                .any(|p| [p.0, p.1].contains(&c.node.raw()))
        });
        for c in self.master.slaves.iter().chain(members) {
            if let Some(source) = GuardingSource::of_slave(c) {
                return Err(RedundantError::GuardingOnFd(GuardingOnFd {
                    node: c.node,
                    source,
                }));
            }
        }
        Ok(())
    }
    #[cfg(not(feature = "fd"))]
    fn check_fd(&self) -> Result<(), RedundantError> {
        Ok(())
    }

    /// Builds the network: master, supervisor with its pairs and peers, dual-bus layer, as one
    /// sans-IO [`LogicalNetwork`] (its clock starts at [`Instant::ZERO`]), on the predefined
    /// connection set: with another [`profile`](Self::profile) this is
    /// [`RedundantError::ProfileNotPredefined`] (build it with
    /// [`build_profiled`](Self::build_profiled)).
    pub fn build(&self) -> Result<LogicalNetwork<DynamicDictionary>, RedundantError> {
        self.build_boxed().map(|n| *n)
    }

    /// [`build`](Self::build), on the heap: the network is some 160 kB, more than a small
    /// thread's stack wants to move around (what a runtime takes).
    pub fn build_boxed(&self) -> Result<Box<LogicalNetwork<DynamicDictionary>>, RedundantError> {
        if self.profile.is_railway() {
            return Err(RedundantError::ProfileNotPredefined {
                profile: self.profile.name(),
            });
        }
        self.build_on(Predefined, Channel::predefined)
    }

    /// The network on the [`profile`](Self::profile) set, whichever it is (what the async
    /// handle runs), on the heap.
    pub fn build_profiled(
        &self,
    ) -> Result<Box<LogicalNetwork<DynamicDictionary, NetProfile>>, RedundantError> {
        self.build_on(self.profile.clone(), self.profile.sdo_channels())
    }

    /// The network on `profile`, the master's SDO client on `channels`.
    fn build_on<P: IdProfile + FrameClassifier + Clone>(
        &self,
        profile: P,
        channels: fn(NodeId) -> Channel,
    ) -> Result<Box<LogicalNetwork<DynamicDictionary, P>>, RedundantError> {
        self.check()?;
        let sup = self.supervisor(profile.clone(), channels)?;
        let guard = self.heartbeat.min(self.pair_heartbeat);
        let link = self
            .link
            .unwrap_or_else(|| DualBusConfig::with_guard_period(LinkMode::ActiveActive, guard));
        #[cfg(feature = "fd")]
        if self.fd.is_some() {
            // What was configured in the master besides the builder's settings.
            sup.check_fd().map_err(RedundantError::GuardingOnFd)?;
        }
        #[cfg_attr(not(feature = "fd"), allow(unused_mut))]
        let mut bus = DualBus::with_classifier(link, profile);
        #[cfg(feature = "fd")]
        if self.fd.is_some() {
            bus.set_port_fd(0, true);
            bus.set_port_fd(1, true);
        }
        let station = SupervisedStation::new(bus, *sup).map_err(RedundantError::Link)?;
        Ok(Box::new(LogicalNetwork::new(station)))
    }

    /// The master and its supervisor, with the pairs and peers (settings checked).
    fn supervisor<P: IdProfile>(
        &self,
        profile: P,
        channels: fn(NodeId) -> Channel,
    ) -> Result<Box<Supervisor<DynamicDictionary, P>>, RedundantError> {
        let id = |raw: u8| {
            NodeId::new(raw).ok_or(RedundantError::BadNodeId {
                role: Role::Node,
                id: raw,
            })
        };
        let me = id(self.node_id)?;
        let mut od = objects::master_dictionary(self.node_id, comm::Identity::default());
        self.profile.fit_dictionary(&mut od, me);
        #[cfg_attr(not(feature = "fd"), allow(unused_mut))]
        let mut node = NodeConfig::master(me);
        #[cfg(feature = "fd")]
        {
            // On a CANopen FD network the master's node serves USDO too.
            node = node.with_fd(self.fd.is_some());
        }
        let sdo = MasterSdoClient::with_sessions(DEFAULT_LIMIT, self.master.sdo_sessions)
            .with_channels(channels);
        let master = Master::with_parts(node, od, profile, sdo, self.master.clone())
            .map_err(|e| RedundantError::Network(super::NetworkError::Nmt(e)))?;
        let mut cfg = SupervisorConfig::new(
            self.priority,
            me,
            self.heartbeat,
            self.master_timeout,
            self.sync.unwrap_or(Duration::ZERO),
        );
        for &(n, p) in &self.peers {
            cfg = cfg.with_peer(p, id(n)?);
        }
        if let Some(t) = self.time {
            cfg = cfg.with_time_period(t);
        }
        cfg.pairs = cfg.pairs.with_boot_timeout(self.boot_timeout);
        let mut sup = Box::new(Supervisor::new(master, cfg, Instant::ZERO));
        #[cfg(all(feature = "std", feature = "time"))]
        if self.time.is_some() {
            // A TIME producer needs a clock: this machine's, at the network's start.
            sup.node_mut().set_time(Instant::ZERO, wall_time_of_day());
        }
        for &(a, b) in &self.pairs {
            let spec = PairSpec::new(id(a)?, id(b)?, self.pair_heartbeat, self.pair_timeout);
            let member = |node: NodeId| {
                self.members
                    .iter()
                    .find(|c| c.node == node)
                    .cloned()
                    .unwrap_or_else(|| SlaveConfig::new(node))
            };
            sup.add_pair_with(Instant::ZERO, spec, member(spec.a), member(spec.b))
                .map_err(RedundantError::Pair)?;
        }
        Ok(sup)
    }
}

/// This machine's wall clock as CiA 301 TIME: days since 1984-01-01 and milliseconds after
/// midnight (UTC). A clock before 1984 reads as its start.
#[cfg(all(feature = "std", feature = "time"))]
fn wall_time_of_day() -> duocan::cia301::time_stamp::TimeOfDay {
    /// 1984-01-01T00:00:00Z in milliseconds since the Unix epoch.
    const EPOCH_1984_MS: u64 = 441_763_200_000;
    let unix_ms = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX));
    duocan::cia301::time_stamp::TimeOfDay::from_total_ms(unix_ms.saturating_sub(EPOCH_1984_MS))
}
