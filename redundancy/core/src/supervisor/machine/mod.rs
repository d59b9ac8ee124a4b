//! The supervisor: a redundant master's brain on one logical bus.
//!
//! [`Supervisor`] is a [`Machine`] composing the CiA 302-2 [`Master`] (its node: heartbeat,
//! SYNC, TIME, NMT state of every node; its SDO client; the boot process of every slave), the
//! [`PairSupervisor`], the [`FlyingMaster`] and the [`AuditTrail`]:
//!
//! - **Active** (strong, or weak after a takeover): the master is active
//!   ([`Master::set_active`]): it produces SYNC and TIME, boots and configures slaves, and sends
//!   the NMT commands of the pair supervision ([`Authority::Command`]); the flying master answers
//!   the requests of other master-capable devices.
//! - **Standby** (hot): the master observes: it consumes SYNC and TIME, produces its own
//!   heartbeat, guards the slaves configured for guarding, follows every node's state; the pair
//!   table follows the heartbeats and the active master's NMT commands
//!   ([`Authority::Shadow`]); the flying master watches the active master's heartbeat. At the
//!   timeout it takes over without resetting anything: the master adopts the running slaves and
//!   re-checks the pre-operational ones, the shadow table becomes the commanding one, SYNC
//!   continues the grid it consumed (the first SYNC comes at once if one is overdue, then on the
//!   old grid), TIME continues the time base it consumed.
//!
//! # Pair members and the master
//!
//! Each member of a pair is a slave of the master ([`Supervisor::add_pair`]), assigned so that
//! the supervisor decides about it: start left to the application
//! ([`StartPolicy::Application`]), no boot process of the master's own accord (0x1F81 bit 2
//! clear), neither mandatory nor keep-alive. Its boot-up makes the pair supervision ask for its
//! configuration ([`PairCommand::Configure`]), which runs the master's boot process
//! ([`Master::boot_slave`]: 0x1000/0x1018 checked against 0x1F84–0x1F88, the configuration
//! steps, PDOs, the heartbeat producer time); [`MasterEventKind::SlaveConfigured`] makes it
//! joined. A wrong identity or a failed configuration keeps it out, and
//! [`SupervisorEvent::NotJoined`] says why. NMT commands go through the master
//! ([`Master::nmt`]), so that its view of every slave follows them. Other slaves are plain
//! slaves of the master ([`Supervisor::add_slave`], or the
//! [`MasterConfig`](duocan_core::master::MasterConfig) the master was built with), booted and
//! started by it.
//!
//! Each member's heartbeats are judged by the dual-bus layer too ([`LinkCommand::Watch`] with
//! its producer time, at [`Supervisor::add_pair`]): a babbling identifier, a duplicate node-ID
//! or an impostor on one bus makes the member suspect ([`LinkRequest::NodeSuspect`]), and a
//! suspect member is handled like a silent one at once; the bounds are in
//! [`pairs`](crate::supervisor::pairs#heartbeats-that-lie).
//!
//! A replacement board that arrives without a node-ID (LSS, CiA 305) is found by the active
//! supervisor when it is configured to look ([`SupervisorConfig::with_lss`]): while a pair slot
//! is vacant it asks every period whether a non-configured board is on the bus, and gives each
//! one found by fastscan the node-ID of the vacant slot whose expected identity (0x1F85–0x1F88,
//! zero parts unchecked) it has ([`SupervisorEvent::Addressed`], an audit record); the board
//! resets its communication with that node-ID and joins as above (`replacement.rs`).
//!
//! Which pair member is active must reach the dual-bus layer (same-function merge): the
//! supervisor's [`Machine::LinkCommand`]s are [`LinkCommand`]s, which a
//! [`Station`](duocan_core::Station) on a [`DualBus`](crate::DualBus) hands to the layer after every
//! input; [`SupervisedStation`](crate::station::SupervisedStation) is that station with the
//! pairs configured in the layer from the start and a status table.
//!
//! On a CANopen FD network (feature `fd`) the CAN FD frames the layer delivers go to the
//! master, whose node serves USDO when it is configured to, and its answers go back through
//! the layer on both buses; error control there is heartbeats alone, which is all the pair
//! supervision and the flying master judge (node guarding needs remote frames, which CAN FD
//! has not: a supervisor configured to guard is refused at start, see `fd_guarding`).
//!
//! This file holds the machine itself: its construction, the [`Machine`] inputs and the pump
//! that moves every part's outputs to where they belong; `application.rs` holds what the
//! application calls, `reactions.rs` what the supervisor does with what its parts report.
//!
//! ```
//! use duocan_core::master::{objects, Master, MasterConfig};
//! use duocan_core::od::comm;
//! use duocan::sim::{BusConfig, SimNetwork};
//! use duocan_core::{Duration, Instant, Node, NodeConfig, NodeId, Station};
//! use duocan_redundancy_core::PairSpec;
//! use duocan_redundancy_core::{DualBus, DualBusConfig, Member, PairId, SupervisedStation, Supervisor, SupervisorConfig};
//!
//! let ms = Duration::from_millis;
//! let mut sim = SimNetwork::new(1);
//! let buses = [sim.add_bus(BusConfig::new("can1", 1_000_000)), sim.add_bus(BusConfig::new("can2", 1_000_000))];
//! // A master alone (a weak peer, node 2, is declared but absent), one pair of boards.
//! let od = objects::master_dictionary(1, comm::Identity::default());
//! let master = Master::new(NodeId::must(1), od, MasterConfig::new()).unwrap();
//! let cfg = SupervisorConfig::new(0, NodeId::must(1), ms(20), ms(50), ms(10)).with_peer(1, NodeId::must(2));
//! let mut sup = Supervisor::new(master, cfg, Instant::ZERO);
//! sup.add_pair(Instant::ZERO, PairSpec::new(NodeId::must(0x10), NodeId::must(0x50), ms(20), ms(50)))?;
//! let master = sim.add_device("master", SupervisedStation::new(DualBus::new(DualBusConfig::default()), sup).unwrap(), &buses)?;
//! for id in [0x10, 0x50] {
//!     let mut n = Node::new(NodeConfig::slave(NodeId::must(id)), comm::standard_dictionary(id, Default::default()));
//!     n.boot(Instant::ZERO);
//!     sim.add_device(format!("board {id:#x}"), Station::new(DualBus::new(DualBusConfig::default()), n), &buses)?;
//! }
//! sim.run_until(Instant::from_secs(1));
//! let st = sim.device(master);
//! assert!(st.sup().is_active());
//! assert_eq!(st.sup().pair_supervisor().pair(PairId(0)).unwrap().active, Some(Member::A));
//! println!("{}", st.status(Instant::from_secs(1)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use crate::link::dual_bus::LinkCommand;
use crate::supervisor::audit::{AuditEntry, AuditTrail, AUDIT_CAPACITY};
use crate::supervisor::flying_master::{FlyingMaster, Rank};
use crate::supervisor::pairs::{Authority, PairSupervisor, PairsEvent};
use alloc::collections::VecDeque;
use core::fmt;
use duocan_core::cia305::{LssMaster, LssMasterConfig};
use duocan_core::frame::instant::{earliest_of, next_on_grid, shift_back, TimeWatch};
use duocan_core::frame::queue::Bounded;
use duocan_core::frame::storage::Heap;
use duocan_core::machine::{LinkRequest, Machine};
use duocan_core::master::{objects, Master, NmtStartup};
use duocan_core::nmt;
use duocan_core::od::{comm, ObjectDictionary};
use duocan_core::profile::{IdProfile, Predefined, ProfileFrame};
use duocan_core::{Duration, Frame, Instant, NmtState, NodeId};

