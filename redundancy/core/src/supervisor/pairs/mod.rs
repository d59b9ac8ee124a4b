//! Slave-pair supervision: a heartbeat table of redundant slave pairs, event-driven and exact.
//!
//! [`PairSupervisor`] is a sans-IO machine. Its inputs are observations — a member's boot-up or
//! heartbeat at an instant, the result of its configuration, an NMT command seen on the bus —
//! and time. Its outputs are [`PairCommand`]s (NMT start / reset / enter pre-operational of a
//! node, configure a node, tell the dual-bus layer which member is active) and [`PairsEvent`]s
//! (role changes with pair, members, reason and time; members joining, lost, missing).
//!
//! # Rules
//!
//! - **Joining.** A member's boot-up asks for its configuration ([`PairCommand::Configure`]:
//!   the CiA 302-2 boot process of the master, identity check, configuration, at least 0x1017);
//!   when [`PairSupervisor::configured`] reports success it is *joined*. The first member of a
//!   pair to be configured becomes active (but see *Member A first* below) and is started — also when a heartbeat says it runs
//!   already (a start is harmless to a running board, and the heartbeat may be a second
//!   device's with its node-ID while the board itself booted pre-operational); the other stays
//!   pre-operational as standby. A first start and a rejoin after a fault look the same. A failed configuration
//!   resets the member (it boots and is configured again); a member that is not what the
//!   configuration expects ([`PairSupervisor::rejected`]: wrong identity) is left alone, not
//!   joined, until it boots again.
//! - **Member A first.** A plant expects the configured primary, A, to run after a cold start,
//!   and with both boards present which configuration ends first is a matter of timing. So B,
//!   configured while the pair has no active member and A is being configured (its boot-up or
//!   adoption was seen, it is trusted), waits for A: A configured within the bound becomes
//!   active and B stays standby. The bound is the pair's consumer time from B's configuration:
//!   at that instant exactly a live B is started and becomes active ([`RoleReason::FirstJoined`]);
//!   a silent one is reset as always. The wait ends at once, B started, when A's configuration
//!   fails, A is rejected or its heartbeats fall in doubt; a boot-up of A during the wait does not
//!   extend it. Why that bound: a pair is allowed to run without a board for the consumer time
//!   anyway (the time it takes to find its active member silent), so waiting for A costs no
//!   more than a failover, and a pair whose B is ready is never without a running board for
//!   longer; only one member is ever started. A pair whose A was never heard (dead, unplugged)
//!   runs B at its configuration, as before; a table that takes command finds the pair without
//!   an active member and starts the live one at once (a takeover, no cold start).
//! - **Evaluation** is event-driven: every joined member has a deadline, its last heartbeat (or
//!   its configuration, whichever is later) + the pair's consumer time. At the deadline exactly:
//!   - active silent, standby alive → start the standby (it becomes active), reset the active;
//!   - standby silent (active alive, or none) → reset it;
//!   - the only joined member silent → reset it, the pair has no active member.
//!
//!   Both silent is the last two cases in a row (with one deadline each). Members reset are no
//!   longer joined; the start of the new active is emitted first, at the deadline, so it is on
//!   the bus within the consumer time + one frame.
//! - **Not operational.** The active member is expected to run. Once it has been heard
//!   operational in its role, a heartbeat of it saying pre-operational or stopped (its
//!   application or its error behaviour, CiA 301 0x1029, put it there; or a device beating with
//!   its node-ID says so) is a failure *at that heartbeat*, handled as a silence is at its
//!   deadline: a live standby is started first (on the bus within one frame) and becomes active,
//!   the member is reset ([`RoleReason::ActiveNotOperational`], [`LossReason::NotOperational`]);
//!   without a live standby it is reset and the pair has no active member. Until it is heard
//!   operational (a heartbeat in flight when it was started may still say pre-operational) only
//!   operational heartbeats move its deadline, which its start pushed to the start + the consumer
//!   time (+ how far behind the bus the table hears, [`PairSupervisor::heard_behind`]): a
//!   member that never runs after its start fails then — unless the pair has no other member
//!   that can run: heard alive but not running, it is started once more and given one more
//!   consumer time (its start may have reached it late, behind a receive path running past the
//!   consumer time; a reset would leave the pair without a board for a whole boot and
//!   configuration), and fails only if it is still not running then. Not failures: a member the
//!   application sent to pre-operational or stopped through this table's master
//!   ([`PairSupervisor::application_nmt`], [`PairSupervisor::is_held`]) stays active, not
//!   running, until it or this table starts it again (its silence is still judged); a member
//!   booting or being configured is not joined; a standby is pre-operational by design; the table
//!   never sends its own active member to pre-operational or stopped (a planned switch does so
//!   to the member it is leaving). A shadow table follows, as below.
//! - **Non-revertive** by default: a member that rejoins after a failover is standby. With
//!   [`PairsConfig::revertive`], member A takes the role back when it rejoins (a planned
//!   switch: A started, B sent to pre-operational).
//! - **Watchdog.** Monitoring starts at configuration, so a member that is configured and never
//!   speaks is detected like one that stops. A configured pair member that is never heard at all
//!   is reported [`PairsEvent::Missing`] after [`PairsConfig::boot_timeout`] (once per wait; no
//!   NMT command is sent to a node nobody hears).
//! - **Members heard without boot-up** (a reset that never reached the node, e.g. across a
//!   partition, or a supervisor started after its slaves) are *adopted*: after
//!   [`PairsConfig::holdoff`] without a boot-up they are configured and join like any other
//!   member; an operational one joining a pair that has an active member is sent to
//!   pre-operational; a stopped one, which answers no SDO, is reset instead and configured at
//!   its boot-up. The hold-off gives a second master that reappeared with them (a healed
//!   partition) the time to be detected before this one commands anything.
//!
//! # Heartbeats that lie
//!
//! A heartbeat names its node but not its sender: a babbling controller repeating it, a second
//! board configured with the same node-ID, a device beating it on one bus only would keep a
//! dead member "alive". The dual-bus layer judges each member's heartbeats per bus against the
//! producer time it is configured with ([`crate::link::plausible`]) and hands its verdicts here
//! ([`PairSupervisor::suspect`]). A **suspect** member is handled like a silent one at the
//! instant of the verdict: an active member is replaced by a live standby (started first, on the
//! bus within one frame) and reset; a standby is reset; while suspect its heartbeats and
//! boot-ups are no sign of life, it is not adopted, and a configuration that ends meanwhile
//! leaves it waiting, unstarted. The standby is thus started, after the member's last real
//! heartbeat, within the consumer time + 1 ms, or earlier, at the verdict.
//!
//! A member whose heartbeats come too fast on *both* buses (`duplicated`: a second device beats
//! with its node-ID beside it) is not reset: its own board may well run, a reset would reach
//! both devices, and its boot-up would be dropped as the duplicate's twin (the board would then
//! wait unconfigured and unheard; a spare plugged in with a live member's node-ID took that
//! member out of its pair for a second at a time, and the pair lost its last board when the
//! other member failed meanwhile). An active one replaced by a live standby is sent to
//! pre-operational; a standby is left alone. Whenever the pair loses its active member with no
//! other that can run, such a member is started as the last resort, not made active (the pair
//! has no active member in the table: its state cannot be read); whichever member becomes
//! active later sends it back to pre-operational. Once trusted, its heartbeats adopt it again
//! after the hold-off, without a reboot.
//!
//! | What | Verdict (detection bound) |
//! | --- | --- |
//! | A controller babbling the heartbeat on one bus, the member silent on the other | at its 6th frame at the latest (0.4 ms at 1 Mbit/s), or 1.5 producer periods after the member's last heartbeat on the other bus if later |
//! | Two devices with the same node-ID beating at the producer time on both buses | within 8 producer periods of both beating |
//! | A second device with the member's node-ID on one bus, the member alive | none: the member is heard over the other bus; that bus's copies are dropped and reported (`DuplicateNode`) |
//! | An impostor beating on one bus only (any node-ID) | the real node's last heartbeat on the other bus + the reachability window (3 guarding periods by default): consumer time + 1 ms + (window − consumer time), once the other bus was seen idle (a gap longer than the frame time) after the real heartbeat was due there; else at the impostor's first heartbeat after that |
//!
//! A standby heard becoming operational while the active member is alive was started by
//! someone else (a rogue NMT start-all): it is sent back to pre-operational at that heartbeat.
//! The active master takes an NMT command it did not send as a sign of another active master
//! and suspends its own commands for the detection timeout (0x1F90 sub 1, 100 ms by default; see
//! [`crate::supervisor::flying_master`]), so one board runs again, on the bus within one frame,
//! at the later of the command + the detection timeout and the standby's first heartbeat after
//! it. A node announces a state change at once with a heartbeat, so that is the command + the
//! detection timeout when this master heard the command, and the standby's heartbeat right
//! after its start when it did not (a command on a bus segment it cannot hear). A standby the
//! application starts through this master ([`PairSupervisor::application_nmt`]) is left running.
//!
//! # Command and shadow
//!
//! A supervisor in [`Authority::Command`] evaluates and commands. One in [`Authority::Shadow`]
//! (the standby master, or an active one that suspects another active master) only follows:
//! heartbeats and boot-ups keep the table and the deadlines up to date, NMT commands of the
//! active master seen on the bus ([`PairSupervisor::nmt_observed`]) move the roles, and a member
//! joins when the active master is seen to configure it
//! ([`PairSupervisor::configuration_observed`]; or, for a table that cannot see that, at its
//! first heartbeat after its boot-up, [`PairsConfig::shadow_join_on_heartbeat`]). One in
//! [`Authority::Idle`] (no active master known yet, at power-on) records and follows commands but
//! takes nobody's word for a configuration. Switching to command evaluates at once what is due (a
//! takeover acts on the shadow table without resetting anything that is alive) and configures
//! what nobody was seen to configure.
//!
//! # Files
//!
//! | File | What it holds |
//! | --- | --- |
//! | `mod.rs` | [`PairSupervisor`]: the table, adding pairs, authority, manual switch, outputs |
//! | `config.rs` | [`PairsConfig`], the policy of the whole table |
//! | `state.rs` | a pair and its members as the table sees them, each phase with its own data |
//! | `observe.rs` | the observations: boot-ups, heartbeats, commands seen, configurations ended |
//! | `roles.rs` | joining, leaving, and which member is active (commanding or following) |
//! | `deadlines.rs` | the members' deadlines and what happens when one passes |
//! | `trust.rs` | the dual-bus layer's verdicts on heartbeats, standbys started by someone else |
//! | `events.rs` | what the table asks for ([`PairCommand`]) and reports ([`PairsEvent`]) |

