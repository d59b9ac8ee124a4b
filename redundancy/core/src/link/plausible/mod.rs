//! Heartbeat plausibility per node and per bus: is the device beating with a node's identifier
//! the node it claims to be?
//!
//! A heartbeat carries no sender address. A device that sends another node's heartbeat (a
//! babbling controller, a board configured with a node-ID already taken, a rogue tool) keeps
//! that node "alive" for every consumer, whether or not the node still runs. The dual-bus layer
//! is where this shows: it sees each bus separately. For every *watched* node (the
//! supervisor watches each pair member with the producer time configured into it, through
//! [`LinkCommand::Watch`](crate::LinkCommand::Watch)) it applies two rules.
//!
//! # Rule 1: far faster than the period (per bus)
//!
//! With `T` the node's producer time, its heartbeats (boot-ups included) on one bus are
//! **too fast** at the first heartbeat that ends a span of time `s` holding more than
//! `BURST + 1 + s / (3T/4)` of them, i.e. `5 + 4s/(3T)` with [`BURST`] = 4. A node may thus beat
//! up to a third faster than its producer time for ever (clock tolerance) and add up to four
//! extra heartbeats at once (its boot-up, the heartbeat a node sends at once on a state change
//! or a new producer time). A boot-up starts a new life with an empty bucket (a board a master
//! resets twice within a few periods is no babbler), at most one boot-up per two periods: a
//! babble of boot-ups is flagged like any other. Implemented as a leaky bucket (GCRA): one `u64` per node and bus, in
//! quarter microseconds so that the drain of `3T/4` per heartbeat is exact.
//!
//! - A babbling controller repeating the heartbeat back to back is flagged at its **sixth frame**
//!   at the latest (earlier if the node's own heartbeats had partly filled the bucket): well
//!   under a millisecond at 1 Mbit/s (0.46 ms in the simulator test).
//! - Two devices beating with the same node-ID and period (any phase, any states) fill the bucket
//!   by about two thirds of a heartbeat per period: flagged **within 8 periods** of both beating.
//!
//! While a bus is too fast for a node, that node's error-control frames from that bus are
//! dropped before the merge (counted in [`LinkStats::implausible`](crate::LinkStats)): neither
//! the stack above nor the merger's twin matching sees them, so the node's heartbeats on the
//! other bus, if any, are delivered as they are. The node itself is suspect by this rule only
//! while the other bus does not *speak* for it: that bus is too fast for it as well, or carried
//! none of its heartbeats for 1.5 periods (suspect 1.5 T + 1 µs after its last one there,
//! exactly), as far as its port has shown it: a port whose reader runs behind hands over its
//! bus only up to that far before the present, and what it has not shown yet is no silence
//! (judged silent, a live board duplicated on both buses was suspect by the other bus alone,
//! as behind an impostor, and reset, and the duplicate then beat alone for it). A board alive on both buses whose heartbeat a second device also sends on one bus
//! thus stays in service, heard over its clean bus (taking it out of service would leave its
//! pair without a board to run should the other member die); a babble on one bus after the
//! board died makes it suspect 1.5 periods after its last heartbeat on the other bus, before
//! its consumer time runs out. A bus's verdict ends when the bucket has drained:
//! at the latest `(BURST + 2) · 3T/4` after the last excess frame while nothing else arrives.
//! While the node beats on alone at its pace (the other device gone), each of its heartbeats
//! drains only a quarter period, and the drain would take 18 periods, all of them dropped: so
//! the verdict also ends, the bucket emptied, at the heartbeat that makes [`CALM_BEATS`] in a
//! row (by the frames' stamps) each at least `3T/4` after the one before, or at a boot-up
//! after one such heartbeat (a master reset the node). Two devices beating with one node-ID at
//! one period put a gap of at most `T/2` in every period; a heartbeat saying a new state (a
//! boot-up among them) counts neither way otherwise, since a node announces a change at once
//! and a master's reset or stop must not keep the verdict, while two devices saying different
//! states change it at every heartbeat and never count one. With the other device still there,
//! the verdict holds.
//! One period after the verdict the rate measured over `[verdict, verdict + T)` is reported:
//! [`Babbling`](crate::LinkEventKind::Babbling) (identifier, bus, frames/s) when it is more
//! than [`BABBLE_FACTOR`] times the producer rate, [`DuplicateNode`][dup] otherwise (devices
//! sharing the node-ID).
//!
//! [dup]: crate::LinkEventKind::DuplicateNode
//!
//! # Rule 2: on one bus only
//!
//! A watched node heard for the reachability timeout `W`
//! ([`DualBusConfig::reach_timeout`](crate::DualBusConfig)) on one bus only is suspect at the
//! instant the other bus has been silent for it for `W` (exactly): since its last heartbeat
//! there or, if that bus has not carried it in this *life* (since its last boot-up, or since it
//! was heard nowhere for `W`), since the life began. Every pair member has a port on each bus,
//! so a node that appears on one bus only is judged too: a master that starts while an
//! impostor beats a dead member's heartbeat on one bus has nothing else to go by. A life that
//! began with a boot-up is judged once the node was heard on both buses in it: a board cut off
//! one bus (suspect, and reset) is not reset again at every boot; and where members may be on
//! one bus by design,
//! [`DualBusConfig::one_bus_members`](crate::DualBusConfig::one_bus_members), every life is
//! judged so. The verdict needs the silent bus
//! *healthy for it*: the port is ok and, after the node's heartbeat was due there (one and a
//! half periods after the silence began, or after the port last came back to ok from a failure
//! or a transmit error if later: a heartbeat sent while the bus was cut is lost, so a flapping
//! bus is no evidence), the bus was
//! **seen idle**, or carried the heartbeat of another watched node of **lower priority** (a
//! higher identifier). Neither a cut nor a babbler can then be what keeps the node's heartbeat
//! off that bus: a cut stops every frame; CAN arbitration lets a frame wait only while the bus
//! is busy (a heartbeat queued when the bus goes idle is sent at once), and a babbler blocks
//! only identifiers of lower priority than its own. The bus is seen idle when two consecutive
//! frames on it (received, or this layer's own, `idle.rs`) are more than the frame time `F`
//! apart ([`DualBusConfig::frame_time`](crate::DualBusConfig::frame_time): the longest frame at
//! the bit rate plus the jitter of the times the layer is given, 2 ms by default): idle at
//! `t − F` at the latest, `t` being the later frame's time. That witness depends on no other
//! node: the highest node-ID of the network, which no heartbeat of lower priority can witness
//! for, is judged like every other. Without a witness at the deadline the rule is checked again
//! at each of the node's heartbeats (so within one period of a witness). The
//! deadline is armed by the node's first heartbeat on the other bus that finds the silent bus
//! late (more than 1.5 periods without it), so a node heard on both buses costs no timer; the
//! instant is exact when that heartbeat comes before the deadline, i.e. when `W` exceeds about
//! 2.5 periods (the default, 3 guarding periods, does when the guarding period is the heartbeat
//! period), and otherwise it is that heartbeat. The node is trusted again when it is heard on
//! the other bus, when it boots (boot-up frame), or when it is heard nowhere for `W` (its silence
//! is then for the consumers to judge). The rule applies in the modes that listen on both buses
//! (active-active, CiA 302-6), not in ECSS toggling. A board cut off one bus by a split of that
//! bus (a partition between it and this master) is, seen from here, what an impostor on the
//! other bus would be: it is suspect too.
//!
//! # Verdicts
//!
//! A node is *suspect* while either rule holds. The change is handed to the machine above as
//! [`LinkRequest::NodeSuspect`][req] (the supervisor takes the member's heartbeats as no sign of
//! life and handles an active member like a silent one) and reported as
//! [`Suspect`](crate::LinkEventKind::Suspect) (with the reason, at each rule's onset) and
//! [`Trusted`](crate::LinkEventKind::Trusted). Should the machine queue be full, the change is
//! handed up at the next input (a station drains the queue after every input).
//!
//! [req]: duocan_core::machine::LinkRequest::NodeSuspect
//!
//! # Order
//!
//! A bus that hands its frames over later than the other (a reader running behind, a lag on
//! the wire) can deliver a node's heartbeat after a newer one that came over the other bus:
//! the merge delivers each exactly once, but the late one reports a state the node has left
//! (pre-operational after its start, say), and the master above would take it for a board that
//! stopped by itself, reset it, and do so again at every heartbeat while the lag lasts. So a
//! watched node's heartbeat that the merge delivered is handed up only if it is not older, by
//! more than the merge's skew window, than one of that node's heartbeats or boot-ups already
//! handed up (stamps as the merge judged them: receive times, corrected by the measured lag).
//! Otherwise it is superseded: counted ([`LinkStats::superseded`](crate::LinkStats)) and
//! dropped. A boot-up is never superseded (the node lost its state then, whatever came after),
//! and the margin keeps the heartbeat a node sends right after another (at a state change)
//! whichever bus brought it first.
//!
//! # Memory
//!
//! A few words per bus for the idle witness, and one entry per watched node, indexed by
//! node-ID, room for as many as the layer was
//! configured for ([`DualBusConfig::watch_capacity`](crate::DualBusConfig::watch_capacity);
//! by default every node-ID, [`MAX_MEMBERS`]: about 13 KiB on a 32-bit target), allocated once
//! at the first watch and never grown, so that a layer that watches nothing (a node's) carries
//! only a pointer. Nothing per frame. Without the `alloc` feature
//! there is no table and watches are refused (counted; the supervisor, the only one to watch,
//! needs `alloc` anyway).

