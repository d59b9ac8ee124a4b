//! The oracle: every frame occurrence exactly once at every device it could reach.
//!
//! Every logical frame a tapped device's stack sends is an *occurrence*, numbered; every copy
//! of it that its link hands to a port is known (see [`crate::tap`]), and so is every copy the
//! simulator hands to a receiver (its receive hook) and whether the receiver's link delivered
//! it. An occurrence is judged at each other tapped device once it is old enough:
//!
//! - a copy of it reached the device: it was delivered exactly once (none: lost; more:
//!   duplicated);
//! - none did: if a bus connected the two devices when it was sent (the campaign's timeline
//!   says so, with a margin around every change of the wiring), it is lost: the sender did
//!   not put it where it would have arrived.
//!
//! Occurrences of the same frame from the same sender sent within the skew window of each
//! other cannot be told apart by any receiver: when one bus missed the first (its sender's port
//! on it not back yet), a receiver pairs the second's copy on that bus with the first's on the
//! other, and delivers the second's other copy (the count stays right; the merger's rule says
//! so). Such a run (each within the window of the one before) is judged by its count: as many
//! deliveries as occurrences are one each, however they fell. When the wiring changed around
//! it (a bus cut as the other is repaired), one occurrence may have gone on one bus only and
//! the next on the other only: to every receiver that is one frame on both, and one of them
//! dropped as the other's twin is not judged.
//!
//! Identical frames of two senders (two masters active for a moment, their SYNCs; one of them
//! held behind a babble and sent when it ended), reaching a receiver within the skew window of
//! each other, the one on one bus only, are one frame on both buses to it (a CAN frame names
//! no sender): when the other was delivered there, this one dropped is right and not judged.
//! They are matched by when they reached the receiver, not when they were sent: a frame that
//! waited behind a babble goes out long after. The other way round is the same count: the
//! one on both buses delivered twice, the other's single copy taken for its twin (seed 769:
//! a master whose port to bus 1 sent late, so its SYNC went on bus 2 only, next to the other
//! master's).
//!
//! A frame whose two copies reached a receiver within the skew window of each other but on
//! either side of a jump ahead of the receiver's clock may be delivered twice: their stamps
//! are the jump apart (in a run of identical frames, one delivery more for each); and one on
//! the wire before the jump whose only copy was handed over after it (a port running behind)
//! may be dropped: it is as old as the jump to the layer (the promise table states both).
//!
//! A heartbeat that reached a receiver only after a newer heartbeat or boot-up of the same
//! sender had been delivered there (over a bus lagging behind the other) may be dropped: it
//! reports a state the node has left, and a master's layer drops such heartbeats of the nodes
//! it watches (superseded). Newer by more than the skew window, as sent or on the wire: a
//! board reset 4.4 ms after a heartbeat put its boot-up on the wire 5.2 ms after it (quiet
//! seed 132).
//!
//! Frames that are not the promise's (an impostor's, a babbler's, a pair's process data at a
//! master, which delivers only the active member's by design) are left out, each for a reason
//! the campaign states when it adds the device or the fault.

use crate::plant::{DeviceClock, SLAVE_HB};
use duocan::sim::StampClock;
use duocan::{Frame, Id, Instant};
use duocan_redundancy::link::plausible::CALM_BEATS;
use std::collections::VecDeque;

/// Most tapped devices.
pub const MAX_NODES: usize = 24;

/// How long after it was sent an occurrence is judged: every copy has arrived by then (the
/// largest receive latency of the campaign plus the wire, with room).
pub const JUDGE_AFTER: duocan::Duration = duocan::Duration::from_millis(400);

/// The layers' skew window: identical frames of one sender sent closer than this are one
/// count (see the module documentation).
pub const SKEW_WINDOW: duocan::Duration = duocan::Duration::from_millis(5);

/// How long a layer's merger remembers a delivered frame for its twin (its late-record
/// horizon).
const HORIZON: duocan::Duration = duocan::Duration::from_millis(80);

#[derive(Clone, Copy, Debug)]
struct Occurrence {
    sender: usize,
    at: Instant,
    frame: Frame,
    reached: [u8; MAX_NODES],
    delivered: [u8; MAX_NODES],
    /// One of a run of identical frames of its sender, each within the skew window of the
    /// one before.
    in_run: bool,
    /// A heartbeat whose first copy reached the receiver after a newer one of its sender was
    /// delivered there (see the module documentation).
    superseded: [bool; MAX_NODES],
    /// Delivered at the receiver while its receive clocks disagreed beyond what its layer had
    /// measured (see [`Oracle::unmeasured`]).
    unmeasured: [bool; MAX_NODES],
    /// When its first and its latest copy reached each receiver (simulated time).
    arrived: [Option<Instant>; MAX_NODES],
    last_arrived: [Option<Instant>; MAX_NODES],
    /// Per bus: when its copy there ended on the wire (as a receiver saw it).
    wire: [Option<Instant>; 2],
    /// Copies a bridge between the buses made of it that reached each receiver (see
    /// [`Oracle::arriving`]), and when the latest of them ended on the wire.
    bridged: [u8; MAX_NODES],
    bridged_wire: [Option<Instant>; MAX_NODES],
}