use crate::pair::{Member, PairId, PairSpec, MAX_PAIRS};
use core::fmt;
use duocan_core::frame::queue::Fifo;
#[cfg(feature = "alloc")]
use duocan_core::frame::storage::Heap;
use duocan_core::frame::storage::{BoundedVec, Inline, Storage};
use duocan_core::{Duration, Instant, NmtCommand, NmtState, NodeId};

mod config;
mod deadlines;
mod events;
mod observe;
mod roles;
mod state;
mod trust;

pub use config::PairsConfig;
pub use events::{LossReason, PairCommand, PairsError, PairsEvent, RoleChange, RoleReason};
use state::Stage;
pub use state::{Authority, MemberState, PairState, Phase};
use trust::bit;

/// Commands a supervisor can hold before they are drained.
pub const COMMAND_QUEUE: usize = 256;
/// Events a supervisor can hold before they are drained.
pub const EVENT_QUEUE: usize = 256;

const NONE: u8 = 0xFF;

/// The pair table and its evaluation. Its tables live in `S`: inline ([`Inline`], the
/// default: room for [`MAX_PAIRS`] pairs and [`COMMAND_QUEUE`] / [`EVENT_QUEUE`] outputs, no
/// allocator) or on the heap ([`Heap`], `alloc`: the room given
/// to [`with_capacity`](PairSupervisor::with_capacity), allocated once).
pub struct PairSupervisor<S: Storage = Inline> {
    cfg: PairsConfig,
    authority: Authority,
    pairs: S::Vec<PairState, MAX_PAIRS>,
    /// Pairs the table takes (`pairs` never grows beyond it).
    room: usize,
    /// node-ID → pair index · 2 + member index.
    index: [u8; 128],
    /// A lower bound of every member's next deadline (recomputed when reached).
    next: Option<Instant>,
    commands: S::Fifo<PairCommand, COMMAND_QUEUE>,
    events: S::Fifo<PairsEvent, EVENT_QUEUE>,
    /// Node-IDs (bits) whose heartbeats the dual-bus layer finds implausible.
    suspect: u128,
    /// The suspect node-IDs (bits) whose heartbeats a second device shares on both buses.
    duplicated: u128,
    /// Node-IDs (bits) the application started through this table's master.
    by_application: u128,
    /// Node-IDs (bits) the application sent to pre-operational or stopped through this
    /// table's master: not running is what was asked of them.
    held: u128,
    /// Node-IDs (bits) of active members heard operational since they became active: a
    /// heartbeat of theirs saying otherwise is a failure.
    running: u128,
    /// Node-IDs (bits) of active members started a second time, not heard running at their
    /// deadline with no other member that could run (see `deadlines.rs`).
    restarted: u128,
    /// How far behind the bus the observations come (see [`PairSupervisor::heard_behind`]),
    /// and since when that is the largest delay seen.
    behind: (Duration, Instant),
}