use crate::pair::MAX_MEMBERS;
use duocan_core::frame::storage::BoundedVec;
use duocan_core::{Duration, Instant, NodeId};

/// Extra heartbeats a node may send in one burst on one bus (see rule 1).
pub const BURST: u64 = 4;
/// The frame time of rule 2's idle witness by default: the longest classic frame with its
/// intermission (160 bit times) at 125 kbit/s, 1.28 ms, and 0.72 ms of jitter in the times the
/// layer is given.
pub const DEFAULT_FRAME_TIME: Duration = Duration::from_millis(2);
/// A rate measured above this many times the producer rate is a babbling identifier; up to it,
/// devices sharing a node-ID.
pub const BABBLE_FACTOR: u64 = 4;
/// Heartbeats in a row at the node's pace (each at least `3T/4` after the one before) that
/// end a bus's verdict (see rule 1).
pub const CALM_BEATS: u8 = 3;
pub(super) const NEVER: u64 = u64::MAX;

/// The watched nodes: an index by node-ID and the entries, of fixed capacity.
#[derive(Clone, Debug)]
struct Table {
    /// node-ID → position in `watched` (`NONE`: not watched).
    index: [u8; 128],
    watched: Watched,
    /// Per bus: the ends of own frames the received frames have not passed yet (`idle.rs`).
    ends: [idle::Ends; 2],
}