use super::config::SupervisorConfig;
use super::events::{SupervisorEvent, SupervisorStats};

mod application;
mod reactions;
mod replacement;

pub use replacement::LSS_SLOTS;

/// Flying-master frames the supervisor itself can hold.
pub const TX_QUEUE: usize = 64;
/// 0x1012 bit 31: consume TIME; bit 30: produce it (the master sets it while active).
const TIME_CONSUMER: u32 = 1 << 31;
const TIME_PRODUCER: u32 = 1 << 30;

/// A planned hand-over or take-over, done between two SYNCs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Planned {
    HandOver(Option<Rank>),
    TakeOver,
}

/// A redundant master: the CiA 302-2 master, pair supervision, flying master, audit trail.
/// `D` and `P` are the [`Master`]'s dictionary and identifier profile.
pub struct Supervisor<D, P = Predefined> {
    master: Master<D, P>,
    pairs: PairSupervisor<Heap>,
    fm: FlyingMaster,
    audit: AuditTrail<AUDIT_CAPACITY, Heap>,
    cfg: SupervisorConfig,
    tx: Bounded<Frame, TX_QUEUE>,
    events: VecDeque<SupervisorEvent>,
    events_dropped: u32,
    link: Bounded<LinkCommand, 256>,
    /// Last SYNC produced or received (the grid planned switches align to).
    last_sync: Option<Instant>,
    planned: Option<(Planned, Instant)>,
    stats: SupervisorStats,
    /// Notices the caller's clock stepping back, for every part (the clock contract).
    clock: TimeWatch,
    /// Board replacement by LSS (`replacement.rs`): the LSS master and the next look.
    lss: LssMaster<LSS_SLOTS>,
    lss_due: Option<Instant>,
    /// [`Supervisor::start`] ran.
    started: bool,
    /// The least lateness that is a jump ([`Supervisor::unwatched`]).
    late: Duration,
    /// When the layer last handed a frame over ([`Supervisor::watch_clock`]).
    heard: Option<Instant>,
    /// No silence is observed again before then: what the last observation re-armed is judged
    /// first, so a network that is often quiet cannot put a judgment off again and again.
    observed_until: Instant,
    /// The longest timeout a node is judged with (a pair's consumer time, the master timeout).
    hold: Duration,
}