impl Occurrence {
    /// When its two copies ended on the wire, the earlier first (`None` unless both did).
    fn on_wire(&self) -> Option<(Instant, Instant)> {
        match self.wire {
            [Some(a), Some(b)] => Some((a.min(b), a.max(b))),
            _ => None,
        }
    }
}

/// Two instants closer than the skew window.
fn within_window(a: Instant, b: Instant) -> bool {
    a.as_micros().abs_diff(b.as_micros()) < SKEW_WINDOW.as_micros()
}

/// Whether a receiver's record (`list`: time, sender, frame) holds `o`'s frame from another
/// sender at a time `near` accepts.
fn other_sender(
    list: Option<&VecDeque<(Instant, usize, Frame)>>,
    o: &Occurrence,
    near: impl Fn(Instant) -> bool,
) -> bool {
    list.into_iter()
        .flatten()
        .any(|(t, s, f)| *s != o.sender && *f == o.frame && near(*t))
}

/// A heartbeat (not a boot-up): what may be superseded.
fn is_heartbeat(f: &Frame) -> bool {
    matches!(f.id(), Id::Standard(0x701..=0x77F)) && f.data().len() == 1 && f.data()[0] != 0
}

/// A heartbeat or a boot-up.
fn is_error_control(f: &Frame) -> bool {
    matches!(f.id(), Id::Standard(0x701..=0x77F)) && f.data().len() == 1
}

/// What went wrong with an occurrence at a receiver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// A copy reached it and none was delivered.
    Dropped,
    /// No copy reached it although a bus connected the two.
    NeverArrived,
    /// Delivered more than once.
    Duplicated(u8),
    /// A heartbeat delivered at a master after a newer heartbeat or boot-up of its sender
    /// (sent more than the skew window later) had been: a state the node has left, taken
    /// for its present one.
    Stale,
}

/// One violation, for the report.
#[derive(Clone, Copy, Debug)]
pub struct Violation {
    pub sender: usize,
    pub receiver: usize,
    pub at: Instant,
    pub frame: Frame,
    pub fault: Fault,
}

/// A tapped device as the oracle knows it.
#[derive(Clone, Debug, Default)]
pub struct NodeInfo {
    pub name: String,
    /// Its simulator device index.
    pub device: usize,
    /// Occurrence of each copy it handed over, by the simulator's serial (`None`: the link's
    /// own frame).
    copies: Vec<Option<u64>>,
    /// A master (the pair members' process data it receives are not judged).
    pub master: bool,
    /// Not duocan ([`crate::foreign`]): what it receives is not judged, and its copies of a
    /// frame may leave further apart than the skew window (see [`Oracle::judge`]).
    pub foreign: bool,
    /// Cabled crossed: its port 0 on bus 2, its port 1 on bus 1.
    pub swapped: bool,
}

/// Whether two devices were connected by a bus, around an instant: what the fault timeline
/// answers.
pub trait Wiring {
    /// `Some(true)`: a bus connected them all through `[t − margin, t + margin]`; `Some(false)`:
    /// none did at any time of it; `None`: the wiring changed meanwhile (not judged).
    fn connected(&self, sender: usize, receiver: usize, t: Instant) -> Option<bool>;
    /// Whether `sender`'s occurrence `frame` at `t` is left out of the promise (an impostor's
    /// target, a receiver rebooting meanwhile, …); `calm(node, end)`: when the node's own
    /// heartbeats after `end` ended a plausibility verdict ([`Beats::calm_after`]).
    fn excluded(
        &self,
        sender: usize,
        receiver: usize,
        t: Instant,
        frame: &Frame,
        calm: &dyn Fn(u8, Instant) -> Instant,
    ) -> bool;
    /// Whether `receiver`'s clock jumped ahead in `(from, to]`.
    fn jumped(&self, receiver: usize, from: Instant, to: Instant) -> bool;
}

/// Every heartbeat each node sent: (time, state byte), by node-ID.
#[derive(Default)]
pub struct Beats(std::collections::BTreeMap<u8, Vec<(Instant, u8)>>);

impl Beats {
    /// When node `node`'s heartbeats after `end` ended a verdict of the layer's rule 1 (see
    /// `link::plausible`): [`CALM_BEATS`] in a row each at least `3T/4` after the heartbeat
    /// before and saying the state of the one before (a heartbeat saying a new state, or a
    /// boot-up, counts neither way; a boot-up after one such heartbeat ends it too). Sent times
    /// stand for the receive stamps. `Instant::MAX`: not yet.
    pub fn calm_after(&self, node: u8, end: Instant) -> Instant {
        let Some(beats) = self.0.get(&node) else {
            return Instant::MAX;
        };
        let start = beats.partition_point(|b| b.0 < end);
        let pace = SLAVE_HB.as_micros() * 3 / 4;
        let (mut prev, mut state, mut calm) = (None::<Instant>, None, 0);
        for &(t, st) in &beats[start..] {
            let gap = prev.map_or(u64::MAX, |p| (t - p).as_micros());
            prev = Some(t);
            if st == 0 && calm > 0 {
                return t;
            }
            if st == 0 || Some(st) != state.replace(st) {
                continue;
            }
            if gap < pace {
                calm = 0;
            } else {
                calm += 1;
                if calm >= CALM_BEATS {
                    return t;
                }
            }
        }
        Instant::MAX
    }
}