/// The entries: allocated for the capacity asked for (`alloc`); without an allocator the
/// table never exists.
#[cfg(feature = "alloc")]
type Watched = alloc::vec::Vec<Watch>;
#[cfg(not(feature = "alloc"))]
type Watched = heapless::Vec<Watch, 0>;

pub(super) const NONE: u8 = u8::MAX;

/// Without an allocator there is no table (nothing is watched): the entry points return at
/// once, and a build without `alloc` (a node's firmware) carries none of the rules' code.
pub(super) const ON: bool = cfg!(feature = "alloc");

// The table is allocated once, at the first watch: a layer that watches nothing (a node's)
// carries only the pointer. Without an allocator there is no table and watches are refused.
#[cfg(feature = "alloc")]
type Holder = alloc::boxed::Box<Table>;
#[cfg(feature = "alloc")]
fn allocate(capacity: usize) -> Option<Holder> {
    Some(alloc::boxed::Box::new(Table {
        index: [NONE; 128],
        watched: alloc::vec::Vec::with_capacity(capacity),
        ends: [idle::Ends::new(), idle::Ends::new()],
    }))
}
#[cfg(not(feature = "alloc"))]
#[derive(Clone, Debug)]
enum Holder {}
#[cfg(not(feature = "alloc"))]
fn allocate(_: usize) -> Option<Holder> {
    None
}
#[cfg(not(feature = "alloc"))]
impl core::ops::Deref for Holder {
    type Target = Table;
    fn deref(&self) -> &Table {
        match *self {}
    }
}
#[cfg(not(feature = "alloc"))]
impl core::ops::DerefMut for Holder {
    fn deref_mut(&mut self) -> &mut Table {
        match *self {}
    }
}

/// The plausibility table of a dual-bus layer (see the [module docs](self)).
#[derive(Clone, Debug)]
pub struct Plausibility {
    /// Rule 2's window `W` (µs); `None`: rule 2 off.
    window: Option<u64>,
    table: Option<Holder>,
    /// Last watched heartbeat on each bus (µs): what rule 2's witnesses can have changed.
    last_any: [u64; 2],
    /// Each bus as a whole: when it was last known idle (rule 2's idle witness, `idle.rs`).
    buses: [idle::Bus; 2],
    /// The frame time `F` (µs): a gap between frames longer than this is idle bus; 0: the
    /// idle witness is off.
    frame_time: u64,
    /// A lower bound of the next deadline.
    next: Option<u64>,
    /// A change could not be handed up (the machine queue was full): retried at the next input.
    unsynced: bool,
    refused: u32,
    /// Nodes the table takes.
    capacity: usize,
    /// Watched nodes may be wired to one bus only: rule 2 waits until a node is heard on both.
    one_bus_members: bool,
}

