//! CiA 302-2 flying master: which of several master-capable devices is the active NMT master.
//!
//! [`FlyingMaster`] is a sans-IO machine for one master-capable device (0x1F80 bit 5). It takes
//! the flying-master frames (COB-IDs 0x71–0x76), the heartbeats of the other masters and hints of
//! a second active master; it yields frames, role changes and whether this device may command the
//! network now ([`FlyingMaster::may_command`]).
//!
//! # Frames
//!
//! | COB-ID | name                    | DLC | payload              |
//! |--------|-------------------------|-----|----------------------|
//! | 0x71   | active-master response  | 2   | priority, node-ID    |
//! | 0x72   | negotiation request     | 0   |                      |
//! | 0x73   | active-master request   | 0   |                      |
//! | 0x74   | master-capable response | 2   | priority, node-ID    |
//! | 0x75   | master-capable request  | 0   |                      |
//! | 0x76   | force negotiation       | 2   | priority, node-ID    |
//!
//! A [`Rank`] is (priority, node-ID); the lower one wins. The strong master is the one with the
//! better priority.
//!
//! # Power-on and forced negotiation (the CiA 302-2 timing)
//!
//! After power-on the device asks for the active master (0x73) and waits the active-master
//! detection timeout (0x1F90 sub 1). An answer (0x71) makes it standby. Without one it sends a
//! negotiation request (0x72); every master-capable device that is not active starts the
//! negotiation when it hears it. Each waits negotiation delay (sub 2) + priority × priority
//! slot (sub 4) + node-ID × device slot (sub 5) and then announces itself on 0x71, unless it
//! heard an announcement first: the first to announce wins, which is the best rank.
//!
//! # Takeover on loss of the active master's heartbeat (the failover bound)
//!
//! A hot standby does not negotiate when the active master's heartbeat is lost: it knows the
//! ranks and the liveness of the other master-capable devices (their heartbeats, 0x74/0x71/0x76
//! payloads). At the heartbeat deadline (last heartbeat + [`FlyingMasterConfig::master_timeout`])
//! it waits one device slot per *live* device ranked better than itself — zero when it is the
//! best one left, as the weak master of a pair always is — and then announces itself on 0x71
//! and is active. So the takeover happens exactly at the master-heartbeat timeout; the priority
//! slots of 302-2 (1.5 s each) apply only to the power-on and forced negotiations, where nobody
//! knows who is there.
//!
//! # Several active masters (healed partition)
//!
//! The active master sends 0x76 with its rank every multiple-master detect cycle (sub 6). An
//! active master that hears 0x76 or 0x71 from another device claiming to be active resolves the
//! conflict at once by rank, which is what a renegotiation between the two would decide, without
//! a period with no master: the worse one demotes and follows the better one; the better one
//! answers with 0x71 so that every device learns who is active. Any sign of another active
//! master — a SYNC or NMT command it did not send ([`FlyingMaster::foreign_activity`]), the
//! heartbeat of a master it had lost coming back — makes an active master send 0x76 at once and
//! *suspend* its NMT commands until the detection timeout has passed without a conflict: during
//! the overlap no two masters command the slaves.
//!
//! # Planned hand-over
//!
//! [`FlyingMaster::hand_over`] announces a successor on 0x71 (its rank, not this device's):
//! the successor takes over at once, this device becomes its standby. With
//! [`FlyingMasterConfig::revertive`], an active master that hears a better master alive as
//! standby for [`FlyingMasterConfig::handback_delay`] asks for a hand-over
//! ([`FlyingMaster::take_handback`]); the supervisor does it between two SYNCs so that SYNC
//! has no gap. A standby can take the role by hand ([`FlyingMaster::take_over`]): its 0x71 makes
//! an active master that has heard it alive all along step down.

use crate::link::config::{read, ConfigError};
use core::cmp::Ordering;
use core::fmt;
use duocan::frame::instant::earliest_of;
use duocan::frame::queue::Bounded;
use duocan::od::{Access, ObjectDef, ObjectDictionary, ObjectType};
use duocan::{Duration, Frame, Id, Instant, NodeId};
use heapless::Vec;

/// Active-master response / announcement.
pub const ACTIVE_MASTER_RESPONSE: u16 = 0x71;
/// Negotiation request.
pub const NEGOTIATION_REQUEST: u16 = 0x72;
/// Active-master request.
pub const ACTIVE_MASTER_REQUEST: u16 = 0x73;
/// Master-capable response.
pub const MASTER_CAPABLE_RESPONSE: u16 = 0x74;
/// Master-capable request.
pub const MASTER_CAPABLE_REQUEST: u16 = 0x75;
/// Force negotiation (and multiple-master detection).
pub const FORCE_NEGOTIATION: u16 = 0x76;