impl PairSupervisor {
    /// An empty table, commanding.
    #[must_use]
    pub fn new(cfg: PairsConfig) -> Self {
        Self::build(cfg, MAX_PAIRS, COMMAND_QUEUE, EVENT_QUEUE)
    }
}

#[cfg(feature = "alloc")]
impl PairSupervisor<Heap> {
    /// An empty table, commanding, with room for `pairs` pairs (at most [`MAX_PAIRS`]) and
    /// `queue` commands and as many events between two drains (at least 1), allocated now
    /// and never grown: a master with a few pairs spends what they need.
    #[must_use]
    pub fn with_capacity(cfg: PairsConfig, pairs: usize, queue: usize) -> Self {
        let queue = queue.max(1);
        Self::build(cfg, pairs.min(MAX_PAIRS), queue, queue)
    }
}

impl<S: Storage> PairSupervisor<S> {
    fn build(cfg: PairsConfig, pairs: usize, commands: usize, events: usize) -> Self {
        PairSupervisor {
            cfg,
            authority: Authority::Command,
            pairs: S::vec(pairs),
            room: pairs,
            index: [NONE; 128],
            next: None,
            commands: S::fifo(commands),
            events: S::fifo(events),
            suspect: 0,
            duplicated: 0,
            by_application: 0,
            held: 0,
            running: 0,
            restarted: 0,
            behind: (Duration::ZERO, Instant::ZERO),
        }
    }