impl Plausibility {
    /// An empty table for every node-ID; rule 2 with window `one_bus` (`None`: off).
    #[must_use]
    pub fn new(one_bus: Option<Duration>) -> Self {
        Plausibility::with_capacity(one_bus, MAX_MEMBERS)
    }

    /// An empty table for `nodes` watched nodes at most ([`MAX_MEMBERS`] at most), allocated
    /// at the first watch; rule 2 with window `one_bus` (`None`: off).
    #[must_use]
    pub fn with_capacity(one_bus: Option<Duration>, nodes: usize) -> Self {
        Plausibility {
            window: one_bus.filter(|w| !w.is_zero()).map(Duration::as_micros),
            table: None,
            last_any: [NEVER; 2],
            buses: [idle::Bus::NEW; 2],
            frame_time: DEFAULT_FRAME_TIME.as_micros(),
            next: None,
            unsynced: false,
            refused: 0,
            capacity: nodes.min(MAX_MEMBERS),
            one_bus_members: false,
        }
    }

    /// The table with watched nodes allowed on one bus only (`true`: rule 2 judges a node once
    /// it was heard on both buses in its life; see
    /// [`DualBusConfig::one_bus_members`](crate::DualBusConfig::one_bus_members)).
    #[must_use]
    pub fn with_one_bus_members(mut self, allowed: bool) -> Self {
        self.one_bus_members = allowed;
        self
    }

    /// The table with rule 2's idle witness judging gaps by the frame time `f` (see
    /// [`DualBusConfig::frame_time`](crate::DualBusConfig::frame_time); zero: no idle witness).
    #[must_use]
    pub fn with_frame_time(mut self, f: Duration) -> Self {
        self.frame_time = f.as_micros().min(1 << 40);
        self
    }

    /// Watches `node`, whose producer time is `period` (zero: stops watching it). False if the
    /// table is full (the capacity it was built with) or there is no allocator (counted in
    /// [`Plausibility::refused`]).
    // Configuration, not the frame path: kept out of the callers so that they stay small.
    #[inline(never)]
    pub fn watch(&mut self, node: NodeId, period: Duration) -> bool {
        let n = node.raw() as usize;
        if period.is_zero() {
            if let Some(t) = self.table.as_deref_mut() {
                if t.index[n] != NONE {
                    t.watched.swap_remove(t.index[n] as usize);
                    t.index = [NONE; 128];
                    for (i, w) in t.watched.iter().enumerate() {
                        t.index[w.node.raw() as usize] = i as u8;
                    }
                }
            }
            return true;
        }
        if self.table.is_none() {
            self.table = allocate(self.capacity);
        }
        let Some(t) = self.table.as_deref_mut() else {
            self.refused = self.refused.saturating_add(1);
            return false;
        };
        // Longer than 12 days is taken as 12 days: every sum on the frame path stays far from
        // overflowing (a producer time is at most 65.535 s).
        let period = period.as_micros().min(1 << 40);
        let drain = period.saturating_mul(3);
        let (limit, late) = (drain.saturating_mul(BURST + 1), period + period / 2);
        if t.index[n] != NONE {
            let w = &mut t.watched[t.index[n] as usize];
            (w.period, w.drain, w.limit, w.late) = (period, drain, limit, late);
            return true;
        }
        let w = Watch {
            node,
            period,
            drain,
            limit,
            late,
            key: None,
            id: None,
            ports: [Track::NEW; 2],
            life: NEVER,
            booted: false,
            one_bus: None,
            told: false,
            fast_verdict: false,
            newest: NEVER,
            checked: NEVER,
            quiet: false,
            #[cfg(feature = "alloc")]
            producer: None,
            reset: 0,
        };
        if t.watched.len() >= self.capacity || t.watched.try_push(w).is_err() {
            self.refused = self.refused.saturating_add(1);
            return false;
        }
        t.index[n] = (t.watched.len() - 1) as u8;
        true
    }

