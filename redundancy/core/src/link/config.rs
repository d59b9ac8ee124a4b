//! What the layer is configured with ([`DualBusConfig`], [`LinkMode`]), from code or from the
//! object dictionary: the definition tables of 0x1F60 (CiA 302-6 redundancy configuration) and of
//! the ECSS bus-toggle object (0x2000 by default; the index is configurable), and readers that
//! build a [`DualBusConfig`] from any [`ObjectDictionary`].
//!
//! ```
//! use duocan_core::od::{comm, ObjectDictionary, StaticDictionary, ObjectDef};
//! use duocan_redundancy_core::link::config::{self, OdLayout};
//! use duocan_redundancy_core::{DualBusConfig, LinkMode};
//!
//! static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
//! static RED: [ObjectDef; 6] = config::cia302_6_objects(config::REDUNDANCY_CONFIG);
//! let mut od = StaticDictionary::<32, 256>::new();
//! od.load(5, &[&COMM, &RED]).unwrap();
//! od.set_value::<u16>(0x1F60, 2, 500).unwrap();
//! let cfg = DualBusConfig::from_od(&od, &OdLayout::default()).unwrap();
//! let LinkMode::Cia302_6(c) = cfg.mode else { panic!() };
//! assert_eq!(c.eval_power_on, duocan_core::Duration::from_millis(500));
//! ```

#[cfg(feature = "cia302-6")]
use crate::link::channel::Cia3026Config;
#[cfg(feature = "ecss")]
use crate::link::channel::{EcssConfig, EcssRole};
use crate::link::health::HealthConfig;
use crate::pair::MAX_MEMBERS;
use core::fmt;
#[cfg(doc)]
use duocan_core::machine::LinkRequest;
use duocan_core::od::abort::AbortCode;
use duocan_core::od::{comm, Access, DefaultValue, Limit, ObjectDef, ObjectDictionary, ObjectType};
use duocan_core::NodeSet;
use duocan_core::{Duration, NodeId};

/// Which redundancy scheme the layer runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum LinkMode {
    /// Both buses carry everything; receive merge exactly once (the railway default).
    #[default]
    ActiveActive,
    /// CiA 302-6 active-standby (feature `cia302-6`, on by default).
    #[cfg(feature = "cia302-6")]
    Cia302_6(Cia3026Config),
    /// ECSS-E-ST-50-15C bus toggling (feature `ecss`, on by default).
    #[cfg(feature = "ecss")]
    EcssToggle(EcssConfig),
}

/// Everything a [`DualBus`](crate::DualBus) is configured with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct DualBusConfig {
    /// The scheme.
    pub mode: LinkMode,
    /// Skew window of the merger (default 5 ms): longer than the worst inter-bus skew of a
    /// frame's two receive timestamps, shorter than the shortest repetition period that
    /// matters (half the 10 ms SYNC of an interlocking cycle: a SYNC one bus lost is not taken
    /// for the twin of the next). With timestamps taken where the frames arrive, the skew is the
    /// wires' (each bus arbitrates alike), well under a millisecond.
    pub skew_window: Duration,
    /// The largest lag between the buses that is corrected without calling the lagging bus
    /// suspect (default 40 ms); a lag up to twice this is corrected and measured at all, and
    /// that is how long the merger keeps an unmatched copy for a reader that runs behind (see
    /// [`crate::link::lag`]). Not below the skew window.
    pub max_skew_window: Duration,
    /// Port health timing.
    pub health: HealthConfig,
    /// A node not heard on a bus for this long is reported unreachable there (default: the
    /// silence limit).
    pub reach_timeout: Duration,
    /// A/B values differing this long raise a discrepancy (default 100 ms; zero: never).
    pub discrepancy_time: Duration,
    /// Where the node's dictionary has the redundancy objects: the layer keeps their status
    /// entries (ECSS Bdefault and Ctoggle, the CiA 302-6 channel error counter) up to date
    /// through [`LinkRequest::SetStatus`].
    pub od_layout: OdLayout,
    /// Nodes whose heartbeats the layer judges at most ([`crate::link::plausible`]: the
    /// supervisor watches every pair member); the table is allocated for them at the first
    /// watch (default [`MAX_MEMBERS`], every node-ID; a master with a few pairs needs twice
    /// their number).
    pub watch_capacity: usize,
    /// The longest a frame with its intermission occupies a bus (160 bit times at the bit rate:
    /// 0.16 ms at 1 Mbit/s, 1.28 ms at 125 kbit/s), plus the jitter of the receive times the
    /// layer is given: a longer gap between two frames on a bus is time it was idle, rule 2's
    /// witness that a heartbeat missing there was not starved ([`crate::link::plausible`]).
    /// Default 2 ms ([`DEFAULT_FRAME_TIME`](crate::link::plausible::DEFAULT_FRAME_TIME): from
    /// 125 kbit/s up); slower buses need more; zero: no idle witness. The transmit-stall limit
    /// ([`HealthConfig::tx_stall`]) is the skew window less this: a copy let go at the limit
    /// is on its bus a frame time later at most, and must reach the receivers within the
    /// window of its twin.
    pub frame_time: Duration,
    /// Watched nodes may be wired to one bus only (default false). By default every pair
    /// member has a port on each bus: one heard on one bus only while the other is healthy is
    /// suspect even if the other bus never carried it (a master that starts while an impostor
    /// beats a dead member's heartbeat on one bus has nothing else to go by). With true, a
    /// node not heard on both buses since it booted is trusted, as a board on one bus by
    /// design ([`crate::link::plausible`], rule 2).
    pub one_bus_members: bool,
    /// How the active-active mode merges the two buses' receptions (default
    /// [`MergePolicy::Exact`]); the CiA 302-6 and ECSS modes keep the exact merge for what
    /// they merge (heartbeats heard on both channels).
    pub merge: MergePolicy,
}

