//! What the run shows, computed from it: the timeline with measured reaction times, the
//! failovers against their bounds, the application messages end to end, the final state.
//!
//! Nothing here is a constant of the script: times come from the wire (the simulator's trace)
//! and from the devices' events, counts from what the boards sent and executed and what the
//! interlocking computers received.
//!
//! **Which computer must receive a board's message.** Both computers hear everything (hot
//! standby), but the one that counts is the one *in charge* of the rack when the message is
//! sent: among the computers powered and connected to the board, the active one (the better
//! ranked if, for an instant after a healed partition, both are); if none is active (a
//! takeover under way), the one that becomes active next, which got it as a standby. A message
//! must reach that computer exactly once, and no computer may get it twice.

use super::board::BoardEvent;
use super::handover::HandOver;
use super::interlocking::IlEvent;
use super::replacement::Replacement;
use super::station::{board_node, master_node, MASTER_NAMES, STRONG, WEAK};
use super::stopped::Stopped;
use super::{Act, Happened, Station, CONSUMER, DETECT_CYCLE, MASTER_TIMEOUT, SILENCE_LIMIT, SYNC};
use duocan::sim::{DeviceRef, TraceRecord, TxOutcome};
use duocan::{Duration, Frame, Instant, NmtState};
use duocan_redundancy::link::health::PortState;
use duocan_redundancy::supervisor::flying_master::{MasterReason, MasterRole};
use duocan_redundancy::{Member, NetworkEventKind as K};
use std::collections::HashMap;

/// A computer still has to be powered this long after a message is sent to be expected to
/// receive it (a message on the wire when the power goes is lost with the computer).
const GRACE: Duration = Duration::from_millis(2);
/// A message is looked for at its receivers this long after it was sent.
const WINDOW: Duration = Duration::from_millis(500);

/// One reaction measured in the run.
#[derive(Clone, Debug)]
pub struct Failover {
    /// The rack.
    pub rack: &'static str,
    /// What was measured.
    pub what: String,
    /// From (the event that starts the clock: last heartbeat, cut, heal).
    pub from: Instant,
    /// To (the reaction: NMT start on the wire, role change, port event).
    pub at: Instant,
    /// The bound the specification sets, if any.
    pub bound: Option<Duration>,
}

impl Failover {
    /// How long it took.
    pub fn took(&self) -> Duration {
        self.at.saturating_since(self.from)
    }
    /// Within its bound (or unbounded).
    pub fn within(&self) -> bool {
        self.bound.is_none_or(|b| self.took() <= b)
    }
}

/// Application messages of one rack, end to end.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Traffic {
    /// Commands of the route schedule.
    pub commands: usize,
    /// Command frames sent (all attempts, both computers).
    pub sends: usize,
    /// Of which repeats of an unanswered command.
    pub resends: usize,
    /// Commands executed by exactly one board.
    pub executed_once: usize,
    /// Commands executed more than once.
    pub executed_twice: usize,
    /// Commands never executed.
    pub not_executed: usize,
    /// Executions by a board whose partner was running too, or of another state.
    pub wrong: usize,
    /// Commands whose answer reached the computer in charge.
    pub answered: usize,
    /// Commands executed but not answered to the computer in charge.
    pub unanswered: usize,
    /// State changes sent by the running boards.
    pub reports: usize,
    /// Of which delivered exactly once to the computer in charge.
    pub delivered: usize,
    /// Of which it never got.
    pub lost: usize,
    /// Deliveries of one state change more than once to one computer.
    pub duplicates: usize,
    /// Payloads that failed their check at a computer.
    pub rejected: usize,
}

impl Traffic {
    /// Application messages lost: commands not executed or not answered, state changes not
    /// delivered.
    pub fn lost_total(&self) -> usize {
        self.not_executed + self.unanswered + self.lost
    }
    /// Application messages handled twice.
    pub fn duplicates_total(&self) -> usize {
        self.executed_twice + self.duplicates
    }
}