    /// The policy.
    pub fn config(&self) -> &PairsConfig {
        &self.cfg
    }
    /// Changes the policy (revertive, hold-off, …) from now on.
    pub fn set_config(&mut self, cfg: PairsConfig) {
        self.cfg = cfg;
    }

    /// Whether [`PairSupervisor::add_pair`] would accept `spec`.
    pub fn check(&self, spec: &PairSpec) -> Result<(), PairsError> {
        if spec.a == spec.b {
            return Err(PairsError::SameNode(spec.a));
        }
        for n in [spec.a, spec.b] {
            if self.index[n.raw() as usize] != NONE {
                return Err(PairsError::NodeTaken(n));
            }
        }
        if self.pairs.len() >= self.room {
            return Err(PairsError::Full);
        }
        Ok(())
    }

    /// Adds a pair; its members are awaited from `now` (boot timeout).
    pub fn add_pair(&mut self, now: Instant, spec: PairSpec) -> Result<PairId, PairsError> {
        self.check(&spec)?;
        let p = self.pairs.len();
        self.pairs
            .try_push(PairState {
                spec,
                active: None,
                members: [
                    MemberState::new(Member::A, spec.a, now),
                    MemberState::new(Member::B, spec.b, now),
                ],
            })
            .map_err(|_| PairsError::Full)?;
        self.index[spec.a.raw() as usize] = (p * 2) as u8;
        self.index[spec.b.raw() as usize] = (p * 2 + 1) as u8;
        self.lower_next(now + self.cfg.boot_timeout);
        Ok(PairId(p as u8))
    }

    /// The pair and member a node belongs to.
    pub fn locate(&self, node: NodeId) -> Option<(PairId, Member)> {
        let i = self.index[node.raw() as usize];
        (i != NONE).then(|| {
            let m = if i.is_multiple_of(2) {
                Member::A
            } else {
                Member::B
            };
            (PairId(i / 2), m)
        })
    }