#[derive(Default)]
pub struct Oracle {
    /// Every heartbeat each node sent.
    pub beats: Beats,
    pub nodes: Vec<NodeInfo>,
    /// Occurrences not judged yet, numbered from `base`.
    pending: VecDeque<Occurrence>,
    base: u64,
    /// The copy being handed to a device now: (receiver node, occurrence).
    current: Option<(usize, Option<u64>)>,
    pub violations: Vec<Violation>,
    /// Occurrences judged, and (occurrence, receiver) judgements made.
    pub judged: u64,
    pub checks: u64,
    /// Deliveries of frames the oracle does not know (a babbler's, an impostor's).
    pub foreign: u64,
    /// Pair members' node-IDs (their process data at masters is not judged).
    pub members: Vec<u8>,
    /// The node whose SYNCs are followed ([`Oracle::syncs`]).
    pub sync_node: Option<usize>,
    /// When each SYNC that node's link delivered was sent, not yet taken by the run.
    pub syncs: std::collections::BTreeSet<Instant>,
    /// Per node: how far its clock reads ahead of the simulated time (µs; the campaign steps
    /// and jumps masters' clocks), to put its occurrences on the simulated time line.
    pub clock: [DeviceClock; MAX_NODES],
    /// Per node: each span in which its producer time differed from the one its masters are
    /// configured with (from a download the application made at run time until its next
    /// boot-up; `Instant::MAX` while it has not booted).
    pub producer_changed: [Vec<(Instant, Instant)>; MAX_NODES],
    /// Per node: when it was last rebuilt (a master's or a board's power cycle).
    pub rebuilt: [Option<Instant>; MAX_NODES],
    /// Per receiver and sender: when the newest heartbeat or boot-up delivered there was sent,
    /// and when its copy delivered there ended on the wire.
    newest: Vec<[Option<(Instant, Instant)>; MAX_NODES]>,
    /// When the copy being handed over now ended on the wire.
    current_wire: Instant,
    /// A bridge's copies that reached a receiver: when each ended on the wire, the sender of
    /// the frame it copied, the receiver, the frame (see [`Oracle::beside_echo`]).
    echoes: VecDeque<(Instant, usize, usize, Frame)>,
    /// Per receiver and sender: when the newest heartbeat or boot-up delivered there was sent,
    /// and the state it said (a boot-up: 0).
    state: Vec<[Option<(Instant, u8)>; MAX_NODES]>,
    /// Per receiver: the frames delivered there lately (simulated time, sender, frame), for as
    /// long as an occurrence that reached it meanwhile may wait to be judged.
    recent: Vec<VecDeque<(Instant, usize, Frame)>>,
    /// The same for the copies handed over there and not delivered.
    passed: Vec<VecDeque<(Instant, usize, Frame)>>,
    /// Per node and port: the latest time (its clock) a frame was handed over late there.
    pub late: [[Option<Instant>; 2]; MAX_NODES],
    /// Per node and port: its receive clock, as the simulator last set it.
    pub stamps: [[StampClock; 2]; MAX_NODES],
    /// Until when a foreign sender's frames may be matched with a copy of its that left
    /// further apart than the window (see [`Oracle::apart`]).
    apart_until: Option<Instant>,
    /// A foreign sender's copies that reached the wire after their occurrence was judged
    /// (held in its transmit queue longer than [`JUDGE_AFTER`]): when they ended on the wire,
    /// and the frame (see [`Oracle::beside_stale`]).
    stale: VecDeque<(Instant, Frame)>,
}

impl Oracle {
    /// Adds a tapped device: its node index.
    pub fn add(&mut self, name: &str, device: usize, master: bool) -> usize {
        assert!(self.nodes.len() < MAX_NODES);
        self.nodes.push(NodeInfo {
            name: name.into(),
            device,
            copies: vec![],
            master,
            foreign: false,
            swapped: false,
        });
        self.nodes.len() - 1
    }

    /// Adds a device that is not duocan (see [`NodeInfo::foreign`]): its node index.
    pub fn add_foreign(&mut self, name: &str, device: usize) -> usize {
        let n = self.add(name, device, false);
        self.nodes[n].foreign = true;
        n
    }

    /// Node `node` was rebuilt: its new link's copies continue after the simulator's serial
    /// `taken`.
    pub fn rebuilt(&mut self, node: usize, taken: u64) {
        self.nodes[node].copies.resize(taken as usize, None);
    }