/// How the active-active mode merges the two buses' receptions into one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MergePolicy {
    /// Every occurrence exactly once, twins matched by their receive timestamps
    /// ([`crate::link::merge`]).
    #[default]
    Exact,
    /// Each sender's frames from one bus, switching to the other after `timeout` of silence
    /// ([`crate::link::sticky`]): never a duplicate while a frame's two copies are stamped less
    /// than `timeout` apart; up to `timeout` of a sender's frames lost at a switch. A timeout
    /// below the skew window is taken as the skew window. Under this policy the transmit-stall
    /// rule of port health waits the timeout (not the skew window): a frame that reaches the
    /// receivers later than that after its copy on the other bus is a lag the rule no longer
    /// covers. (Feature `sticky`, on by default.)
    #[cfg(feature = "sticky")]
    Sticky {
        /// Silence of a sender on its bus after which it switches: above the largest lag
        /// between the buses' stamps.
        timeout: Duration,
    },
}

#[cfg(feature = "sticky")]
impl MergePolicy {
    /// The sticky merge's default timeout, 40 ms: the default maximum skew window, the largest
    /// lag between the buses the layer takes for normal (beyond it a port is suspect). With
    /// receive timestamps the copies are stamped far closer (the skew on the wires); a port
    /// whose driver has none, or a bus behind a bridge, needs its lag below this.
    pub const STICKY_TIMEOUT: Duration = Duration::from_millis(40);