/// A pair at the end of the day.
#[derive(Clone, Debug)]
pub struct PairEnd {
    /// "P2".
    pub label: String,
    /// Members running (operational).
    pub running: Vec<Member>,
    /// The active member in the active computer's table.
    pub table: Option<Member>,
}

/// A rack at the end of the day.
#[derive(Clone, Debug)]
pub struct RackEnd {
    /// Its name.
    pub name: &'static str,
    /// Active computers (STRONG, WEAK).
    pub active: Vec<usize>,
    /// Its pairs.
    pub pairs: Vec<PairEnd>,
    /// The active computer's status table.
    pub status: String,
    /// Commands the active computer still waits for.
    pub unanswered: usize,
}

/// A line of the timeline: when, indentation, text.
#[derive(Clone, Debug)]
pub struct Line {
    /// Simulated time.
    pub at: Instant,
    /// 0: what the script did; 1: how the station reacted.
    pub depth: u8,
    /// The text.
    pub text: String,
}

/// Everything the demo prints and the test asserts.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The timeline.
    pub lines: Vec<Line>,
    /// Every measured reaction.
    pub failovers: Vec<Failover>,
    /// Boards replaced by a spare without node-ID.
    pub replacements: Vec<Replacement>,
    /// Buses handed over by a maintainer.
    pub hand_overs: Vec<HandOver>,
    /// Active boards that stopped by themselves.
    pub stops: Vec<Stopped>,
    /// Per rack.
    pub traffic: Vec<(&'static str, Traffic)>,
    /// Per rack.
    pub ends: Vec<RackEnd>,
    /// Frames on all buses, and the busiest bus's load.
    pub frames: u64,
    /// Highest bus load (fraction).
    pub max_load: f64,
}

impl Outcome {
    /// The verdicts of the scenes that have their own invariants (the hand-overs, the boards
    /// that stopped by themselves), and whether each held; a scripted scene the run did not show
    /// is a failed verdict.
    pub fn verdicts(&self, st: &Station) -> Vec<(String, bool)> {
        let mut v: Vec<(String, bool)> = self
            .hand_overs
            .iter()
            .map(|h| (h.summary(), h.held()))
            .chain(self.stops.iter().map(|s| (s.summary(), s.held())))
            .collect();
        let scripted = |f: fn(&Act) -> bool| st.happened.iter().filter(|h| f(&h.act)).count();
        if scripted(|a| matches!(a, Act::HandOver { .. })) != self.hand_overs.len()
            || scripted(|a| matches!(a, Act::BoardStops { .. })) != self.stops.len()
        {
            v.push((
                "every scripted hand-over and stop shown in the run".into(),
                false,
            ));
        }
        v
    }

    /// Sum over the racks.
    pub fn total(&self) -> Traffic {
        let mut t = Traffic::default();
        for (_, x) in &self.traffic {
            t.commands += x.commands;
            t.sends += x.sends;
            t.resends += x.resends;
            t.executed_once += x.executed_once;
            t.executed_twice += x.executed_twice;
            t.not_executed += x.not_executed;
            t.wrong += x.wrong;
            t.answered += x.answered;
            t.unanswered += x.unanswered;
            t.reports += x.reports;
            t.delivered += x.delivered;
            t.lost += x.lost;
            t.duplicates += x.duplicates;
            t.rejected += x.rejected;
        }
        t
    }
}

/// A frame delivered on a bus of a rack.
#[derive(Clone, Copy, Debug)]
pub struct Wire {
    /// When it ended.
    pub end: Instant,
    /// Who sent it.
    pub sender: DeviceRef,
    /// The frame.
    pub frame: Frame,
}

fn ms(d: Duration) -> String {
    format!("{:.1} ms", d.as_micros() as f64 / 1000.0)
}

/// The analysis of one station's day.
pub struct Analysis<'a> {
    st: &'a Station,
    /// Per rack: delivered frames of both buses, in order.
    wire: Vec<Vec<Wire>>,
}