    /// Node `node`'s stack sent `frame` at `now`: a new occurrence.
    pub fn sent(&mut self, node: usize, now: Instant, frame: &Frame) -> u64 {
        let at = self.clock[node].back(now);
        if let (Id::Standard(id @ 0x701..=0x77F), [state]) = (frame.id(), frame.data()) {
            let v = self.beats.0.entry((id & 0x7F) as u8).or_default();
            v.push((at, *state));
            if *state == 0 {
                // Booted: its dictionary's producer time, which its master configures again.
                if let Some((_, until)) = self.producer_changed[node].last_mut() {
                    *until = (*until).min(at);
                }
            }
        }
        self.pending.push_back(Occurrence {
            sender: node,
            at,
            frame: *frame,
            reached: [0; MAX_NODES],
            delivered: [0; MAX_NODES],
            in_run: false,
            superseded: [false; MAX_NODES],
            unmeasured: [false; MAX_NODES],
            arrived: [None; MAX_NODES],
            last_arrived: [None; MAX_NODES],
            wire: [None; 2],
            bridged: [0; MAX_NODES],
            bridged_wire: [None; MAX_NODES],
        });
        self.base + self.pending.len() as u64 - 1
    }

    /// Node `node`'s link handed a copy of occurrence `of` (or a frame of its own) to a port.
    pub fn copy(&mut self, node: usize, of: Option<u64>, _port: usize) {
        self.nodes[node].copies.push(of);
    }

    /// The simulator hands device `receiver`'s port `port` (on bus `port`, the other one if it
    /// is cabled crossed) the copy `serial`
    /// of device `sender`, which ended on the wire at `wire`; `bridged`: the copy is a bridge's
    /// of that one (see [`duocan::sim::RxNote::bridged`]).
    #[allow(clippy::too_many_arguments)]
    pub fn arriving(
        &mut self,
        receiver: usize,
        sender: usize,
        serial: Option<u64>,
        port: usize,
        wire: Instant,
        frame: &Frame,
        bridged: bool,
    ) {
        let node = |d: usize| self.nodes.iter().position(|n| n.device == d);
        let (Some(r), Some(s)) = (node(receiver), node(sender)) else {
            self.current = None;
            return;
        };
        let of = serial.and_then(|k| self.nodes[s].copies.get(k as usize).copied().flatten());
        let newest = self.newest.get(r).and_then(|n| n[s]);
        let bus = (port & 1) ^ usize::from(self.nodes[r].swapped);
        if self.nodes[s].foreign && of.is_some_and(|o| o < self.base) {
            self.stale.push_back((wire, *frame));
        }
        if let Some(o) = of.and_then(|o| self.occ(o)) {
            if o.reached[r] == 0
                && is_heartbeat(&o.frame)
                && newest.is_some_and(|(sent, on_wire)| {
                    // Older by more than the window, as sent or as on the wire (the layer
                    // judges by receive timestamps, corrected for a measured lag).
                    o.at + SKEW_WINDOW < sent || wire + SKEW_WINDOW < on_wire
                })
            {
                o.superseded[r] = true;
            }
            o.reached[r] = o.reached[r].saturating_add(1);
            if bridged {
                o.bridged[r] = o.bridged[r].saturating_add(1);
                o.bridged_wire[r] = Some(wire);
                self.echoes.push_back((wire, s, r, *frame));
            } else {
                o.wire[bus].get_or_insert(wire);
            }
        }
        self.current = Some((r, of));
        self.current_wire = wire;
    }

    /// Node `node`'s port `port` handed a frame over late, at `now` on its clock.
    pub fn late(&mut self, node: usize, port: usize, now: Instant) {
        self.late[node][port & 1] = Some(self.sim_time(node, now));
    }

    /// Node `node`'s port `port` stamps with `clock` from now on (the simulator's).
    pub fn drift(&mut self, node: usize, port: usize, clock: StampClock) {
        self.stamps[node][port & 1] = clock;
    }

    /// Node `node`'s link delivered the copy being handed over (at `now` on its clock), its
    /// lag corrections `lags` (µs per port) when it came; `settling`: they changed within the
    /// window before. Its receive clocks disagreeing by more than half the skew window beyond
    /// them, or settling after they did, a duplicate is the promise's (a lag change on the
    /// wire: the copies up to the second frame that measures it, and those within the window
    /// after it, may come twice): not judged.
    pub fn unmeasured(&mut self, node: usize, now: Instant, lags: [i64; 2], settling: bool) {
        let t = self.sim_time(node, now);
        let off = |p: usize| self.stamps[node][p].offset_at(t) - lags[p];
        let residual = off(1) - off(0);
        // Its clocks drifting, or resynchronised lately (its correction then taken back).
        let drifted = (0..2).any(|p| {
            let c = self.stamps[node][p];
            c.ppm() != 0 || t.saturating_since(c.since()) < HORIZON
        });
        if !(residual.unsigned_abs() >= SKEW_WINDOW.as_micros() / 2 || settling && drifted) {
            return;
        }
        if let Some((r, Some(of))) = self.current.filter(|c| c.0 == node) {
            if let Some(o) = self.occ(of) {
                o.unmeasured[r] = true;
            }
        }
    }