    /// True if no node is watched (the frame path then skips the table).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.table.is_none()
    }
    /// A heartbeat or boot-up (`boot`) of `node` that the merge delivered, stamped `at`:
    /// false if it is superseded, older than one already handed up by more than `margin` (see
    /// "Order"). Nodes not watched are never superseded.
    #[inline]
    pub(crate) fn current(
        &mut self,
        node: NodeId,
        at: Instant,
        boot: bool,
        margin: Duration,
    ) -> bool {
        let Some(i) = self.find(node).filter(|_| ON) else {
            return true;
        };
        let w = self.at(i);
        let t = at.as_micros();
        if w.newest == NEVER {
            w.newest = t;
            return true;
        }
        if !boot && t.saturating_add(margin.as_micros()) < w.newest {
            return false;
        }
        w.newest = w.newest.max(t);
        true
    }

    /// Whether `node` is suspect now (`None`: not watched).
    pub fn is_suspect(&self, node: NodeId) -> Option<bool> {
        self.entry(node).map(Watch::suspect)
    }
    /// The bus `node` is heard on only, if rule 2 holds for it.
    pub fn one_bus(&self, node: NodeId) -> Option<u8> {
        self.entry(node).and_then(|w| w.one_bus)
    }
    /// Whether `node`'s heartbeats on port `p` are too fast (rule 1) now.
    pub fn too_fast(&self, node: NodeId, p: usize) -> bool {
        self.entry(node).is_some_and(|w| w.ports[p.min(1)].fast())
    }
    /// Watches refused because the table was full (or there is no allocator).
    pub fn refused(&self) -> u32 {
        self.refused
    }
    /// Every watched node with whether it is suspect.
    pub fn iter(&self) -> impl Iterator<Item = (NodeId, bool)> + '_ {
        self.entries().iter().map(|w| (w.node, w.suspect()))
    }

    fn entries(&self) -> &[Watch] {
        self.table.as_deref().map_or(&[], |t| &t.watched[..])
    }
    fn entry(&self, node: NodeId) -> Option<&Watch> {
        self.find(node).map(|i| &self.entries()[i])
    }
    /// A frame received or sent by this station that may change how a watched node beats:
    /// an NMT reset (`reset.rs`), a download to its producer time (`producer.rs`).
    #[cfg(feature = "alloc")]
    #[inline]
    pub(crate) fn on_command(&mut self, frame: &duocan_core::Frame) {
        self.on_nmt(frame);
        self.on_sdo(frame);
    }
    #[inline]
    fn find(&self, node: NodeId) -> Option<usize> {
        let t = self.table.as_deref()?;
        let i = t.index[node.raw() as usize];
        (i != NONE).then_some(i as usize)
    }
    /// Entry `i` (an index `find` returned).
    fn at(&mut self, i: usize) -> &mut Watch {
        match self.table.as_deref_mut() {
            Some(t) => &mut t.watched[i],
            None => unreachable!("an index exists only with a table"),
        }
    }

    fn wake(&mut self, t: u64) {
        self.next = Some(self.next.map_or(t, |n| n.min(t)));
    }

    /// Earliest deadline (may be early: a sweep then finds nothing to do).
    #[must_use]
    #[inline]
    pub fn poll_timeout(&self) -> Option<Instant> {
        self.next
            .filter(|_| ON)
            .filter(|t| *t != NEVER)
            .map(Instant::from_micros)
    }

    /// The caller's clock stepped back `by` (the clock contract, see [`crate::link`]): every
    /// time held moves back with it, the buckets too, so that a step back is no burst of
    /// heartbeats.
    #[cold]
    pub(crate) fn step_back(&mut self, by: Duration) {
        if !ON {
            return;
        }
        let by = by.as_micros();
        let back = |t: &mut u64| {
            if *t != NEVER {
                *t = t.saturating_sub(by);
            }
        };
        for v in self.last_any.iter_mut() {
            back(v);
        }
        let mut ends = self.table.as_deref_mut().map(|t| &mut t.ends);
        for (p, b) in self.buses.iter_mut().enumerate() {
            b.step_back(by, ends.as_deref_mut().map(|e| &mut e[p]));
        }
        if let Some(n) = self.next.as_mut() {
            back(n);
        }
        if let Some(t) = self.table.as_deref_mut() {
            for w in t.watched.iter_mut() {
                back(&mut w.checked);
                back(&mut w.newest);
                back(&mut w.life);
                for tr in w.ports.iter_mut() {
                    back(&mut tr.last);
                    back(&mut tr.since);
                    back(&mut tr.prev);
                    tr.tat = tr.tat.saturating_sub(by.saturating_mul(4));
                    tr.boots = tr.boots.saturating_sub(by.saturating_mul(4));
                }
            }
        }
    }
}

mod idle;
// Without an allocator nothing is watched (see `ON`): no producer time to follow.
#[cfg(feature = "alloc")]
mod producer;
#[cfg(feature = "alloc")]
mod reset;
mod rules;
mod watch;
use watch::{Track, Watch};
#[cfg(test)]
mod tests;