/// Other master-capable devices a device keeps track of.
pub const MAX_PEERS: usize = 8;

/// A master's rank: priority first (lower wins), then node-ID.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rank {
    /// 0x1F90 sub 3.
    pub priority: u8,
    /// Node-ID.
    pub node: NodeId,
}

impl Rank {
    /// A rank.
    #[must_use]
    pub const fn new(priority: u8, node: NodeId) -> Self {
        Rank { priority, node }
    }
    fn payload(self) -> [u8; 2] {
        [self.priority, self.node.raw()]
    }
    fn from_payload(d: &[u8]) -> Option<Rank> {
        match d {
            [p, n] => Some(Rank::new(*p, NodeId::new(*n)?)),
            _ => None,
        }
    }
}

impl Ord for Rank {
    fn cmp(&self, o: &Self) -> Ordering {
        (self.priority, self.node.raw()).cmp(&(o.priority, o.node.raw()))
    }
}
impl PartialOrd for Rank {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

impl fmt::Display for Rank {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (priority {})", self.node, self.priority)
    }
}

/// 0x1F90 and this implementation's additions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub struct FlyingMasterConfig {
    /// This device's rank (node-ID, 0x1F90 sub 3 priority).
    pub rank: Rank,
    /// Sub 1: active-master detection timeout (100 ms).
    pub detection_timeout: Duration,
    /// Sub 2: negotiation delay (500 ms).
    pub negotiation_delay: Duration,
    /// Sub 4: priority time slot (1500 ms).
    pub priority_slot: Duration,
    /// Sub 5: device time slot (10 ms).
    pub device_slot: Duration,
    /// Sub 6: multiple-master detect cycle (4000 ms; zero: no periodic detection).
    pub detect_cycle: Duration,
    /// Heartbeat consumer time for the other masters: the takeover deadline.
    pub master_timeout: Duration,
    /// Take the role back from a worse active master (default false: non-revertive).
    pub revertive: bool,
    /// How long a better master must be heard as standby before it is given the role back.
    pub handback_delay: Duration,
}

// Builders: the struct is `#[non_exhaustive]` (it may gain fields), so code outside the crate
// starts from a constructor or `Default` and sets what it needs.
impl FlyingMasterConfig {
    /// The configuration with [`rank`](Self::rank) replaced.
    #[must_use]
    pub fn with_rank(mut self, rank: Rank) -> Self {
        self.rank = rank;
        self
    }
    /// The configuration with [`detection_timeout`](Self::detection_timeout) replaced.
    #[must_use]
    pub fn with_detection_timeout(mut self, detection_timeout: Duration) -> Self {
        self.detection_timeout = detection_timeout;
        self
    }
    /// The configuration with [`negotiation_delay`](Self::negotiation_delay) replaced.
    #[must_use]
    pub fn with_negotiation_delay(mut self, negotiation_delay: Duration) -> Self {
        self.negotiation_delay = negotiation_delay;
        self
    }
    /// The configuration with [`priority_slot`](Self::priority_slot) replaced.
    #[must_use]
    pub fn with_priority_slot(mut self, priority_slot: Duration) -> Self {
        self.priority_slot = priority_slot;
        self
    }
    /// The configuration with [`device_slot`](Self::device_slot) replaced.
    #[must_use]
    pub fn with_device_slot(mut self, device_slot: Duration) -> Self {
        self.device_slot = device_slot;
        self
    }
    /// The configuration with [`detect_cycle`](Self::detect_cycle) replaced.
    #[must_use]
    pub fn with_detect_cycle(mut self, detect_cycle: Duration) -> Self {
        self.detect_cycle = detect_cycle;
        self
    }
    /// The configuration with [`master_timeout`](Self::master_timeout) replaced.
    #[must_use]
    pub fn with_master_timeout(mut self, master_timeout: Duration) -> Self {
        self.master_timeout = master_timeout;
        self
    }
    /// The configuration with [`revertive`](Self::revertive) replaced.
    #[must_use]
    pub fn with_revertive(mut self, revertive: bool) -> Self {
        self.revertive = revertive;
        self
    }
    /// The configuration with [`handback_delay`](Self::handback_delay) replaced.
    #[must_use]
    pub fn with_handback_delay(mut self, handback_delay: Duration) -> Self {
        self.handback_delay = handback_delay;
        self
    }
}