    /// Node `node`'s link was handed the copy (at `now` on its clock), delivered or not.
    pub fn handled(&mut self, node: usize, now: Instant) {
        let t = self.sim_time(node, now);
        if let Some((r, Some(of))) = self.current.filter(|c| c.0 == node) {
            if let Some(o) = self.occ(of) {
                o.arrived[r].get_or_insert(t);
                o.last_arrived[r] = Some(t);
            }
        }
    }

    fn sim_time(&self, node: usize, now: Instant) -> Instant {
        self.clock[node].back(now)
    }

    /// Node `node`'s link delivered `frame` (the copy being handed to it).
    pub fn delivered(&mut self, node: usize, now: Instant, frame: &Frame) {
        if self.recent.len() <= node {
            self.recent.resize(node + 1, VecDeque::new());
        }
        let sender = match self.current {
            Some((r, Some(of))) if r == node => self.occ(of).map(|o| o.sender),
            _ => None,
        };
        if let Some(s) = sender {
            let t = self.sim_time(node, now);
            self.recent[node].push_back((t, s, *frame));
        }
        if frame.id() == Id::Standard(0x80) && self.sync_node == Some(node) {
            // When it was sent: a port's receive lag (a fault of the plant) delays SYNCs, and
            // one bus lagging behind the other hands some over late and out of order; what
            // the masters promise is the SYNCs they sent, every one delivered.
            let sent = match self.current {
                Some((r, Some(of))) if r == node => self.occ(of).map(|o| o.at),
                _ => None,
            };
            let at = sent.unwrap_or_else(|| self.sim_time(node, now));
            self.syncs.insert(at);
        }
        match self.current {
            Some((r, Some(of))) if r == node => {
                let mut sent = None;
                let mut beat = None;
                let mut o_state = 0;
                if let Some(o) = self.occ(of) {
                    o_state = o.frame.data().first().copied().unwrap_or(0);
                    o.delivered[r] = o.delivered[r].saturating_add(1);
                    sent = is_error_control(&o.frame).then_some((o.sender, o.at));
                    beat = is_heartbeat(&o.frame).then_some((o.sender, o.at, o.frame));
                }
                if let Some((s, at)) = sent {
                    if self.newest.len() <= r {
                        self.newest.resize(r + 1, [None; MAX_NODES]);
                    }
                    // A master that takes a heartbeat older than one it already took acts
                    // on a state the node has left (the promise table: superseded).
                    if self.state.len() <= r {
                        self.state.resize(r + 1, [None; MAX_NODES]);
                    }
                    let newest = self.state[r][s];
                    if let Some((s, at, frame)) = beat.filter(|_| self.nodes[r].master) {
                        // Older than the newest by more than the window, in another state.
                        let stale = newest.is_some_and(|(a, state)| {
                            at + SKEW_WINDOW < a && state != frame.data()[0]
                        });
                        if stale && !self.nodes[s].foreign {
                            self.violations.push(Violation {
                                sender: s,
                                receiver: r,
                                at,
                                frame,
                                fault: Fault::Stale,
                            });
                        }
                    }
                    let state = o_state;
                    let st = &mut self.state[r][s];
                    if st.is_none_or(|(a, _)| a < at) {
                        *st = Some((at, state));
                    }
                    let wire = self.current_wire;
                    let n = &mut self.newest[r][s];
                    *n = Some(n.map_or((at, wire), |(a, w)| (a.max(at), w.max(wire))));
                }
            }
            _ => self.foreign += 1,
        }
    }

    fn occ(&mut self, id: u64) -> Option<&mut Occurrence> {
        let i = id.checked_sub(self.base)?;
        self.pending.get_mut(i as usize)
    }