impl<D: ObjectDictionary, P: IdProfile> Supervisor<D, P> {
    /// A supervisor on `master` (built, not booted). The supervisor makes it a standby until
    /// the flying master decides, sets its heartbeat, SYNC period and production, makes it a
    /// TIME consumer (so that a takeover continues the time base), sets 0x1F80 bits 0 (NMT
    /// master) and 5 (flying master), boots it at `now` and starts the flying-master detection.
    #[must_use]
    pub fn new(master: Master<D, P>, cfg: SupervisorConfig, now: Instant) -> Self {
        let mut s = Self::unstarted(|| master, cfg);
        s.start(now);
        s
    }

    /// A supervisor on the master `make` builds (not booted), not started: what
    /// [`new`](Self::new) does in two steps, for building it in place. `make` is called last,
    /// after everything else is ready, so that a constructor that is not inlined writes the
    /// master straight into the supervisor (on a microcontroller every move of these tens of
    /// kilobytes is a copy on the stack); [`start`](Self::start) then does the rest where the
    /// supervisor stands. Nothing is sent, no timer runs until it is started.
    #[must_use]
    #[inline]
    pub fn unstarted(make: impl FnOnce() -> Master<D, P>, cfg: SupervisorConfig) -> Self {
        let mut fm = FlyingMaster::new(cfg.flying);
        for p in &cfg.peers {
            let _ = fm.add_peer(*p);
        }
        let pairs = PairSupervisor::with_capacity(cfg.pairs, cfg.pair_capacity, cfg.pair_queue);
        let audit = AuditTrail::with_capacity(cfg.audit_capacity);
        // Allocated once here and never grown: `emit` checks the capacity first.
        let events = VecDeque::with_capacity(cfg.event_queue.max(1));
        let (tx, link) = (Bounded::new(), Bounded::new());
        let lss = LssMaster::new(LssMasterConfig::default());
        Supervisor {
            master: make(),
            pairs,
            fm,
            audit,
            cfg,
            tx,
            events,
            events_dropped: 0,
            link,
            last_sync: None,
            planned: None,
            stats: SupervisorStats::default(),
            clock: TimeWatch::new(),
            lss,
            lss_due: None,
            started: false,
            late: Duration::MAX,
            heard: None,
            observed_until: Instant::ZERO,
            hold: Duration::ZERO,
        }
    }

    /// Writes the network configuration into a master built with
    /// [`Master::unconfigured`] (for building it in place, see [`unstarted`](Self::unstarted)):
    /// [`Master::configure`], before [`start`](Self::start) boots the master; after it,
    /// [`MasterError::AlreadyBooted`](duocan_core::master::MasterError::AlreadyBooted).
    pub fn configure_master(
        &mut self,
        config: duocan_core::master::MasterConfig,
    ) -> Result<(), duocan_core::master::MasterError> {
        self.master.configure(config)
    }