    /// The sticky merge with the default timeout ([`MergePolicy::STICKY_TIMEOUT`]).
    #[must_use]
    pub const fn sticky() -> Self {
        MergePolicy::Sticky {
            timeout: Self::STICKY_TIMEOUT,
        }
    }
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl DualBusConfig {
    /// The configuration with [`mode`](Self::mode) replaced.
    #[must_use]
    pub fn with_mode(mut self, mode: LinkMode) -> Self {
        self.mode = mode;
        self
    }
    /// The configuration with [`skew_window`](Self::skew_window) replaced.
    ///
    /// The transmit-stall limit follows (see [`frame_time`](Self::frame_time)), unless the
    /// health configuration was given another one.
    #[must_use]
    pub fn with_skew_window(mut self, skew_window: Duration) -> Self {
        self.follow_stall(skew_window, self.frame_time);
        self.skew_window = skew_window;
        self
    }
    /// The configuration with [`max_skew_window`](Self::max_skew_window) replaced.
    #[must_use]
    pub fn with_max_skew_window(mut self, max_skew_window: Duration) -> Self {
        self.max_skew_window = max_skew_window;
        self
    }
    /// The configuration with [`health`](Self::health) replaced.
    #[must_use]
    pub fn with_health(mut self, health: HealthConfig) -> Self {
        self.health = health;
        self
    }
    /// The configuration with [`reach_timeout`](Self::reach_timeout) replaced.
    #[must_use]
    pub fn with_reach_timeout(mut self, reach_timeout: Duration) -> Self {
        self.reach_timeout = reach_timeout;
        self
    }
    /// The configuration with [`discrepancy_time`](Self::discrepancy_time) replaced.
    #[must_use]
    pub fn with_discrepancy_time(mut self, discrepancy_time: Duration) -> Self {
        self.discrepancy_time = discrepancy_time;
        self
    }
    /// The configuration with [`od_layout`](Self::od_layout) replaced.
    #[must_use]
    pub fn with_od_layout(mut self, od_layout: OdLayout) -> Self {
        self.od_layout = od_layout;
        self
    }
    /// The configuration with [`frame_time`](Self::frame_time) replaced.
    ///
    /// The transmit-stall limit follows, unless the health configuration was given another
    /// one.
    #[must_use]
    pub fn with_frame_time(mut self, frame_time: Duration) -> Self {
        self.follow_stall(self.skew_window, frame_time);
        self.frame_time = frame_time;
        self
    }
    /// The configuration with [`one_bus_members`](Self::one_bus_members) replaced.
    #[must_use]
    pub fn with_one_bus_members(mut self, allowed: bool) -> Self {
        self.one_bus_members = allowed;
        self
    }
    /// The configuration with [`merge`](Self::merge) replaced.
    #[must_use]
    pub fn with_merge(mut self, merge: MergePolicy) -> Self {
        self.merge = merge;
        self
    }
    /// The configuration with [`watch_capacity`](Self::watch_capacity) replaced (at most
    /// [`MAX_MEMBERS`]).
    #[must_use]
    pub fn with_watch_capacity(mut self, nodes: usize) -> Self {
        self.watch_capacity = nodes;
        self
    }
}

impl Default for DualBusConfig {
    fn default() -> Self {
        DualBusConfig::with_guard_period(LinkMode::ActiveActive, Duration::from_millis(100))
    }
}

/// The transmit-stall limit for a skew window and a frame time ([`HealthConfig::tx_stall`]):
/// the window less the frame time, as a copy the rule lets go at its last moment is on its bus
/// at most a frame time later and must reach the receivers within the window of its twin; at
/// least a quarter of the window (a bus that slow needs a wider window). With the defaults
/// (5 ms, 2 ms) 3 ms. Half the window, as the limit was, flushed copies that would have come
/// in time: on a bus that carried a burst of the master's requests the other bus did not
/// (its copies there flushed behind a node at the wrong bit rate), a low-priority reply waited
/// 3 ms, and a receiver that heard only that bus never got it.
fn stall_limit(skew_window: Duration, frame_time: Duration) -> Duration {
    let w = skew_window.as_micros();
    Duration::from_micros(w.saturating_sub(frame_time.as_micros()).max(w / 4))
}

impl DualBusConfig {
    /// The stall limit follows a new window or frame time if it was the one derived from them.
    fn follow_stall(&mut self, skew_window: Duration, frame_time: Duration) {
        if self.health.tx_stall == stall_limit(self.skew_window, self.frame_time) {
            self.health.tx_stall = stall_limit(skew_window, frame_time);
        }
    }

    /// `mode` with the health and reachability timing derived from the node-guarding (or
    /// heartbeat) period: silence limit 3 periods.
    #[must_use]
    pub fn with_guard_period(mode: LinkMode, period: Duration) -> Self {
        let skew_window = Duration::from_millis(5);
        let frame_time = crate::link::plausible::DEFAULT_FRAME_TIME;
        let health = HealthConfig {
            tx_stall: stall_limit(skew_window, frame_time),
            ..HealthConfig::from_guard_period(period)
        };
        DualBusConfig {
            mode,
            skew_window,
            max_skew_window: Duration::from_millis(40),
            health,
            reach_timeout: health.silence_limit,
            discrepancy_time: Duration::from_millis(100),
            od_layout: OdLayout::default(),
            watch_capacity: MAX_MEMBERS,
            frame_time,
            one_bus_members: false,
            merge: MergePolicy::Exact,
        }
    }
}

/// CiA 302-6 redundancy configuration.
pub const REDUNDANCY_CONFIG: u16 = 0x1F60;
/// Default index of the ECSS bus-toggle object (manufacturer-specific area).
pub const BUS_TOGGLE: u16 = 0x2000;

/// Where the redundancy objects live in a dictionary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OdLayout {
    /// The CiA 302-6 object (0x1F60).
    pub redundancy: u16,
    /// The ECSS bus-toggle object (0x2000).
    pub toggle: u16,
}