impl FlyingMasterConfig {
    /// The 0x1F90 defaults for a device of `priority` and `node`, with a master-heartbeat timeout.
    #[must_use]
    pub const fn new(priority: u8, node: NodeId, master_timeout: Duration) -> Self {
        FlyingMasterConfig {
            rank: Rank::new(priority, node),
            detection_timeout: Duration::from_millis(100),
            negotiation_delay: Duration::from_millis(500),
            priority_slot: Duration::from_millis(1500),
            device_slot: Duration::from_millis(10),
            detect_cycle: Duration::from_millis(4000),
            master_timeout,
            revertive: false,
            handback_delay: Duration::from_millis(1000),
        }
    }
    /// Wait of a negotiation, from its start.
    pub fn negotiation_wait(&self) -> Duration {
        self.negotiation_delay
            + self.priority_slot.saturating_mul(self.rank.priority as u64)
            + self.device_slot.saturating_mul(self.rank.node.raw() as u64)
    }
}

/// NMT start-up (0x1F80); bit 5 makes a device flying-master capable.
pub const NMT_STARTUP: u16 = 0x1F80;
/// Flying-master timing (0x1F90).
pub const FLYING_MASTER_TIMING: u16 = 0x1F90;
/// 0x1F80 bit 5: NMT flying master.
pub const STARTUP_FLYING_MASTER: u32 = 1 << 5;

/// The seven entries of 0x1F90 with the CiA 302-2 defaults (times in ms).
pub const fn timing_objects() -> [ObjectDef; 7] {
    const fn rec(d: ObjectDef) -> ObjectDef {
        d.object_type(ObjectType::Record)
    }
    const I: u16 = FLYING_MASTER_TIMING;
    [
        rec(ObjectDef::u8(I, 0, Access::Const, 6)).named("NMT flying master timing parameters"),
        rec(ObjectDef::u16(I, 1, Access::Rw, 100)).named("Active master detection timeout"),
        rec(ObjectDef::u16(I, 2, Access::Rw, 500)).named("Negotiation delay"),
        rec(ObjectDef::u16(I, 3, Access::Rw, 0)).named("NMT master priority"),
        rec(ObjectDef::u16(I, 4, Access::Rw, 1500)).named("Priority time slot"),
        rec(ObjectDef::u16(I, 5, Access::Rw, 10)).named("CANopen device time slot"),
        rec(ObjectDef::u16(I, 6, Access::Rw, 4000)).named("Multiple master detect cycle time"),
    ]
}

impl FlyingMasterConfig {
    /// Reads 0x1F80 and 0x1F90 of `node`'s dictionary: `None` if 0x1F80 bit 5 is clear (not a
    /// flying master). The master-heartbeat timeout is not a 302-2 entry and is given.
    pub fn from_od<D: ObjectDictionary>(
        od: &D,
        node: NodeId,
        master_timeout: Duration,
    ) -> Result<Option<Self>, ConfigError> {
        if read(od, NMT_STARTUP, 0)? & STARTUP_FLYING_MASTER == 0 {
            return Ok(None);
        }
        let ms = |sub| read(od, FLYING_MASTER_TIMING, sub).map(|v| Duration::from_millis(v as u64));
        let priority = read(od, FLYING_MASTER_TIMING, 3)?;
        let priority = u8::try_from(priority).map_err(|_| ConfigError::Invalid {
            index: FLYING_MASTER_TIMING,
            sub: 3,
            what: "priority above 255",
        })?;
        Ok(Some(FlyingMasterConfig {
            detection_timeout: ms(1)?,
            negotiation_delay: ms(2)?,
            priority_slot: ms(4)?,
            device_slot: ms(5)?,
            detect_cycle: ms(6)?,
            ..FlyingMasterConfig::new(priority, node, master_timeout)
        }))
    }
}

/// Where the device is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterRole {
    /// Not started.
    Off,
    /// Asked for the active master; waiting for an answer.
    Detecting,
    /// Negotiating; announces itself at the end of its wait.
    Negotiating,
    /// The active master.
    Active,
    /// A standby following the active master (if known).
    Standby(Option<Rank>),
}

impl MasterRole {
    /// True when active.
    pub fn is_active(&self) -> bool {
        *self == MasterRole::Active
    }
}

impl fmt::Display for MasterRole {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MasterRole::Off => f.write_str("off"),
            MasterRole::Detecting => f.write_str("detecting"),
            MasterRole::Negotiating => f.write_str("negotiating"),
            MasterRole::Active => f.write_str("active"),
            MasterRole::Standby(Some(r)) => write!(f, "standby (active: {r})"),
            MasterRole::Standby(None) => f.write_str("standby"),
        }
    }
}