    /// Judges every occurrence sent before `now − JUDGE_AFTER`.
    pub fn judge(&mut self, now: Instant, wiring: &dyn Wiring, powered: &dyn Fn(usize) -> bool) {
        // What an occurrence judged from now on can be matched with (see `crossed`).
        let keep = now
            .as_micros()
            .saturating_sub((JUDGE_AFTER + SKEW_WINDOW).as_micros());
        for v in self.recent.iter_mut().chain(self.passed.iter_mut()) {
            while v.front().is_some_and(|d| d.0.as_micros() < keep) {
                v.pop_front();
            }
        }
        let near = (SKEW_WINDOW + HORIZON).as_micros();
        while self
            .stale
            .front()
            .is_some_and(|(w, _)| w.as_micros() + near < keep)
        {
            self.stale.pop_front();
        }
        while self
            .echoes
            .front()
            .is_some_and(|e| e.0.as_micros() + (JUDGE_AFTER + SKEW_WINDOW).as_micros() < keep)
        {
            self.echoes.pop_front();
        }
        while let Some(o) = self.pending.front() {
            if o.at + JUDGE_AFTER > now {
                break;
            }
            let mut o = self.pending.pop_front().unwrap();
            self.base += 1;
            self.judged += 1;
            self.indistinguishable(&mut o, wiring);
            // A frame of the node that is not duocan that reached nobody never left it: its
            // one transmit queue feeds both controllers, and a frame its controller on one bus
            // cannot send (long frames lost there) holds every frame behind it until that
            // controller gives up (bus-off). What the others receive of it is judged; what it
            // never sent is not; nor what it sent held back longer than a merger remembers, in
            // the backlog it then releases at once (its identical heartbeats back to back, a
            // fraction of a millisecond apart, some with one copy only: no layer can pair
            // them). Retransmissions on a noisy bus delay its frames far less: still judged.
            let held = o
                .arrived
                .iter()
                .flatten()
                .min()
                .is_some_and(|&a| a > o.at + HORIZON);
            let excused = self.nodes[o.sender].foreign
                && (o.reached.iter().all(|&n| n == 0) || held || self.apart(&o));
            for r in 0..self.nodes.len() {
                if r == o.sender || !powered(r) || self.nodes[r].foreign || excused {
                    continue;
                }
                if self.nodes[o.sender].foreign && self.apart_at(&o, r) {
                    continue;
                }
                if self.nodes[r].master && self.is_member_pdo(&o.frame) {
                    continue;
                }
                if self.nodes[r].master && is_error_control(&o.frame) && self.unknown_period(&o, r)
                {
                    continue;
                }
                let beats = &self.beats;
                let calm = |node, end| beats.calm_after(node, end);
                if wiring.excluded(o.sender, r, o.at, &o.frame, &calm) {
                    continue;
                }
                self.checks += 1;
                let fault = match (o.reached[r], o.delivered[r]) {
                    // Its two copies on either side of a jump ahead of the receiver's clock:
                    // their stamps are the jump apart, no twins (the promise table says so).
                    (2, 2) if self.straddles(&o, r, wiring) || self.swapped(&o, r) => None,
                    // Delivered while its receive clocks disagreed beyond the lags its layer
                    // had measured: twice until the layer measures it (the promise table).
                    (2, 2) if o.unmeasured[r] => None,
                    // A bridge loop's copy of it that reached the receiver within the skew
                    // window of a copy of the next identical frame of its sender (the bridge's
                    // delay a multiple of the sender's period): on that bus two identical
                    // frames at once, as if it had sent twice; a frame names no sender and
                    // carries no sequence number, so no receiver can tell which of the two is
                    // the copy (the promise table): once more for each such copy, not judged.
                    (_, d) if d > 1 && d <= 1 + o.bridged[r] && self.echo_beside_repeat(&o, r) => {
                        None
                    }
                    (_, d) if d > 1 => Some(Fault::Duplicated(d)),
                    (0, 0) => match wiring.connected(o.sender, r, o.at) {
                        Some(true) => Some(Fault::NeverArrived),
                        _ => None,
                    },
                    // A run straddling a change of the wiring (a bus cut as the other is
                    // repaired): the first occurrence only on one bus, the next only on the
                    // other, is one frame on both to any receiver; its copy delivered, the
                    // other's dropped as its twin (the merger's rule, see above).
                    (_, 0) if o.in_run && wiring.connected(o.sender, r, o.at).is_none() => None,
                    (_, 0) if o.superseded[r] || self.crossed(&o, r) => None,
                    // The other side of the same: a copy of it met a bridge's copy of an
                    // earlier identical frame of its sender within the window, and was taken
                    // for its twin (which of the two is the copy, no receiver can tell).
                    (_, 0) if self.beside_echo(&o, r) => None,
                    // Its only copy there handed over after a jump ahead of the receiver's
                    // clock, on the wire before it: as old as the jump to the layer, dropped
                    // as late (the promise table says so).
                    (_, 0) if o.arrived[r].is_some_and(|a| wiring.jumped(r, o.at, a)) => None,
                    (_, 0) => Some(Fault::Dropped),
                    _ => None,
                };
                if let Some(fault) = fault {
                    self.violations.push(Violation {
                        sender: o.sender,
                        receiver: r,
                        at: o.at,
                        frame: o.frame,
                        fault,
                    });
                }
            }
        }
    }

    /// Whether a bridge's copy of `o` reached receiver `r` within the skew window of a copy (on
    /// either bus) of a later occurrence of the same frame of the same sender, not judged yet.
    fn echo_beside_repeat(&self, o: &Occurrence, r: usize) -> bool {
        let Some(echo) = o.bridged_wire[r] else {
            return false;
        };
        self.pending.iter().any(|n| {
            n.sender == o.sender
                && n.frame == o.frame
                && n.wire.iter().flatten().any(|&w| within_window(w, echo))
        })
    }