impl Default for OdLayout {
    fn default() -> Self {
        OdLayout {
            redundancy: REDUNDANCY_CONFIG,
            toggle: BUS_TOGGLE,
        }
    }
}

/// The six entries of the CiA 302-6 redundancy configuration at `index`. Times in ms.
pub const fn cia302_6_objects(index: u16) -> [ObjectDef; 6] {
    const fn rec(d: ObjectDef) -> ObjectDef {
        d.object_type(ObjectType::Record)
    }
    [
        rec(ObjectDef::u8(index, 0, Access::Const, 5)).named("Redundancy configuration"),
        rec(ObjectDef::u16(index, 1, Access::Rw, 0)).named("Maximum transmit delay"),
        rec(ObjectDef::u16(index, 2, Access::Rw, 1000))
            .named("Heartbeat evaluation time after power-on"),
        rec(ObjectDef::u16(index, 3, Access::Rw, 1000))
            .named("Heartbeat evaluation time after reset communication"),
        rec(ObjectDef::u8(index, 4, Access::Rw, 16)).named("Channel error counter threshold"),
        rec(ObjectDef::u8(index, 5, Access::Ro, 0)).named("Channel error counter"),
    ]
}

/// The five entries of the ECSS bus-toggle object at `index`.
pub const fn ecss_objects(index: u16) -> [ObjectDef; 5] {
    const fn rec(d: ObjectDef) -> ObjectDef {
        d.object_type(ObjectType::Record)
    }
    [
        rec(ObjectDef::u8(index, 0, Access::Const, 4)).named("Bus redundancy"),
        rec(ObjectDef::u8(index, 1, Access::Rw, 0))
            .limits(Limit::Unsigned(0), Limit::Unsigned(1))
            .named("Bdefault"),
        rec(ObjectDef::u8(index, 2, Access::Rw, 2)).named("Ttoggle"),
        rec(ObjectDef::u8(index, 3, Access::Rw, 4)).named("Ntoggle"),
        rec(ObjectDef::u8(index, 4, Access::Ro, 0))
            .default(DefaultValue::Unsigned(0))
            .named("Ctoggle"),
    ]
}

/// The 0x1F60 table at its standard index.
pub static CIA302_6_OBJECTS: [ObjectDef; 6] = cia302_6_objects(REDUNDANCY_CONFIG);
/// The bus-toggle table at 0x2000.
pub static ECSS_OBJECTS: [ObjectDef; 5] = ecss_objects(BUS_TOGGLE);

/// Why a configuration could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigError {
    /// An entry the configuration needs is missing or unreadable.
    Missing {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What the dictionary said.
        abort: AbortCode,
    },
    /// An entry holds a value the layer cannot use.
    Invalid {
        /// Index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What is wrong.
        what: &'static str,
    },
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Missing { index, sub, abort } => write!(
                f,
                "redundancy configuration needs {index:#06x}sub{sub}, which cannot be read ({abort:?}): add the entry to the dictionary"
            ),
            ConfigError::Invalid { index, sub, what } => {
                write!(f, "{index:#06x}sub{sub}: {what}")
            }
        }
    }
}

impl core::error::Error for ConfigError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            ConfigError::Missing { abort, .. } => Some(abort),
            _ => None,
        }
    }
}

pub(crate) fn read<D: ObjectDictionary>(od: &D, index: u16, sub: u8) -> Result<u32, ConfigError> {
    match od.get(index, sub) {
        Ok(_) => od.get_u32(index, sub).ok_or(ConfigError::Missing {
            index,
            sub,
            abort: AbortCode::TYPE_MISMATCH,
        }),
        Err(abort) => Err(ConfigError::Missing { index, sub, abort }),
    }
}

fn has_object<D: ObjectDictionary>(od: &D, index: u16) -> bool {
    od.get(index, 0).is_ok()
}