impl<'a> Analysis<'a> {
    /// Reads the trace.
    pub fn new(st: &'a Station) -> Self {
        let mut wire = vec![Vec::new(); st.racks.len()];
        let mut rack_of = HashMap::new();
        for (i, r) in st.racks.iter().enumerate() {
            for b in r.buses() {
                rack_of.insert(b, i);
            }
        }
        for rec in st.sim.trace() {
            if let TraceRecord::Tx(x) = rec {
                if matches!(x.outcome, TxOutcome::Delivered { .. }) {
                    if let Some(&i) = rack_of.get(&x.bus) {
                        wire[i].push(Wire {
                            end: x.end,
                            sender: x.sender.device,
                            frame: x.frame,
                        });
                    }
                }
            }
        }
        Analysis { st, wire }
    }

    /// The station analysed.
    pub fn station(&self) -> &'a Station {
        self.st
    }

    fn happened(&self, f: impl Fn(&Act) -> bool) -> Option<&Happened> {
        self.st.happened.iter().find(|h| f(&h.act))
    }

    /// Whether computer `w` has power at `t`.
    fn powered(&self, w: usize, t: Instant) -> bool {
        let off = self.happened(|a| *a == Act::MasterKilled(w)).map(|h| h.at);
        let on = self.happened(|a| *a == Act::MasterBack(w)).map(|h| h.at);
        match (off, on) {
            (Some(k), Some(b)) => !(k <= t && t < b),
            (Some(k), None) => t < k,
            _ => true,
        }
    }

    /// Whether computer `w` is cut off from rack `rack`'s boards at `t`.
    fn isolated(&self, rack: usize, w: usize, t: Instant) -> bool {
        let p = self
            .happened(|a| *a == Act::Partition { rack })
            .map(|h| h.at);
        let h = self.happened(|a| *a == Act::Healed { rack }).map(|h| h.at);
        w == WEAK && p.is_some_and(|p| p <= t) && h.is_none_or(|h| t < h)
    }

    fn roles(&self, rack: usize, w: usize) -> Vec<(Instant, bool)> {
        self.st.racks[rack]
            .master_events(&self.st.sim, w)
            .iter()
            .filter_map(|(_, e)| match e {
                IlEvent::Net(n) => match &n.kind {
                    K::MasterRole(r) => Some((n.at, r.to.is_active())),
                    _ => None,
                },
                _ => None,
            })
            .collect()
    }

    pub(super) fn active_at(&self, rack: usize, w: usize, t: Instant) -> bool {
        self.powered(w, t)
            && self
                .roles(rack, w)
                .iter()
                .rev()
                .find(|(at, _)| *at <= t)
                .is_some_and(|r| r.1)
    }

    /// The computer in charge of `rack` for a message sent at `t` (see the module's doc).
    pub fn in_charge(&self, rack: usize, t: Instant) -> Option<usize> {
        let candidates: Vec<usize> = [STRONG, WEAK]
            .into_iter()
            .filter(|w| self.powered(*w, t) && self.powered(*w, t + GRACE))
            .filter(|w| !self.isolated(rack, *w, t))
            .collect();
        if let Some(&w) = candidates.iter().find(|w| self.active_at(rack, **w, t)) {
            return Some(w);
        }
        candidates
            .into_iter()
            .filter_map(|w| {
                self.roles(rack, w)
                    .into_iter()
                    .find(|(at, active)| *at >= t && *active)
                    .map(|(at, _)| (at, w))
            })
            .min()
            .map(|x| x.1)
    }

    /// A board's NMT state at `t` (not running while powered off).
    pub fn board_running(&self, rack: usize, pair: usize, m: Member, t: Instant) -> bool {
        let killed = self
            .st
            .happened
            .iter()
            .find(|h| h.act == Act::BoardKilled { rack, pair } && h.member == Some(m));
        let back = self
            .st
            .happened
            .iter()
            .find(|h| h.act == Act::BoardReplaced { rack, pair } && h.member == Some(m));
        if let Some(k) = killed {
            if k.at <= t && back.is_none_or(|b| t < b.at) {
                return false;
            }
        }
        let from = back.filter(|b| b.at <= t).map_or(Instant::ZERO, |b| b.at);
        self.st.racks[rack]
            .board_events(&self.st.sim, pair, m)
            .into_iter()
            .filter_map(|(at, e)| match e {
                BoardEvent::State(s) => Some((at, s)),
                _ => None,
            })
            .rfind(|(at, _)| *at >= from && *at <= t)
            .is_some_and(|(_, s)| s == NmtState::Operational)
    }

    /// The application messages of one rack.
    pub fn traffic(&self, rack: usize) -> Traffic {
        self.traffic_between(rack, Instant::ZERO, self.st.sim.now())
    }

    /// The application messages of one rack due or sent in `[from, to]` (commands by their due
    /// time, state changes by the time the board sent them).
    pub fn traffic_between(&self, rack: usize, from: Instant, to: Instant) -> Traffic {
        let r = &self.st.racks[rack];
        let sim = &self.st.sim;
        let during = |at: Instant| from <= at && at <= to;
        let mut t = Traffic {
            commands: r.schedule().iter().filter(|c| during(c.at)).count(),
            ..Traffic::default()
        };
        // What each computer received: (board, seq) → instants.
        let mut reports: [HashMap<(u8, u16), Vec<Instant>>; 2] = Default::default();
        let mut answers: [HashMap<u16, Vec<Instant>>; 2] = Default::default();
        for w in [STRONG, WEAK] {
            for (at, e) in r.master_events(sim, w) {
                match e {
                    IlEvent::Report { from, seq, .. } => {
                        reports[w].entry((from.raw(), *seq)).or_default().push(*at)
                    }
                    IlEvent::Answer { seq, .. } => answers[w].entry(*seq).or_default().push(*at),
                    IlEvent::Sent { attempt, .. } if during(*at) => {
                        t.sends += 1;
                        if *attempt > 1 {
                            t.resends += 1;
                        }
                    }
                    IlEvent::Rejected { .. } if during(*at) => t.rejected += 1,
                    _ => {}
                }
            }
        }
        let mut executions: HashMap<u16, Vec<(Instant, usize, Member, u8)>> = HashMap::new();
        for pair in 0..r.pairs() {
            for m in [Member::A, Member::B] {
                let node = board_node(pair, m).raw();
                for (at, e) in r.board_events(sim, pair, m) {
                    match e {
                        BoardEvent::Reported { seq, .. } if during(at) => {
                            t.reports += 1;
                            let within = |v: Option<&Vec<Instant>>| {
                                v.map_or(0, |v| {
                                    v.iter().filter(|d| **d >= at && **d <= at + WINDOW).count()
                                })
                            };
                            let got = [STRONG, WEAK].map(|w| within(reports[w].get(&(node, seq))));
                            match self.in_charge(rack, at).map(|w| got[w]) {
                                Some(1) => t.delivered += 1,
                                _ if got.iter().all(|n| *n == 0) => t.lost += 1,
                                Some(0) => t.lost += 1,
                                _ => {}
                            }
                            t.duplicates += got.iter().filter(|n| **n > 1).count();
                        }
                        BoardEvent::Executed { seq, code } => {
                            executions.entry(seq).or_default().push((at, pair, m, code))
                        }
                        _ => {}
                    }
                }
            }
        }
        for (i, route) in r.schedule().iter().enumerate() {
            if !during(route.at) {
                continue;
            }
            let seq = i as u16 + 1;
            let ex = executions.get(&seq).map_or(&[][..], |v| v.as_slice());
            match ex.len() {
                0 => t.not_executed += 1,
                1 => t.executed_once += 1,
                _ => t.executed_twice += 1,
            }
            let Some(&(at, pair, m, code)) = ex.first() else {
                continue;
            };
            if pair != route.pair
                || code != route.code
                || self.board_running(rack, pair, m.other(), at)
            {
                t.wrong += 1;
            }
            let answered = self
                .in_charge(rack, at)
                .and_then(|w| answers[w].get(&seq))
                .is_some_and(|v| v.iter().any(|d| *d >= at));
            if answered {
                t.answered += 1;
            } else {
                t.unanswered += 1;
            }
        }
        t
    }

    /// First copy (either bus) of the last frame `keep` accepts ending at or before `t`.
    fn last_before(
        &self,
        rack: usize,
        t: Instant,
        keep: impl Fn(&Wire) -> bool,
    ) -> Option<Instant> {
        let v: Vec<Instant> = self.wire[rack]
            .iter()
            .filter(|w| w.end <= t && keep(w))
            .map(|w| w.end)
            .collect();
        let last = *v.iter().max()?;
        // Its twin on the other bus may have ended a little earlier.
        v.into_iter()
            .filter(|e| last.saturating_since(*e) < Duration::from_millis(2))
            .min()
    }

    /// The frames of `rack` (both buses) that `keep` accepts, ending in `[from, to]`.
    pub(super) fn frames<'s>(
        &'s self,
        rack: usize,
        from: Instant,
        to: Instant,
        keep: impl Fn(&Wire) -> bool + 's,
    ) -> impl Iterator<Item = &'s Wire> + 's {
        self.wire[rack]
            .iter()
            .filter(move |w| w.end >= from && w.end <= to && keep(w))
    }

    pub(super) fn first_after(
        &self,
        rack: usize,
        t: Instant,
        keep: impl Fn(&Wire) -> bool,
    ) -> Option<Instant> {
        self.wire[rack]
            .iter()
            .find(|w| w.end > t && keep(w))
            .map(|w| w.end)
    }

    /// The largest gap between SYNCs (first copies) of `rack` in `[from, to]`.
    pub(super) fn sync_gap(&self, rack: usize, from: Instant, to: Instant) -> Duration {
        let id = self.st.racks[rack].sync_id();
        let mut last: Option<Instant> = None;
        let mut gap = Duration::ZERO;
        for w in &self.wire[rack] {
            if w.frame.id() != id || w.end < from || w.end > to {
                continue;
            }
            if let Some(l) = last {
                let d = w.end - l;
                if d >= Duration::from_millis(2) {
                    gap = gap.max(d);
                } else {
                    continue;
                }
            }
            last = Some(w.end);
        }
        gap
    }

    pub(super) fn net_events(
        &self,
        rack: usize,
        w: usize,
    ) -> impl Iterator<Item = &duocan_redundancy::NetworkEvent> + '_ {
        self.st.racks[rack]
            .master_events(&self.st.sim, w)
            .iter()
            .filter_map(|(_, e)| match e {
                IlEvent::Net(n) => Some(n),
                _ => None,
            })
    }

    pub(super) fn port_event(
        &self,
        rack: usize,
        w: usize,
        port: u8,
        after: Instant,
        to: PortState,
    ) -> Option<Instant> {
        self.net_events(rack, w)
            .find(|e| {
                e.at >= after
                    && matches!(e.kind, K::Port { port: p, to: s, .. } if p == port && s == to)
            })
            .map(|e| e.at)
    }

    fn role_change(
        &self,
        rack: usize,
        w: usize,
        after: Instant,
        active: bool,
    ) -> Option<(Instant, MasterReason)> {
        self.net_events(rack, w).find_map(|e| match &e.kind {
            K::MasterRole(r) if e.at >= after && r.to.is_active() == active => {
                Some((e.at, r.reason))
            }
            _ => None,
        })
    }

    /// Everything, from the run.
    pub fn outcome(&self) -> Outcome {
        let st = self.st;
        let mut lines = Vec::new();
        let mut failovers = Vec::new();
        let mut replacements = Vec::new();
        let mut hand_overs = Vec::new();
        let mut stops = Vec::new();
        let mut line = |at: Instant, depth: u8, text: String| lines.push(Line { at, depth, text });
        let first_route = st
            .racks
            .iter()
            .filter_map(|r| r.schedule().first())
            .map(|r| r.at)
            .min();
        if let Some(t) = first_route {
            let n: usize = st.racks.iter().map(|r| r.schedule().len()).sum();
            line(t, 0, format!("route setting starts: {n} commands to points, signals and level crossings until the end"));
        }
        for h in &st.happened {
            let at = h.at;
            match h.act {
                Act::BusCut { rack, bus } => {
                    let r = &st.racks[rack];
                    line(at, 0, format!("{}: bus {} cut", r.name(), bus + 1));
                    for w in [STRONG, WEAK] {
                        if let Some(t) = self.port_event(rack, w, bus as u8, at, PortState::Failed)
                        {
                            let f = Failover {
                                rack: r.name(),
                                what: format!("bus {} failed at the {}", bus + 1, MASTER_NAMES[w]),
                                from: at,
                                at: t,
                                bound: Some(SILENCE_LIMIT),
                            };
                            line(t, 1, format!("{} detects it after {} (silence limit {}); traffic goes on on bus {}", MASTER_NAMES[w], ms(f.took()), ms(SILENCE_LIMIT), 2 - bus));
                            failovers.push(f);
                        }
                    }
                }
                Act::BusRestored { rack, bus } => {
                    let r = &st.racks[rack];
                    line(at, 0, format!("{}: bus {} restored", r.name(), bus + 1));
                    if let Some(w) = self.in_charge(rack, at) {
                        if let Some(t) = self.port_event(rack, w, bus as u8, at, PortState::Ok) {
                            line(
                                t,
                                1,
                                format!(
                                    "{}: bus {} back in service after {}",
                                    MASTER_NAMES[w],
                                    bus + 1,
                                    ms(t - at)
                                ),
                            );
                            failovers.push(Failover {
                                rack: r.name(),
                                what: format!("bus {} back at the {}", bus + 1, MASTER_NAMES[w]),
                                from: at,
                                at: t,
                                bound: None,
                            });
                        }
                    }
                }
                Act::BoardKilled { rack, pair } => {
                    let r = &st.racks[rack];
                    let Some(m) = h.member else { continue };
                    let (node, other) = (board_node(pair, m), board_node(pair, m.other()));
                    let label = r.kind().label(pair);
                    line(
                        at,
                        0,
                        format!(
                            "{}: {label}'s active board {m} ({node}) loses power",
                            r.name()
                        ),
                    );
                    let dev = r.board_dev(pair, m);
                    let hb = r.heartbeat_id(node);
                    let last =
                        self.last_before(rack, at, |w| w.sender == dev && w.frame.id() == hb);
                    let nmt = r.nmt_id();
                    let start = self.first_after(rack, at, |w| {
                        w.frame.id() == nmt && w.frame.data() == [0x01, other.raw()]
                    });
                    if let (Some(last), Some(start)) = (last, start) {
                        let f = Failover {
                            rack: r.name(),
                            what: format!(
                                "{label}: board {} started after {m}'s last heartbeat",
                                m.other()
                            ),
                            from: last,
                            at: start,
                            bound: Some(CONSUMER + Duration::from_millis(1)),
                        };
                        line(start, 1, format!("{label}: board {} ({other}) started {} after {m}'s last heartbeat (bound {})", m.other(), ms(f.took()), ms(f.bound.unwrap_or_default())));
                        failovers.push(f);
                    }
                }
                Act::BoardReplaced { rack, pair } => {
                    if let Some((rep, ls, fs)) = self.replacement(h, rack, pair) {
                        for l in ls {
                            line(l.at, l.depth, l.text);
                        }
                        failovers.extend(fs);
                        replacements.push(rep);
                    }
                }
                Act::HandOver { rack, repaired } => {
                    let (ho, ls, fs) = self.hand_over(h, rack, repaired);
                    for l in ls {
                        line(l.at, l.depth, l.text);
                    }
                    failovers.extend(fs);
                    hand_overs.push(ho);
                }
                Act::BoardStops { rack, pair, state } => {
                    if let Some((s, ls, fs)) = self.stopped(h, rack, pair, state) {
                        for l in ls {
                            line(l.at, l.depth, l.text);
                        }
                        failovers.extend(fs);
                        stops.push(s);
                    }
                }
                Act::MasterKilled(dead) => {
                    line(
                        at,
                        0,
                        format!("{} loses power (all four racks)", MASTER_NAMES[dead]),
                    );
                    let alive = 1 - dead;
                    for (rack, r) in st.racks.iter().enumerate() {
                        let dev = r.master_dev(dead);
                        let hb = r.heartbeat_id(master_node(dead));
                        let last =
                            self.last_before(rack, at, |w| w.sender == dev && w.frame.id() == hb);
                        let took = self.role_change(rack, alive, at, true);
                        if let (Some(last), Some((t, _))) = (last, took) {
                            let f = Failover {
                                rack: r.name(),
                                what: format!(
                                    "{} active after the {}'s last heartbeat",
                                    MASTER_NAMES[alive], MASTER_NAMES[dead]
                                ),
                                from: last,
                                at: t,
                                bound: Some(MASTER_TIMEOUT + Duration::from_millis(1)),
                            };
                            let gap = self.sync_gap(
                                rack,
                                at - Duration::from_millis(100),
                                t + Duration::from_millis(100),
                            );
                            line(t, 1, format!("{}: {} active {} after the last heartbeat (bound {}); longest SYNC gap {}", r.name(), MASTER_NAMES[alive], ms(f.took()), ms(f.bound.unwrap_or_default()), ms(gap)));
                            failovers.push(f);
                            failovers.push(Failover {
                                rack: r.name(),
                                what: "SYNC gap over the takeover".into(),
                                from: t,
                                at: t + gap,
                                bound: Some(MASTER_TIMEOUT + SYNC),
                            });
                        }
                    }
                }
                Act::MasterBack(w) => {
                    line(at, 0, format!("{} powered on again", MASTER_NAMES[w]));
                    // Standby, following the other computer, on every rack.
                    let standby = (0..st.racks.len())
                        .map(|rack| {
                            self.net_events(rack, w).find_map(|e| match &e.kind {
                                K::MasterRole(r)
                                    if e.at >= at
                                        && matches!(r.to, MasterRole::Standby(Some(_))) =>
                                {
                                    Some(e.at)
                                }
                                _ => None,
                            })
                        })
                        .collect::<Option<Vec<_>>>()
                        .and_then(|v| v.into_iter().max());
                    if let Some(t) = standby {
                        line(t, 1, format!("standby on every rack after {}; the {} stays active (non-revertive)", ms(t - at), MASTER_NAMES[1 - w]));
                        failovers.push(Failover {
                            rack: "station",
                            what: format!("{} back as standby", MASTER_NAMES[w]),
                            from: at,
                            at: t,
                            bound: None,
                        });
                    }
                }
                Act::Partition { rack } => {
                    let r = &st.racks[rack];
                    line(
                        at,
                        0,
                        format!(
                            "{}: both buses split between the computers, the {} alone on one side",
                            r.name(),
                            MASTER_NAMES[WEAK]
                        ),
                    );
                    let dev = r.master_dev(WEAK);
                    let hb = r.heartbeat_id(master_node(WEAK));
                    let last =
                        self.last_before(rack, at, |w| w.sender == dev && w.frame.id() == hb);
                    if let (Some(last), Some((t, _))) =
                        (last, self.role_change(rack, STRONG, at, true))
                    {
                        let f = Failover {
                            rack: r.name(),
                            what: format!(
                                "{} active after the {}'s last heartbeat",
                                MASTER_NAMES[STRONG], MASTER_NAMES[WEAK]
                            ),
                            from: last,
                            at: t,
                            bound: Some(MASTER_TIMEOUT + Duration::from_millis(1)),
                        };
                        line(t, 1, format!("{} active on the boards' side {} after the weak master's last heartbeat (bound {}); the cut-off weak master stays active on its own", MASTER_NAMES[STRONG], ms(f.took()), ms(f.bound.unwrap_or_default())));
                        failovers.push(f);
                    }
                }
                Act::Healed { rack } => {
                    let r = &st.racks[rack];
                    line(
                        at,
                        0,
                        format!("{}: partition healed, two active masters", r.name()),
                    );
                    if let Some((t, reason)) = self.role_change(rack, WEAK, at, false) {
                        let f = Failover {
                            rack: r.name(),
                            what: format!("{} stepped down after the heal", MASTER_NAMES[WEAK]),
                            from: at,
                            at: t,
                            bound: Some(DETECT_CYCLE),
                        };
                        line(
                            t,
                            1,
                            format!(
                                "{} steps down after {} (bound: one detect cycle, {}): {reason}",
                                MASTER_NAMES[WEAK],
                                ms(f.took()),
                                ms(DETECT_CYCLE)
                            ),
                        );
                        failovers.push(f);
                    }
                }
            }
        }
        // Commands that met a failure on their way: how they got through.
        for r in &st.racks {
            let mut sends: HashMap<u16, Vec<(Instant, usize, duocan::NodeId)>> = HashMap::new();
            for w in [STRONG, WEAK] {
                for (at, e) in r.master_events(&st.sim, w) {
                    if let IlEvent::Sent { seq, to, .. } = e {
                        sends.entry(*seq).or_default().push((*at, w, *to));
                    }
                }
            }
            let mut executed: HashMap<u16, (Instant, Member)> = HashMap::new();
            for pair in 0..r.pairs() {
                for m in [Member::A, Member::B] {
                    for (at, e) in r.board_events(&st.sim, pair, m) {
                        if let BoardEvent::Executed { seq, .. } = e {
                            executed.entry(seq).or_insert((at, m));
                        }
                    }
                }
            }
            for (i, route) in r.schedule().iter().enumerate() {
                let seq = i as u16 + 1;
                let Some(&(t, m)) = executed.get(&seq) else {
                    continue;
                };
                if t - route.at < Duration::from_millis(5) {
                    continue;
                }
                let mut v = sends.get(&seq).cloned().unwrap_or_default();
                v.sort();
                let member = |n: duocan::NodeId| {
                    if n == board_node(route.pair, Member::A) {
                        "A"
                    } else {
                        "B"
                    }
                };
                let path: Vec<String> = v
                    .iter()
                    .map(|(at, w, to)| {
                        format!(
                            "{} -> {} at {:.3} s",
                            MASTER_NAMES[*w],
                            member(*to),
                            at.as_micros() as f64 / 1e6
                        )
                    })
                    .collect();
                line(
                    t,
                    1,
                    format!(
                        "{}: {} -> {} (due {:.3} s) executed by {m} {} late; sent: {}",
                        r.name(),
                        r.kind().label(route.pair),
                        r.kind().word(route.code),
                        route.at.as_micros() as f64 / 1e6,
                        ms(t - route.at),
                        path.join(", "),
                    ),
                );
            }
        }
        lines.sort_by_key(|l| (l.at, l.depth));
        let traffic = (0..st.racks.len())
            .map(|i| (st.racks[i].name(), self.traffic(i)))
            .collect();
        let now = st.sim.now();
        let ends = st
            .racks
            .iter()
            .map(|r| {
                let active: Vec<usize> = [STRONG, WEAK]
                    .into_iter()
                    .filter(|w| {
                        st.sim.is_powered(r.master_dev(*w)) && r.role(&st.sim, *w).is_active()
                    })
                    .collect();
                let shown = active.first().copied().unwrap_or(WEAK);
                let pairs = (0..r.pairs())
                    .map(|p| PairEnd {
                        label: r.kind().label(p),
                        running: [Member::A, Member::B]
                            .into_iter()
                            .filter(|m| {
                                st.sim.is_powered(r.board_dev(p, *m))
                                    && r.board_state(&st.sim, p, *m) == NmtState::Operational
                            })
                            .collect(),
                        table: r.active_member(&st.sim, shown, p),
                    })
                    .collect();
                RackEnd {
                    name: r.name(),
                    active,
                    pairs,
                    status: r.status(&st.sim, shown, now),
                    unanswered: r.unanswered(&st.sim, shown),
                }
            })
            .collect();
        let mut frames = 0;
        let mut max_load: f64 = 0.0;
        for r in &st.racks {
            for b in r.buses() {
                frames += st.sim.bus_stats(b).delivered;
                max_load = max_load.max(st.sim.bus_load(b));
            }
        }
        Outcome {
            lines,
            failovers,
            replacements,
            hand_overs,
            stops,
            traffic,
            ends,
            frames,
            max_load,
        }
    }
}