    /// Starts an [`unstarted`](Self::unstarted) supervisor at `now`: everything
    /// [`new`](Self::new) describes, on the master where it stands. A second call does
    /// nothing (the master is booted once).
    pub fn start(&mut self, now: Instant) {
        if self.started {
            return;
        }
        self.started = true;
        let cfg = &self.cfg;
        let master = &mut self.master;
        master.set_active(now, false);
        let hb = cfg.heartbeat.as_millis().min(u16::MAX as u64) as u16;
        let node = master.node_mut();
        // Entries a master dictionary has; a missing one is reported by the node's own checks.
        let _ = node.set(now, comm::HEARTBEAT_PRODUCER, 0, hb);
        let _ = node.set(
            now,
            comm::SYNC_PERIOD,
            0,
            cfg.sync_period.as_micros().min(u32::MAX as u64) as u32,
        );
        let time = node.od().get_u32(comm::TIME_COB_ID, 0).unwrap_or(0x100);
        let _ = node.set(
            now,
            comm::TIME_COB_ID,
            0,
            (time | TIME_CONSUMER) & !TIME_PRODUCER,
        );
        let startup = node.od().get_u32(objects::NMT_STARTUP, 0).unwrap_or(0);
        let startup = NmtStartup(startup)
            .with(NmtStartup::MASTER)
            .with(NmtStartup::FLYING_MASTER);
        let _ = node
            .od_mut()
            .write_local(objects::NMT_STARTUP, 0, &startup.0.to_le_bytes());
        master.set_production(now, !cfg.sync_period.is_zero(), true);
        master.boot(now);
        self.fm.start(now);
        self.pairs.set_authority(now, Authority::Shadow);
        self.watch_clock(now);
        self.measure_timeouts();
        self.pump(now);
    }

    // ----- internals -----

    /// Every input that carries a time passes it here first: three comparisons, unless it
    /// comes at least [`late`](Self::measure_timeouts) after the latest one.
    ///
    /// A network heard in total silence for `late` is observed again too: with a dozen nodes
    /// beating, nothing at all from any of them is a receive path that ran behind (a reader
    /// held up, a port queue or gateway lagging) or a cut at this master's own connector, not
    /// every node dead at once. Judged from the handing-over, the frames stuck behind would
    /// make every watched node look silent, and a standby take over and reset the boards of a
    /// network whose master is alive. A node that really died is found one timeout later: after
    /// an observation, none for the longest timeout (`hold`), so what it re-armed is judged.
    #[inline]
    fn watch_clock(&mut self, now: Instant) {
        let latest = self.clock.latest();
        if let Some(by) = self.clock.step_back(now) {
            self.step_back(now, by);
        } else if now.saturating_since(latest) >= self.late && self.unwatched(latest, now) {
            self.jumped(latest, now);
        } else if let Some(h) = self
            .heard
            .filter(|h| now >= self.observed_until && now.saturating_since(*h) >= self.late)
        {
            self.jumped(h, now);
        }
    }

    /// Whether the time from `latest` to `now` went by unwatched: an input the jump threshold
    /// after the latest one, or one at least `late` after the earliest deadline this supervisor
    /// reported (its driver was to call it then: had it, the frames of that span would have
    /// come as inputs). A span that long can hold every heartbeat a watched node sent within its
    /// timeout; a shorter one cannot, and is time that passed.
    fn unwatched(&self, latest: Instant, now: Instant) -> bool {
        now.saturating_since(latest) >= self.jump_threshold()
            || self
                .poll_timeout()
                .is_some_and(|due| now.saturating_since(due) >= self.late)
    }

    /// `late`, the least lateness that is a jump: the smallest slack a timeout is judged with (a
    /// pair's consumer time less its producer time; the master timeout less this master's
    /// heartbeat period, the masters beating alike), at least 1 ms and at most the jump
    /// threshold; and `hold`, the longest timeout. Measured when the supervisor starts and when
    /// a pair is added.
    pub(super) fn measure_timeouts(&mut self) {
        let threshold = self.jump_threshold();
        let fm = self.cfg.flying.master_timeout - self.cfg.heartbeat;
        let slack = self.pairs.slack().map_or(fm, |p| p.min(fm));
        let longest = self.pairs.longest_consumer().unwrap_or(Duration::ZERO);
        self.hold = longest.max(self.cfg.flying.master_timeout);
        self.late = if threshold == Duration::MAX {
            threshold
        } else {
            slack.max(Duration::from_millis(1)).min(threshold)
        };
    }

    /// An input this long after the latest one is a jump ahead: the pair policy's
    /// [`clock_jump`](crate::supervisor::pairs::PairsConfig::clock_jump), at least twice this
    /// master's heartbeat period (its own heartbeat calls for an input every period); zero
    /// (both zero): no jump is ever seen.
    fn jump_threshold(&self) -> Duration {
        let jump = self.pairs.config().clock_jump;
        match jump.max(self.cfg.heartbeat.saturating_mul(2)) {
            Duration::ZERO => Duration::MAX,
            j => j,
        }
    }