/// The heartbeat producers a device consumes (0x1016 entries with a node-ID and a time).
pub fn heartbeat_producers<D: ObjectDictionary>(od: &D) -> NodeSet {
    let mut set = NodeSet::EMPTY;
    let count = od
        .get_u32(comm::HEARTBEAT_CONSUMER, 0)
        .unwrap_or(0)
        .min(127) as u8;
    for sub in 1..=count {
        if let Some((n, t)) = od
            .get_u32(comm::HEARTBEAT_CONSUMER, sub)
            .and_then(consumer_entry)
        {
            if !t.is_zero() {
                set.insert(n);
            }
        }
    }
    set
}

/// Decodes a 0x1016 sub-entry: node-ID in bits 16–23, time in ms in bits 0–15.
fn consumer_entry(v: u32) -> Option<(NodeId, Duration)> {
    let n = NodeId::new(((v >> 16) & 0xFF) as u8)?;
    Some((n, Duration::from_millis((v & 0xFFFF) as u64)))
}

#[cfg(feature = "cia302-6")]
impl Cia3026Config {
    /// Reads 0x1F60 (at `index`) subs 1–4 and the producers of 0x1016.
    pub fn from_od<D: ObjectDictionary>(od: &D, index: u16) -> Result<Self, ConfigError> {
        let ms = |sub| read(od, index, sub).map(|v| Duration::from_millis(v as u64));
        let threshold = read(od, index, 4)?;
        Ok(Cia3026Config {
            default_channel: 0,
            max_tx_delay: ms(1)?,
            eval_power_on: ms(2)?,
            eval_reset: ms(3)?,
            error_threshold: u8::try_from(threshold).map_err(|_| ConfigError::Invalid {
                index,
                sub: 4,
                what: "channel error counter threshold above 255",
            })?,
            producers: heartbeat_producers(od),
        })
    }
}

#[cfg(feature = "ecss")]
impl EcssConfig {
    /// Reads the bus-toggle object at `index` and the redundancy master from 0x1016 sub 1 (a
    /// device without a valid entry there is the master).
    pub fn from_od<D: ObjectDictionary>(od: &D, index: u16) -> Result<Self, ConfigError> {
        let bdefault = read(od, index, 1)?;
        if bdefault > 1 {
            return Err(ConfigError::Invalid {
                index,
                sub: 1,
                what: "Bdefault must be 0 (bus 1) or 1 (bus 2)",
            });
        }
        let role = match od
            .get_u32(comm::HEARTBEAT_CONSUMER, 1)
            .and_then(consumer_entry)
        {
            Some((master, period)) if !period.is_zero() => EcssRole::Slave { master, period },
            _ => EcssRole::Master,
        };
        Ok(EcssConfig {
            bdefault: bdefault as u8,
            ttoggle: read(od, index, 2)?.min(255) as u8,
            ntoggle: read(od, index, 3)?.min(255) as u8,
            role,
        })
    }
}

impl DualBusConfig {
    /// The configuration a dictionary describes: CiA 302-6 if it has the redundancy object,
    /// else bus toggling if it has the toggle object, else active-active. Timing from the
    /// guard time (0x100C) or, without one, the producer heartbeat time (0x1017); 100 ms if
    /// neither is set.
    pub fn from_od<D: ObjectDictionary>(od: &D, layout: &OdLayout) -> Result<Self, ConfigError> {
        let mode = if has_object(od, layout.redundancy) {
            cia302_6_mode(od, layout.redundancy)?
        } else if has_object(od, layout.toggle) {
            ecss_mode(od, layout.toggle)?
        } else {
            LinkMode::ActiveActive
        };
        let period = [comm::GUARD_TIME, comm::HEARTBEAT_PRODUCER]
            .into_iter()
            .filter_map(|i| od.get_u32(i, 0))
            .find(|v| *v != 0)
            .unwrap_or(100);
        Ok(DualBusConfig {
            od_layout: *layout,
            ..DualBusConfig::with_guard_period(mode, Duration::from_millis(period as u64))
        })
    }
}

/// The CiA 302-6 mode the redundancy object at `index` describes; an error naming the object
/// in a build that leaves the policy out.
fn cia302_6_mode<D: ObjectDictionary>(od: &D, index: u16) -> Result<LinkMode, ConfigError> {
    #[cfg(feature = "cia302-6")]
    return Ok(LinkMode::Cia302_6(Cia3026Config::from_od(od, index)?));
    #[cfg(not(feature = "cia302-6"))]
    left_out(
        od,
        index,
        "CiA 302-6: this build leaves the policy out (feature cia302-6)",
    )
}