    /// One pair.
    pub fn pair(&self, p: PairId) -> Option<&PairState> {
        self.pairs.get(p.0 as usize)
    }
    /// The whole table.
    pub fn pairs(&self) -> impl Iterator<Item = (PairId, &PairState)> + '_ {
        self.pairs
            .iter()
            .enumerate()
            .map(|(i, p)| (PairId(i as u8), p))
    }
    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.pairs.len()
    }
    /// Pairs the table has room for.
    pub fn capacity(&self) -> usize {
        self.room
    }
    /// True if no pair is configured.
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Commanding or following.
    pub fn authority(&self) -> Authority {
        self.authority
    }

    /// Switches between commanding and following. Becoming the commander evaluates at once
    /// what is due: silent members, pairs without an active member but with a live one,
    /// configurations the previous commander left unfinished.
    pub fn set_authority(&mut self, now: Instant, a: Authority) {
        if self.authority == a {
            return;
        }
        self.authority = a;
        if a != Authority::Command {
            return;
        }
        for p in 0..self.pairs.len() {
            for m in [Member::A, Member::B] {
                let holdoff = self.cfg.holdoff;
                match &mut self.pairs[p].member_mut(m).stage {
                    Stage::Configuring => self.configure(p, m),
                    // Watched while following: the hold-off starts over from now.
                    Stage::Waiting {
                        adopt_at: Some(at), ..
                    } => *at = now + holdoff,
                    _ => {}
                }
            }
        }
        self.next = Some(now);
        self.handle_timeout(now);
        for p in 0..self.pairs.len() {
            self.ensure_active(now, p, RoleReason::Takeover);
            // Two running members (one started by another master behind a partition): the
            // standby goes back to pre-operational.
            if let Some(a) = self.pairs[p].active {
                let o = self.pairs[p].member(a.other());
                if o.joined() && o.nmt == Some(NmtState::Operational) {
                    let node = o.node;
                    self.nmt(NmtCommand::EnterPreOperational, node);
                }
            }
        }
    }

    // ----- commands -----

    /// Makes `to` the active member of `pair` by hand: it is started, the previous active member
    /// sent to pre-operational.
    pub fn switch_over(
        &mut self,
        now: Instant,
        pair: PairId,
        to: Member,
    ) -> Result<(), PairsError> {
        if self.authority != Authority::Command {
            return Err(PairsError::Shadow);
        }
        let p = pair.0 as usize;
        let state = self.pairs.get(p).ok_or(PairsError::NoPair(pair))?;
        if !self.alive(p, to, now) {
            return Err(PairsError::NotAlive(pair, to));
        }
        if state.active == Some(to) {
            return Ok(());
        }
        self.planned_switch(now, p, to, RoleReason::Manual);
        Ok(())
    }

    // ----- outputs -----

    /// Next command.
    #[must_use]
    pub fn poll_command(&mut self) -> Option<PairCommand> {
        self.commands.pop()
    }
    /// Next event.
    #[must_use]
    pub fn poll_event(&mut self) -> Option<PairsEvent> {
        self.events.pop()
    }
    /// Commands and events dropped because they were not drained.
    pub fn dropped(&self) -> (u32, u32) {
        (self.commands.dropped(), self.events.dropped())
    }

    // ----- internals -----

    fn configure(&mut self, p: usize, m: Member) {
        let spec = self.pairs[p].spec;
        self.cmd(PairCommand::Configure {
            node: spec.node(m),
            producer_time: spec.producer_time,
        });
    }

    fn nmt(&mut self, cmd: NmtCommand, node: NodeId) {
        if self.authority == Authority::Command {
            // This table decides again what it runs.
            self.by_application &= !bit(node);
            self.held &= !bit(node);
            self.cmd(PairCommand::Nmt { cmd, node });
        }
    }

    fn cmd(&mut self, c: PairCommand) {
        self.commands.push(c);
    }

    fn event(&mut self, e: PairsEvent) {
        self.events.push(e);
    }
}

impl<S: Storage> fmt::Debug for PairSupervisor<S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PairSupervisor")
            .field("authority", &self.authority)
            .field("pairs", &self.pairs.len())
            .field("next", &self.next)
            .finish_non_exhaustive()
    }
}