/// Why the role changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasterReason {
    /// Power-on: started detection.
    PowerOn,
    /// No active master answered: negotiation.
    NoActiveMaster,
    /// A negotiation was requested or forced by another device.
    NegotiationRequested,
    /// Won the negotiation (nobody announced earlier).
    NegotiationWon,
    /// Another device announced itself, or was found, active.
    ActiveMasterFound(Rank),
    /// The active master's heartbeat stopped (its last heartbeat).
    HeartbeatLost {
        /// The lost master.
        master: NodeId,
        /// Its last heartbeat.
        last: Instant,
    },
    /// The active master sent a boot-up: it rebooted and is no longer active.
    MasterRebooted(NodeId),
    /// Two active masters: this one is worse and stepped down.
    ConflictLost(Rank),
    /// Appointed by the active master's hand-over.
    Appointed,
    /// Handed the role over to another master.
    HandedOver(Rank),
    /// The application asked (take over / stand by).
    Manual,
}

impl fmt::Display for MasterReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MasterReason::PowerOn => f.write_str("power-on: active-master detection"),
            MasterReason::NoActiveMaster => f.write_str("no active master answered"),
            MasterReason::NegotiationRequested => f.write_str("negotiation requested"),
            MasterReason::NegotiationWon => f.write_str("won the negotiation"),
            MasterReason::ActiveMasterFound(r) => write!(f, "active master is {r}"),
            MasterReason::HeartbeatLost { master, last } => {
                write!(f, "heartbeat of active master {master} lost (last {last})")
            }
            MasterReason::MasterRebooted(n) => write!(f, "active master {n} rebooted"),
            MasterReason::ConflictLost(r) => {
                write!(f, "two active masters: {r} ranks better")
            }
            MasterReason::Appointed => f.write_str("appointed by the active master's hand-over"),
            MasterReason::HandedOver(r) => write!(f, "handed over to {r}"),
            MasterReason::Manual => f.write_str("commanded by the application"),
        }
    }
}

/// The device's role changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MasterRoleChange {
    /// When (deadline-driven changes: exactly the deadline).
    pub at: Instant,
    /// Before.
    pub from: MasterRole,
    /// After.
    pub to: MasterRole,
    /// Why.
    pub reason: MasterReason,
}

impl fmt::Display for MasterRoleChange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: master {} -> {}: {}",
            self.at, self.from, self.to, self.reason
        )
    }
}

/// What the flying master reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum FlyingEvent {
    /// The role changed.
    Role(MasterRoleChange),
    /// Another active master was suspected; commands are suspended until `until`.
    Suspended {
        /// When.
        at: Instant,
        /// End of the suspension, unless the conflict resolves earlier.
        until: Instant,
    },
}

/// Another master-capable device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Peer {
    /// Its rank.
    pub rank: Rank,
    /// Last heartbeat (or flying-master frame).
    pub last: Option<Instant>,
    /// Heard without a loss since this device became active.
    continuous: bool,
    /// Its heartbeat had been lost (a return is a hint of a healed partition).
    lost: bool,
}

/// Why a command of the application was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlyingMasterError {
    /// No live master to hand over to.
    NoSuccessor,
    /// Only an active master can hand over; only a standby can take over.
    WrongRole(MasterRole),
    /// The peer table is full.
    PeersFull,
}

impl core::error::Error for FlyingMasterError {}

impl fmt::Display for FlyingMasterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FlyingMasterError::NoSuccessor => {
                f.write_str("no other master is alive to take over: staying active")
            }
            FlyingMasterError::WrongRole(r) => write!(f, "not possible while {r}"),
            FlyingMasterError::PeersFull => write!(f, "at most {MAX_PEERS} other masters"),
        }
    }
}

/// Where the device is, with the data only that phase has. Every transition builds the new
/// variant whole, so nothing of one role (a detection cycle, a suspension, a hand-back) outlives
/// it into the next; the public [`MasterRole`] is read off it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Not started.
    Off,
    /// Asked for the active master; negotiates at `until` if nobody answered.
    Detecting { until: Instant },
    /// Announces itself at `until` unless another device announced first.
    Negotiating { until: Instant },
    /// Follows `master` (if known) and takes over at `takeover_at`: the master's heartbeat
    /// deadline, or, the master lost, the end of the slots of the live devices ranked better.
    Standby {
        master: Option<Rank>,
        takeover_at: Instant,
    },
    /// The active master, with its own timers.
    Active(Active),
}