/// The ECSS mode the bus-toggle object at `index` describes; an error naming the object in a
/// build that leaves the policy out.
fn ecss_mode<D: ObjectDictionary>(od: &D, index: u16) -> Result<LinkMode, ConfigError> {
    #[cfg(feature = "ecss")]
    return Ok(LinkMode::EcssToggle(EcssConfig::from_od(od, index)?));
    #[cfg(not(feature = "ecss"))]
    left_out(
        od,
        index,
        "ECSS bus toggling: this build leaves the policy out (feature ecss)",
    )
}

/// The dictionary's object at `index` asks for a policy this build leaves out.
#[cfg(not(all(feature = "cia302-6", feature = "ecss")))]
fn left_out<D>(_: &D, index: u16, what: &'static str) -> Result<LinkMode, ConfigError> {
    let sub = 0;
    Err(ConfigError::Invalid { index, sub, what })
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan_core::od::StaticDictionary;

    static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
    static HB: [ObjectDef; 4] = comm::heartbeat_consumers::<4>();
    static TOGGLE_AT_2100: [ObjectDef; 5] = ecss_objects(0x2100);

    #[test]
    fn mode_follows_the_objects_present() {
        let mut od = StaticDictionary::<64, 512>::new();
        od.load(5, &[&COMM, &HB]).unwrap();
        od.set_value::<u16>(comm::HEARTBEAT_PRODUCER, 0, 50)
            .unwrap();
        let c = DualBusConfig::from_od(&od, &OdLayout::default()).unwrap();
        assert_eq!(c.mode, LinkMode::ActiveActive);
        assert_eq!(c.health.silence_limit, Duration::from_millis(150));

        let mut od = StaticDictionary::<64, 512>::new();
        od.load(5, &[&COMM, &HB, &CIA302_6_OBJECTS]).unwrap();
        od.set_value::<u32>(comm::HEARTBEAT_CONSUMER, 1, 0x0002_0064)
            .unwrap();
        od.set_value::<u32>(comm::HEARTBEAT_CONSUMER, 3, 0x0007_0064)
            .unwrap();
        od.set_value::<u16>(REDUNDANCY_CONFIG, 1, 20).unwrap();
        let c = DualBusConfig::from_od(&od, &OdLayout::default()).unwrap();
        let LinkMode::Cia302_6(m) = c.mode else {
            panic!("{:?}", c.mode)
        };
        assert_eq!(m.max_tx_delay, Duration::from_millis(20));
        assert_eq!(m.error_threshold, 16);
        assert_eq!(
            m.producers.iter().map(|n| n.raw()).collect::<Vec<_>>(),
            [2, 7]
        );

        let mut od = StaticDictionary::<64, 512>::new();
        od.load(5, &[&COMM, &HB, &TOGGLE_AT_2100]).unwrap();
        od.set_value::<u32>(comm::HEARTBEAT_CONSUMER, 1, 0x0001_00C8)
            .unwrap();
        od.set_value::<u8>(0x2100, 1, 1).unwrap();
        let layout = OdLayout {
            toggle: 0x2100,
            ..Default::default()
        };
        let c = DualBusConfig::from_od(&od, &layout).unwrap();
        assert_eq!(
            c.mode,
            LinkMode::EcssToggle(EcssConfig {
                bdefault: 1,
                ttoggle: 2,
                ntoggle: 4,
                role: EcssRole::Slave {
                    master: NodeId::must(1),
                    period: Duration::from_millis(200)
                }
            })
        );
        // Bdefault is range-checked by the dictionary itself.
        assert!(od.write(0x2100, 1, &[2]).is_err());
    }

    #[test]
    fn missing_entries_are_reported() {
        static PARTIAL: [ObjectDef; 2] = {
            let t = cia302_6_objects(REDUNDANCY_CONFIG);
            [t[0], t[1]]
        };
        let mut od = StaticDictionary::<64, 512>::new();
        od.load(5, &[&COMM, &PARTIAL]).unwrap();
        let e = DualBusConfig::from_od(&od, &OdLayout::default()).unwrap_err();
        assert_eq!(
            e,
            ConfigError::Missing {
                index: 0x1F60,
                sub: 4,
                abort: AbortCode::NO_SUB_INDEX
            }
        );
        assert!(e.to_string().contains("0x1f60sub4"));
    }
}