    /// The clock jumped ahead from `latest` to `now` (or the driver stalled): the pair members
    /// and the other masters are observed again before they are judged (the clock contract).
    #[cold]
    #[inline(never)]
    fn jumped(&mut self, latest: Instant, now: Instant) {
        self.observed_until = now + self.hold + Duration::from_micros(1);
        self.fm.jumped(latest, now);
        self.pairs.jumped(latest, now);
    }

    /// The caller's clock stepped back `by` to `now`: every part moves the times it holds back
    /// with it. The master watches the clock itself (its node and SDO client too), so it is not
    /// shifted here but shown the step ([`Master::watch_clock`], which runs no timer): first the
    /// latest time this supervisor was given (a time it may not have seen, if that input was not
    /// for it: a flying-master frame, a verdict, an application command), then `now`, so that it
    /// measures the same step as everything else, once, before any part acts on the input.
    #[cold]
    #[inline(never)]
    fn step_back(&mut self, now: Instant, by: Duration) {
        self.master.watch_clock(now + by);
        self.pairs.step_back(by);
        self.fm.step_back(by);
        shift_back(&mut self.last_sync, by);
        shift_back(&mut self.heard, by);
        self.observed_until = self.observed_until - by;
        shift_back(&mut self.lss_due, by);
        if let Some((_, at)) = self.planned.as_mut() {
            *at = *at - by;
        }
        self.master.watch_clock(now);
    }

    /// Half a SYNC period after the last SYNC (now if there is no SYNC).
    fn plan(&mut self, now: Instant, what: Planned) {
        let p = self.cfg.sync_period;
        let at = match self.last_sync {
            Some(g) if !p.is_zero() => {
                let t = g + Duration::from_micros(p.as_micros() / 2);
                // The first mid-point not before `now`, computed: a SYNC heard an hour before
                // (a jump of the clock) costs no loop over the periods in between.
                if t >= now {
                    t
                } else {
                    next_on_grid(t, p, now - Duration::from_micros(1))
                }
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

    /// A boot-up, heartbeat or guarding answer: (node, state).
    fn error_control(&self, frame: &Frame) -> Option<(NodeId, NmtState)> {
        if frame.is_remote() || frame.dlc() != 1 {
            return None;
        }
        match self.master.node().profile().classify(frame.id(), false)? {
            ProfileFrame::Heartbeat(n) | ProfileFrame::Guarding(n) => {
                let (state, _) = nmt::parse_error_control(frame).ok()?;
                Some((n, state))
            }
            _ => None,
        }
    }

    /// A pair member confirming an SDO download of its heartbeat producer time (0x1017): the
    /// last step of a master's boot process, so seen from a standby, the active master has
    /// configured it.
    fn heartbeat_confirmed(&self, frame: &Frame) -> Option<NodeId> {
        let d = frame.data();
        if frame.is_remote() || d.len() != 8 || d[..4] != [0x60, 0x17, 0x10, 0x00] {
            return None;
        }
        let sdo = self.master.sdo();
        self.pairs.pairs().find_map(|(_, p)| {
            [p.spec.a, p.spec.b]
                .into_iter()
                .find(|n| sdo.channel(*n).response == frame.id())
        })
    }

    /// The dual-bus layer's verdict on a node's heartbeats: for the pair supervision.
    #[cold]
    fn verdict(&mut self, now: Instant, node: NodeId, suspect: bool, duplicated: bool) {
        self.pairs.suspect(now, node, suspect, duplicated);
        self.pump(now);
    }

    fn emit(&mut self, e: SupervisorEvent) {
        if self.events.len() >= self.cfg.event_queue.max(1) {
            self.events_dropped = self.events_dropped.saturating_add(1);
        } else {
            self.events.push_back(e);
        }
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
                self.flying_event(now, e);
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
                self.emit(SupervisorEvent::Pairs(e));
            }
            while let Some(e) = self.master.poll_event() {
                progressed = true;
                self.manager_event(now, e);
            }
            if !progressed {
                break;
            }
        }
    }
}

impl<D: ObjectDictionary, P: IdProfile> Machine for Supervisor<D, P> {
    type Event = SupervisorEvent;
    /// Which pair member's process data the dual-bus layer delivers.
    type LinkCommand = LinkCommand;