/// What only an active master keeps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Active {
    /// Next periodic 0x76 (none with a zero detect cycle).
    detect_at: Option<Instant>,
    /// NMT commands suspended until then (another active master suspected).
    suspended_until: Option<Instant>,
    /// A revertive hand-back is due then.
    handback_at: Option<Instant>,
    /// The hand-back that became due, until the supervisor takes it.
    handback: Option<Rank>,
}

impl State {
    fn role(&self) -> MasterRole {
        match self {
            State::Off => MasterRole::Off,
            State::Detecting { .. } => MasterRole::Detecting,
            State::Negotiating { .. } => MasterRole::Negotiating,
            State::Standby { master, .. } => MasterRole::Standby(*master),
            State::Active(_) => MasterRole::Active,
        }
    }
}

/// One master-capable device's part of the flying-master protocol.
pub struct FlyingMaster {
    cfg: FlyingMasterConfig,
    state: State,
    peers: Vec<Peer, MAX_PEERS>,
    tx: Bounded<Frame, 16>,
    events: Bounded<FlyingEvent, 16>,
}

impl FlyingMaster {
    /// A device that has not started.
    #[must_use]
    pub fn new(cfg: FlyingMasterConfig) -> Self {
        FlyingMaster {
            cfg,
            state: State::Off,
            peers: Vec::new(),
            tx: Bounded::new(),
            events: Bounded::new(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &FlyingMasterConfig {
        &self.cfg
    }
    /// This device's rank.
    pub fn rank(&self) -> Rank {
        self.cfg.rank
    }
    /// The role now.
    pub fn role(&self) -> MasterRole {
        self.state.role()
    }
    /// True when active.
    pub fn is_active(&self) -> bool {
        matches!(self.state, State::Active(_))
    }
    /// Active and not suspended: NMT commands to slaves may be sent at `now`.
    pub fn may_command(&self, now: Instant) -> bool {
        matches!(self.state, State::Active(a) if a.suspended_until.is_none_or(|u| now >= u))
    }
    /// The other master-capable devices known.
    pub fn peers(&self) -> &[Peer] {
        &self.peers
    }
    /// The active master, as far as this device knows (itself when active).
    pub fn active_master(&self) -> Option<Rank> {
        match self.state {
            State::Active(_) => Some(self.cfg.rank),
            State::Standby { master, .. } => master,
            _ => None,
        }
    }

    /// Declares another master-capable device (its heartbeat is then watched).
    pub fn add_peer(&mut self, rank: Rank) -> Result<(), FlyingMasterError> {
        self.learn(rank)
            .map(|_| ())
            .ok_or(FlyingMasterError::PeersFull)
    }

    /// Power-on: ask for the active master. Called again, it starts over from the detection,
    /// whatever the role was.
    pub fn start(&mut self, now: Instant) {
        self.send(ACTIVE_MASTER_REQUEST, &[]);
        let until = now + self.cfg.detection_timeout;
        self.change(now, State::Detecting { until }, MasterReason::PowerOn);
    }

    // ----- inputs -----

    /// A frame from the bus; true if it was a flying-master frame.
    pub fn handle_frame(&mut self, now: Instant, frame: &Frame) -> bool {
        let Id::Standard(id) = frame.id() else {
            return false;
        };
        if !(ACTIVE_MASTER_RESPONSE..=FORCE_NEGOTIATION).contains(&id) || frame.is_remote() {
            return false;
        }
        let rank = Rank::from_payload(frame.data());
        if let Some(r) = rank.filter(|r| r.node != self.cfg.rank.node) {
            let _ = self.learn(r);
        }
        match (id, rank) {
            (ACTIVE_MASTER_RESPONSE, Some(r)) => self.on_announcement(now, r),
            (NEGOTIATION_REQUEST, _) => match self.state {
                State::Active(_) => self.announce(),
                State::Negotiating { .. } | State::Off => {}
                _ => self.negotiate(now, MasterReason::NegotiationRequested),
            },
            (ACTIVE_MASTER_REQUEST, _) if self.is_active() => self.announce(),
            (MASTER_CAPABLE_REQUEST, _) if self.state != State::Off => {
                self.send(MASTER_CAPABLE_RESPONSE, &self.cfg.rank.payload());
            }
            (FORCE_NEGOTIATION, Some(r)) if r.node != self.cfg.rank.node => self.on_force(now, r),
            _ => {}
        }
        true
    }

    /// A heartbeat of `node`; `boot_up` if it is a boot-up message. Tracks the other masters:
    /// only heartbeats (not flying-master frames) move the takeover deadline, so that it is
    /// exactly the active master's last heartbeat + the timeout.
    pub fn heartbeat(&mut self, now: Instant, node: NodeId, boot_up: bool) {
        let timeout = self.cfg.master_timeout;
        let Some(p) = self.peers.iter_mut().find(|p| p.rank.node == node) else {
            return;
        };
        let gap = p.last.is_none_or(|l| l + timeout <= now);
        let returned = p.lost || (gap && p.last.is_some());
        if gap {
            p.continuous = false;
        }
        p.last = Some(now);
        p.lost = false;
        let rank = p.rank;
        // A master that was lost while this one was active and comes back without booting may
        // have been active behind a partition. A rebooted one starts by detecting: no conflict.
        if returned && !boot_up && self.is_active() {
            self.suspect(now);
        }
        if matches!(self.state, State::Standby { master: Some(m), .. } if m == rank) {
            if boot_up {
                // The active master rebooted (faster than the timeout): it is not active any
                // more and starts by detecting; take over now rather than leave the network
                // without a master for a whole negotiation.
                return self.lose_master(now, rank, MasterReason::MasterRebooted(node));
            }
            self.state = State::Standby {
                master: Some(rank),
                takeover_at: now + timeout,
            };
        }
        self.plan_handback(now);
    }

    /// A SYNC or NMT command this device did not send: if active, another master may be.
    pub fn foreign_activity(&mut self, now: Instant) {
        if self.is_active() {
            self.suspect(now);
        }
    }

    // ----- commands -----

    /// Hands the role to `to` (or the best live peer): announces it on 0x71 and becomes its
    /// standby.
    pub fn hand_over(&mut self, now: Instant, to: Option<Rank>) -> Result<Rank, FlyingMasterError> {
        if !self.is_active() {
            return Err(FlyingMasterError::WrongRole(self.role()));
        }
        let to = match to {
            Some(r) => r,
            None => self
                .best_live_peer(now)
                .ok_or(FlyingMasterError::NoSuccessor)?,
        };
        self.send(ACTIVE_MASTER_RESPONSE, &to.payload());
        self.follow(now, to, MasterReason::HandedOver(to));
        Ok(to)
    }

    /// Takes the role by hand (standby): announces itself. An active master that has heard this
    /// one alive all along steps down.
    pub fn take_over(&mut self, now: Instant) -> Result<(), FlyingMasterError> {
        match self.state {
            State::Standby { .. } | State::Negotiating { .. } | State::Detecting { .. } => {
                self.activate(now, MasterReason::Manual);
                Ok(())
            }
            _ => Err(FlyingMasterError::WrongRole(self.role())),
        }
    }

    /// A revertive hand-back that became due (the supervisor performs it between two SYNCs).
    pub fn take_handback(&mut self) -> Option<Rank> {
        match &mut self.state {
            State::Active(a) => a.handback.take(),
            _ => None,
        }
    }

    // ----- time -----

    /// Earliest deadline.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        match self.state {
            State::Off => None,
            State::Detecting { until }
            | State::Negotiating { until }
            | State::Standby {
                takeover_at: until, ..
            } => earliest_of([Some(until)]),
            State::Active(a) => earliest_of([a.detect_at, a.suspended_until, a.handback_at]),
        }
    }

    /// Does what is due at `now`.
    pub fn handle_timeout(&mut self, now: Instant) {
        match self.state {
            State::Off => {}
            State::Active(a) => self.active_timers(now, a),
            State::Detecting { until: t } if t <= now => {
                self.send(NEGOTIATION_REQUEST, &[]);
                self.negotiate(t, MasterReason::NoActiveMaster);
            }
            State::Negotiating { until: t } if t <= now => {
                self.activate(t, MasterReason::NegotiationWon)
            }
            State::Standby {
                master: Some(master),
                takeover_at: t,
            } if t <= now => self.master_silent(t, master),
            State::Standby {
                master: None,
                takeover_at: t,
            } if t <= now => {
                // A pending takeover (better live peers had their slots first).
                self.activate(t, MasterReason::NoActiveMaster)
            }
            _ => {}
        }
    }

    // ----- outputs -----

    /// Next frame to send.
    #[must_use]
    pub fn poll_transmit(&mut self) -> Option<Frame> {
        self.tx.pop()
    }
    /// Next event.
    #[must_use]
    pub fn poll_event(&mut self) -> Option<FlyingEvent> {
        self.events.pop()
    }

    // ----- internals -----

    /// The active master's timers due at `now`; `a` is its data, written back at the end (no
    /// timer changes the role).
    fn active_timers(&mut self, now: Instant, mut a: Active) {
        if a.suspended_until.is_some_and(|u| u <= now) {
            a.suspended_until = None;
        }
        if let Some(t) = a.detect_at.filter(|t| *t <= now) {
            self.send(FORCE_NEGOTIATION, &self.cfg.rank.payload());
            // On the cycle's grid; after a jump of the clock past further cycles, one cycle
            // after `now`: one request for all the missed ones, not a burst of them.
            let next = t + self.cfg.detect_cycle;
            a.detect_at = self.detection_after(if next <= now { now } else { t });
        }
        if let Some(t) = a.handback_at.filter(|t| *t <= now) {
            a.handback_at = None;
            a.handback = self.better_live_peer(t);
        }
        self.state = State::Active(a);
    }

    fn on_announcement(&mut self, now: Instant, r: Rank) {
        if r == self.cfg.rank {
            // Named by someone else's 0x71: a hand-over to this device.
            if !self.is_active() {
                self.activate(now, MasterReason::Appointed);
            }
            return;
        }
        match self.state {
            State::Active(_) => {
                let planned = self
                    .peers
                    .iter()
                    .any(|p| p.rank == r && p.continuous && !p.lost);
                if r < self.cfg.rank || planned {
                    self.follow(now, r, MasterReason::ConflictLost(r));
                } else {
                    // A worse master claims the role: assert ours.
                    self.send(FORCE_NEGOTIATION, &self.cfg.rank.payload());
                    self.suspect(now);
                }
            }
            State::Off => {}
            _ => self.follow(now, r, MasterReason::ActiveMasterFound(r)),
        }
    }

    fn on_force(&mut self, now: Instant, r: Rank) {
        match self.state {
            State::Active(_) => {
                if r < self.cfg.rank {
                    self.follow(now, r, MasterReason::ConflictLost(r));
                } else {
                    // We rank better: tell the other one (and everyone) who is active.
                    self.announce();
                }
            }
            // The periodic detection of the master followed, or of a worse one (which the
            // better one will deal with).
            State::Standby {
                master: Some(m), ..
            } if m <= r => {}
            State::Off => {}
            _ => self.follow(now, r, MasterReason::ActiveMasterFound(r)),
        }
    }

    fn master_silent(&mut self, t: Instant, master: Rank) {
        let last = t - self.cfg.master_timeout;
        let reason = MasterReason::HeartbeatLost {
            master: master.node,
            last,
        };
        self.lose_master(t, master, reason);
    }

    fn lose_master(&mut self, t: Instant, master: Rank, reason: MasterReason) {
        if let Some(p) = self.peers.iter_mut().find(|p| p.rank == master) {
            p.lost = true;
            p.continuous = false;
        }
        let better = self
            .peers
            .iter()
            .filter(|p| p.rank < self.cfg.rank && p.rank != master && self.alive(p, t))
            .count() as u64;
        if better == 0 {
            self.activate(t, reason);
        } else {
            let takeover_at = t + self.cfg.device_slot.saturating_mul(better);
            let pending = State::Standby {
                master: None,
                takeover_at,
            };
            self.change(t, pending, reason);
        }
    }

    /// The next periodic detection, a cycle after `from`; none with a zero cycle (a request
    /// due again at the instant it was sent would never let time move on).
    fn detection_after(&self, from: Instant) -> Option<Instant> {
        let cycle = self.cfg.detect_cycle;
        (!cycle.is_zero()).then(|| from + cycle)
    }

    fn negotiate(&mut self, now: Instant, reason: MasterReason) {
        let until = now + self.cfg.negotiation_wait();
        self.change(now, State::Negotiating { until }, reason);
    }

    fn activate(&mut self, now: Instant, reason: MasterReason) {
        for p in self.peers.iter_mut() {
            p.continuous = p.last.is_some_and(|l| l + self.cfg.master_timeout > now);
        }
        self.announce();
        let active = Active {
            detect_at: self.detection_after(now),
            ..Active::default()
        };
        self.change(now, State::Active(active), reason);
        self.plan_handback(now);
    }

    fn follow(&mut self, now: Instant, r: Rank, reason: MasterReason) {
        // Watched from its last heartbeat if that is recent, else from now.
        let timeout = self.cfg.master_timeout;
        let last = self
            .peers
            .iter()
            .find(|p| p.rank == r)
            .and_then(|p| p.last)
            .filter(|l| *l + timeout > now)
            .unwrap_or(now);
        let standby = State::Standby {
            master: Some(r),
            takeover_at: last + timeout,
        };
        self.change(now, standby, reason);
    }

    /// Active: another active master may be there; commands stop until the detection timeout
    /// has passed without a conflict.
    fn suspect(&mut self, now: Instant) {
        let until = now + self.cfg.detection_timeout;
        let State::Active(a) = &mut self.state else {
            return;
        };
        let fresh = a.suspended_until.is_none();
        a.suspended_until = Some(until);
        if fresh {
            self.send(FORCE_NEGOTIATION, &self.cfg.rank.payload());
            self.events.push(FlyingEvent::Suspended { at: now, until });
        }
    }

    fn plan_handback(&mut self, now: Instant) {
        let planned = match self.state {
            State::Active(a) => a.handback_at.is_some(),
            _ => return,
        };
        if !self.cfg.revertive || planned || self.better_live_peer(now).is_none() {
            return;
        }
        if let State::Active(a) = &mut self.state {
            a.handback_at = Some(now + self.cfg.handback_delay);
        }
    }

    fn announce(&mut self) {
        self.send(ACTIVE_MASTER_RESPONSE, &self.cfg.rank.payload());
    }

    fn alive(&self, p: &Peer, now: Instant) -> bool {
        p.last.is_some_and(|l| l + self.cfg.master_timeout > now)
    }

    fn best_live_peer(&self, now: Instant) -> Option<Rank> {
        self.peers
            .iter()
            .filter(|p| self.alive(p, now))
            .map(|p| p.rank)
            .min()
    }

    fn better_live_peer(&self, now: Instant) -> Option<Rank> {
        self.best_live_peer(now).filter(|r| *r < self.cfg.rank)
    }

    fn learn(&mut self, r: Rank) -> Option<usize> {
        if let Some(i) = self.peers.iter().position(|p| p.rank.node == r.node) {
            self.peers[i].rank = r;
            return Some(i);
        }
        self.peers
            .push(Peer {
                rank: r,
                last: None,
                continuous: false,
                lost: false,
            })
            .ok()?;
        Some(self.peers.len() - 1)
    }

    fn send(&mut self, id: u16, data: &[u8]) {
        if let Ok(f) = Frame::new(Id::Standard(id), data) {
            self.tx.push(f);
        }
    }

    /// Enters `to`; reports a role change if the role differs (following the same master
    /// again only re-times its deadline).
    fn change(&mut self, at: Instant, to: State, reason: MasterReason) {
        let from = self.role();
        self.state = to;
        let to = self.role();
        if from == to {
            return;
        }
        self.events.push(FlyingEvent::Role(MasterRoleChange {
            at,
            from,
            to,
            reason,
        }));
    }
}

impl fmt::Debug for FlyingMaster {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("FlyingMaster")
            .field("rank", &self.cfg.rank)
            .field("role", &self.role())
            .field("peers", &self.peers)
            .finish_non_exhaustive()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan::od::{comm, StaticDictionary};