    /// Whether a copy of `o` on the wire came within the skew window of a bridge's copy of
    /// another identical frame of its sender that reached receiver `r`.
    fn beside_echo(&self, o: &Occurrence, r: usize) -> bool {
        self.echoes.iter().any(|&(w, s, at, f)| {
            s == o.sender
                && at == r
                && f == o.frame
                && o.bridged_wire[r] != Some(w)
                && o.wire.iter().flatten().any(|&t| within_window(t, w))
        })
    }

    /// Whether `o`, of a sender that is not duocan, is one of its frames whose copies left
    /// further apart than the skew window, or near enough to one that its late copy could be
    /// matched with `o`'s (no layer can tell those from two frames: the late copy is
    /// delivered, or matched with a neighbour of the same content, whose own copy is then
    /// dropped): not judged. Every other sender's frames are, throughout. (A frame that could
    /// be matched with `o` has both its copies on the wire by the time `o` is judged.)
    fn apart(&mut self, o: &Occurrence) -> bool {
        let near = SKEW_WINDOW + HORIZON;
        let spread = |o: &Occurrence| o.on_wire().filter(|(a, b)| !within_window(*a, *b));
        if let Some((_, last)) = spread(o) {
            let until = last + near;
            self.apart_until = Some(self.apart_until.map_or(until, |u| u.max(until)));
        }
        self.apart_until.is_some_and(|u| o.at <= u)
            || self.apart_after(o, |n| spread(n).is_some())
            || self.beside_stale(o)
    }

    /// Whether a stale copy of `o`'s content (one its sender held longer than `o` waits to be
    /// judged, see [`Oracle::stale`]) reached the wire near enough to `o`'s copies to be
    /// matched with one of them (seed 1599: long frames lost on one bus for 1.5 s held the
    /// queue of the node that is not duocan; when the fault ended that bus carried 44 copies
    /// of its unchanging TPDO more than the other within 17 ms, stale ones first; a receiver
    /// counts identical copies, so as many fresh ones came twice). No layer can tell a stale
    /// copy from a fresh one of the same content: the count on that bus is what it sees.
    fn beside_stale(&self, o: &Occurrence) -> bool {
        let near = (SKEW_WINDOW + HORIZON).as_micros();
        self.stale.iter().any(|(w, f)| {
            *f == o.frame
                && o.wire
                    .iter()
                    .flatten()
                    .any(|a| a.as_micros().abs_diff(w.as_micros()) <= near)
        })
    }

    /// Whether one of `o`'s sender's frames after it, near enough to be matched with it, is
    /// `spread`.
    fn apart_after(&self, o: &Occurrence, spread: impl Fn(&Occurrence) -> bool) -> bool {
        let near = SKEW_WINDOW + HORIZON;
        self.pending
            .iter()
            .take_while(|n| n.at <= o.at + near)
            .any(|n| n.sender == o.sender && spread(n))
    }

    /// Whether `o`, of a sender that is not duocan, or one of that sender's frames after it and
    /// near enough to be matched with it, left its copies further apart than the skew window
    /// *as `r`'s clock reads them*: a receive stamp is that clock's reading, so a receiver whose
    /// clock runs fast sees the copies further apart than they were (seed 401: 4.8 ms on the
    /// wire behind retransmissions on a degrading bus, 5.04 ms to a board whose clock ran 5 %
    /// fast). [`Oracle::apart`] judges the spread on the simulated time line.
    fn apart_at(&self, o: &Occurrence, r: usize) -> bool {
        let clock = &self.clock[r];
        let spread = |n: &Occurrence| {
            n.on_wire()
                .is_some_and(|(a, b)| !within_window(clock.read(a), clock.read(b)))
        };
        spread(o) || self.apart_after(o, spread)
    }

    /// Node `node` was given another producer time at `at` (a confirmed download): a new span
    /// of [`Oracle::producer_changed`], or the one running goes on.
    pub fn producer_changed(&mut self, node: usize, at: Instant) {
        let spans = &mut self.producer_changed[node];
        if spans.last().is_none_or(|s| s.1 != Instant::MAX) {
            spans.push((at, Instant::MAX));
        }
    }

    /// Whether `o` is a heartbeat of a board beating at a producer time the application
    /// downloaded while master `r` was not running (it started after): `r`'s layer watches the
    /// period it is configured with and, at twice the rate, takes the board for two devices
    /// sharing its node-ID (the promise table: a master follows a download it saw; one that
    /// starts later is configured anew by the application, or resets the board as an
    /// impostor's victim and so configures it), until the verdict ends after its next boot.
    fn unknown_period(&self, o: &Occurrence, r: usize) -> bool {
        // After its boot-up, until three heartbeats at the configured pace end the verdict
        // (the boot-up among the heartbeats it drops: rule 1 of `link::plausible`).
        let tail = SLAVE_HB.saturating_mul(CALM_BEATS as u64 + 1);
        self.producer_changed[o.sender].iter().any(|&(c, until)| {
            c <= o.at && o.at < until.saturating_add(tail) && self.rebuilt[r].is_some_and(|b| b > c)
        })
    }