    fn handle_frame_at(&mut self, now: Instant, frame: &Frame, at: Instant) {
        self.pairs.heard_behind(now, now.saturating_since(at));
        self.handle_frame(now, frame);
    }

    fn handle_frame(&mut self, now: Instant, frame: &Frame) {
        self.watch_clock(now);
        self.heard = Some(now);
        if frame.id() == duocan_core::cia305::codec::SLAVE_TO_MASTER {
            self.lss.handle_frame(now, frame);
            return self.lss_pump(now);
        }
        if frame.id() == duocan_core::cia305::codec::MASTER_TO_SLAVE {
            // Another master's request: it matters only to an active master (a standby looks
            // for no board), and not while its own sequence runs, which goes on regardless.
            if self.is_active() && self.lss.is_idle() {
                self.lss_heard(now);
            }
            return;
        }
        if self.fm.handle_frame(now, frame) {
            return self.pump(now);
        }
        if let Some((node, state)) = self.error_control(frame) {
            self.fm
                .heartbeat(now, node, state == NmtState::Initialising);
            self.pairs.heartbeat(now, node, state);
        } else if let Some(node) = self.heartbeat_confirmed(frame) {
            self.pairs.configuration_observed(now, node);
        }
        self.master.handle_frame(now, frame);
        self.pump(now);
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.watch_clock(now);
        self.fm.handle_timeout(now);
        if let Some(to) = self.fm.take_handback() {
            self.plan(now, Planned::HandOver(Some(to)));
        }
        // Role changes first: a takeover makes the master active before its timers run.
        self.pump(now);
        self.run_planned(now);
        self.pump(now);
        self.pairs.handle_timeout(now);
        self.pump(now);
        self.master.handle_timeout(now);
        self.pump(now);
        self.lss.handle_timeout(now);
        self.lss_tick(now);
        self.lss_pump(now);
    }

    fn poll_transmit(&mut self) -> Option<Frame> {
        if let Some(f) = self.tx.pop() {
            return Some(f);
        }
        self.lss
            .poll_transmit()
            .or_else(|| self.master.poll_transmit())
    }

    fn poll_timeout(&self) -> Option<Instant> {
        earliest_of([
            self.fm.poll_timeout(),
            self.pairs.poll_timeout(),
            self.master.poll_timeout(),
            self.planned.map(|p| p.1),
            self.lss.poll_timeout(),
            self.lss_due,
        ])
    }

    fn poll_event(&mut self) -> Option<SupervisorEvent> {
        self.events.pop_front()
    }

    /// A verdict on a node's heartbeats is for the pair supervision (a suspect member is
    /// handled like a silent one, at once); the layer's other requests (status entries, ECSS
    /// pre-operational) are for the master's node, which owns that state; its reactions reach
    /// the supervisor with its next input.
    fn handle_link_request(&mut self, now: Instant, req: LinkRequest) {
        self.watch_clock(now);
        if let LinkRequest::NodeSuspect {
            node,
            suspect,
            duplicated,
        } = req
        {
            return self.verdict(now, node, suspect, duplicated);
        }
        self.master.node_mut().handle_link_request(now, req);
    }

    fn poll_link_command(&mut self) -> Option<LinkCommand> {
        self.link.pop()
    }

    /// A CAN FD frame the layer delivered (feature `fd`): for the master, whose node serves
    /// USDO (CiA 1301) on a CANopen FD network when it is configured to
    /// ([`NodeConfig::fd`](duocan_core::NodeConfig::fd)). Heartbeats, NMT, the flying master's
    /// frames and LSS are classic frames, so nothing else of the supervisor looks at it; it is
    /// a frame heard all the same (the silence rule of the clock contract).
    #[cfg(feature = "fd")]
    fn handle_frame_fd(&mut self, now: Instant, frame: &duocan_core::frame::FdFrame) {
        self.watch_clock(now);
        self.heard = Some(now);
        self.master.handle_frame_fd(now, frame);
        self.pump(now);
    }

    /// The master's CAN FD frames (its node's USDO answers), after its classic ones.
    #[cfg(feature = "fd")]
    fn poll_transmit_fd(&mut self) -> Option<duocan_core::frame::FdFrame> {
        self.master.poll_transmit_fd()
    }
}

impl<D, P> fmt::Debug for Supervisor<D, P> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Supervisor")
            .field("fm", &self.fm)
            .field("pairs", &self.pairs)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}