    static COMM: [ObjectDef; comm::COMM_LEN] = comm::communication();
    static STARTUP: [ObjectDef; 1] = [ObjectDef::u32(NMT_STARTUP, 0, Access::Rw, 0)];
    static TIMING: [ObjectDef; 7] = timing_objects();

    #[test]
    fn configuration_from_the_dictionary() {
        let mut od = StaticDictionary::<64, 512>::new();
        od.load(1, &[&COMM, &STARTUP, &TIMING]).unwrap();
        let node = NodeId::must(1);
        let t = Duration::from_millis(50);
        assert_eq!(FlyingMasterConfig::from_od(&od, node, t), Ok(None));
        od.set_value::<u32>(NMT_STARTUP, 0, 0x21).unwrap();
        od.set_value::<u16>(FLYING_MASTER_TIMING, 3, 2).unwrap();
        od.set_value::<u16>(FLYING_MASTER_TIMING, 6, 1000).unwrap();
        let c = FlyingMasterConfig::from_od(&od, node, t).unwrap().unwrap();
        assert_eq!(c.rank, Rank::new(2, node));
        assert_eq!(c.detect_cycle, Duration::from_millis(1000));
        assert_eq!(c.detection_timeout, Duration::from_millis(100));
        assert_eq!(
            c.negotiation_wait(),
            Duration::from_millis(500 + 2 * 1500 + 10)
        );
        od.set_value::<u16>(FLYING_MASTER_TIMING, 3, 300).unwrap();
        assert!(FlyingMasterConfig::from_od(&od, node, t).is_err());
    }
}