    /// Whether `o`'s copies left within the skew window of each other, on either side of a
    /// jump ahead of `r`'s clock: a receive stamp is the clock's reading of the moment the
    /// copy ended on the wire, so theirs are the jump apart, whenever each was handed over
    /// (quiet seeds 608, 928 and 934: behind a lagging port, the first handed over after the
    /// jump, or the second a lag later).
    fn straddles(&self, o: &Occurrence, r: usize, wiring: &dyn Wiring) -> bool {
        o.on_wire()
            .is_some_and(|(a, b)| within_window(a, b) && wiring.jumped(r, a, b))
    }

    /// Node `node`'s link was handed the copy (at `now` on its clock) and did not deliver it.
    pub fn not_delivered(&mut self, node: usize, now: Instant) {
        let t = self.sim_time(node, now);
        if let Some((r, Some(of))) = self.current.filter(|c| c.0 == node) {
            if let Some((s, f)) = self.occ(of).map(|o| (o.sender, o.frame)) {
                if self.passed.len() <= r {
                    self.passed.resize(r + 1, VecDeque::new());
                }
                self.passed[r].push_back((t, s, f));
            }
        }
    }

    /// Whether `o`, delivered twice at `r` from a copy on each bus, met there an identical
    /// frame of another sender on one bus only within the skew window, which was not
    /// delivered: the same two frames on three copies, counted right, one copy of `o` taken
    /// for the other's (see the module documentation).
    fn swapped(&self, o: &Occurrence, r: usize) -> bool {
        let near = |t: Instant| {
            [o.arrived[r], o.last_arrived[r]]
                .into_iter()
                .flatten()
                .any(|a| within_window(a, t))
        };
        other_sender(self.passed.get(r), o, near)
            || self.pending.iter().any(|n| {
                n.sender != o.sender
                    && n.frame == o.frame
                    && n.reached[r] == 1
                    && n.delivered[r] == 0
                    && n.arrived[r].is_some_and(near)
            })
    }

    /// Whether `o` reached `r` on one bus only within the skew window of an identical frame of
    /// another sender that was delivered there (see the module documentation).
    fn crossed(&self, o: &Occurrence, r: usize) -> bool {
        let (Some(t), true) = (o.arrived[r], o.reached[r] == 1) else {
            return false;
        };
        other_sender(self.recent.get(r), o, |d| within_window(d, t))
    }

    /// Evens out the deliveries of `o` (about to be judged) and the occurrences of the same
    /// frame from the same sender that follow it each within the skew window of the one
    /// before (a master's SDO request repeated back to back: three within half a
    /// millisecond): at a receiver that got a copy of each, as many deliveries as
    /// occurrences are one each, however they fell.
    fn indistinguishable(&mut self, o: &mut Occurrence, wiring: &dyn Wiring) {
        let mut group = vec![];
        let mut last = o.at;
        for (i, n) in self.pending.iter().enumerate() {
            if n.at.saturating_since(last) >= SKEW_WINDOW {
                break;
            }
            if n.sender == o.sender && n.frame == o.frame {
                group.push(i);
                last = n.at;
            }
        }
        if group.is_empty() {
            return;
        }
        o.in_run = true;
        for &i in &group {
            self.pending[i].in_run = true;
        }
        let size = group.len() + 1;
        for r in 0..self.nodes.len() {
            // One more for each whose copies straddle a jump ahead of the receiver's clock
            // (see `straddles`: seed 3249 of the quiet network, a request repeated back to
            // back, the first's copies on either side of a 70 ms jump).
            let extra = std::iter::once(&*o)
                .chain(group.iter().map(|&i| &self.pending[i]))
                .filter(|n| self.straddles(n, r, wiring))
                .count();
            let all_reached =
                o.reached[r] > 0 && group.iter().all(|&i| self.pending[i].reached[r] > 0);
            let total = o.delivered[r] as usize
                + group
                    .iter()
                    .map(|&i| self.pending[i].delivered[r] as usize)
                    .sum::<usize>();
            if all_reached && (size..=size + extra).contains(&total) {
                o.delivered[r] = 1;
                for &i in &group {
                    self.pending[i].delivered[r] = 1;
                }
            }
        }
    }

    fn is_member_pdo(&self, f: &Frame) -> bool {
        match f.id() {
            Id::Standard(id @ 0x180..=0x57F) => self.members.contains(&((id & 0x7F) as u8)),
            _ => false,
        }
    }

    /// The violations, one line each (at most `n`).
    pub fn report(&self, n: usize) -> String {
        let mut s = String::new();
        for v in self.violations.iter().take(n) {
            s += &format!(
                "  {} from {} at {}: {} {:?}\n",
                self.nodes[v.receiver].name, self.nodes[v.sender].name, v.at, v.frame, v.fault
            );
        }
        if self.violations.len() > n {
            s += &format!("  … {} more\n", self.violations.len() - n);
        }
        s
    }
}
