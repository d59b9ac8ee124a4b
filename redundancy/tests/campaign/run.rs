//! A run: the plant, its fault timeline, scheduled actions, and the invariants checked every
//! millisecond of simulated time.
//!
//! Invariants (the promise table of the user guide's redundant-master chapter says which fault
//! classes each must survive):
//!
//! - **exactly once** ([`crate::oracle`]): every frame occurrence reaches every device it could
//!   reach exactly once;
//! - **a running board per pair**: a pair with a live member, whose members an active master
//!   can reach in time (a bus between them on which neither receives later than the slack,
//!   [`crate::timeline::LAG_SLACK`]), is without an operational member for at most
//!   [`PAIR_BOUND`] at a time;
//! - **one active master**: two masters active at once for at most [`TWO_MASTERS_BOUND`],
//!   unless they could not hear each other (no bus between them) in the last detect cycle;
//! - **SYNC**: the SYNCs the observer node gets were sent with no gap over [`SYNC_BOUND`]
//!   while a live master can reach it, and from within [`SYNC_AFTER_OUTAGE`] of its being
//!   reached again after no master could (judged by when they were sent: a receive lag the
//!   campaign injects delays them all alike);
//! - **SDO** ([`crate::sdo`]): every transfer a master starts ends, completed with the right
//!   data or aborted with a reason, within [`crate::sdo::SDO_BOUND`]; none times out while a
//!   bus connected the master and the server for the whole transfer (from
//!   [`crate::timeline::MARGIN`] before its start), unless the fault schedule explains it: the
//!   server off, rebooted or not answering SDO (stopped) meanwhile, or the master's clock
//!   jumped ahead by the rest of its timeout (a jump is time that passed). A transfer whose
//!   master died or rebooted is gone with it;
//! - **bounded memory**: no layer's merger overflows, no queue drops.

use crate::foreign::FOREIGN;
use crate::oracle::JUDGE_AFTER;
use crate::plant::*;
use crate::sdo::{End, Transfer, SDO_BOUND};
use crate::timeline::MARGIN;
use crate::timeline::{Dev, Timeline};
use duocan::{Duration, Instant, NmtState};
use duocan_redundancy::supervisor::flying_master::MasterRole;

/// A pair may be without an operational board this long under composed faults: its consumer
/// time (a silent or stopped active board), the reachability window (an impostor on one bus,
/// 3 × 20 ms), the master timeout (its master dies meanwhile), a board's boot and configuration
/// (~20 ms) and a heartbeat period of scheduling, with room. The exact single-fault bounds
/// (consumer time + 1 ms and the like) are asserted by the dedicated tests.
pub const PAIR_BOUND: Duration = Duration::from_millis(400);
/// Two active masters at once, while they can hear each other, at most this long (the
/// detection timeout of the flying master, 100 ms by default).
pub const TWO_MASTERS_BOUND: Duration = Duration::from_millis(100);
/// After the masters could not hear each other, the worse of two active ones steps down within
/// a detect cycle (4 s by default) and a negotiation.
pub const SPLIT_ALLOWANCE: Duration = Duration::from_millis(4_700);
/// The largest SYNC gap at the observer while a live master reaches it: the SYNC period plus
/// the master timeout (the active master dies, the other takes over) plus a frame. A master
/// whose port hands its frames over late (a receive lag) learns of the other's death that much
/// later: the bound grows by the largest lag a master's port had during the gap.
pub const SYNC_BOUND: Duration = Duration::from_millis(61);
/// After a time when no live master reached the observer (both buses cut between them), SYNC
/// is back within this: the masters' detection timeout (both may have gone active and one
/// steps down, or the one that stayed waits out its suspension) plus a period and a frame.
pub const SYNC_AFTER_OUTAGE: Duration = Duration::from_millis(111);

/// How long a receive lag beyond the slack disturbs what a device's heartbeat consumers saw
/// (a consumer time, and the masters' negotiation after a master seemed lost, with room).
pub const SLOW_MEMORY: Duration = Duration::from_millis(200);

/// A scheduled action.
pub type Action = Box<dyn FnOnce(&mut Run)>;

pub struct Run {
    pub plant: Plant,
    pub timeline: Timeline,
    actions: Vec<(Instant, u64, Action)>,
    seq: u64,
    /// Per pair: since when it has had no operational member (while judged).
    no_board: Vec<Option<Instant>>,
    two_since: Option<Instant>,
    /// The masters last had no bus between them.
    masters_apart: Option<Instant>,
    /// When the last SYNC judged at the observer was sent.
    last_sync: Option<Instant>,
    /// Spans of time when no live master reached the observer, and when no master was alive.
    observer_cut: Vec<(Instant, Instant)>,
    no_master: Vec<(Instant, Instant)>,
    /// A disturbance of the pair (or of every pair) that restarts its clock: member rebooted,
    /// master rebooted, a clock change.
    pub settle_from: Vec<Instant>,
    pub problems: Vec<String>,
    /// Longest seen: pair without a board, two masters, SYNC gap.
    pub worst: [Duration; 3],
    /// Faults that took effect, by class ([`crate::effects`]).
    pub effective: std::collections::BTreeMap<&'static str, u32>,
}

impl Run {
    pub fn new(p: Params) -> Run {
        let plant = Plant::new(p);
        let mut timeline = Timeline::default();
        let o = plant.oracle.borrow();
        for (i, n) in o.nodes.iter().enumerate() {
            let id = match i {
                0 => STRONG,
                1 => WEAK,
                _ => plant.slaves.get(i - 2).map_or(FOREIGN, |s| s.0),
            };
            timeline.devs.push(Dev {
                node_id: id,
                swapped: n.swapped,
                ..Dev::default()
            });
        }
        drop(o);
        let obs = timeline.devs.iter().position(|d| d.node_id == OBSERVER);
        plant.oracle.borrow_mut().sync_node = obs;
        let pairs = p.pairs as usize;
        Run {
            plant,
            timeline,
            actions: vec![],
            seq: 0,
            no_board: vec![None; pairs],
            two_since: None,
            masters_apart: None,
            last_sync: None,
            observer_cut: vec![],
            no_master: vec![],
            settle_from: vec![Instant::ZERO; pairs],
            problems: vec![],
            worst: [Duration::ZERO; 3],
            effective: Default::default(),
        }
    }

    pub fn now(&self) -> Instant {
        self.plant.sim.now()
    }

    /// Does `f` at `t`.
    pub fn at(&mut self, t: Instant, f: impl FnOnce(&mut Run) + 'static) {
        self.seq += 1;
        self.actions.push((t, self.seq, Box::new(f)));
    }

    /// Runs to `end`, a millisecond at a time: actions due, the simulation, the checks.
    pub fn run_until(&mut self, end: Instant) {
        let ms = Duration::from_millis(1);
        while self.now() < end {
            let t = (self.now() + ms).min(end);
            self.actions.sort_by_key(|a| (a.0, a.1));
            while self.actions.first().is_some_and(|a| a.0 <= self.now()) {
                let (_, _, f) = self.actions.remove(0);
                f(self);
            }
            self.plant.sim.run_until(t);
            self.check(t);
        }
    }

    fn oracle_node(&self, id: u8) -> usize {
        self.timeline
            .devs
            .iter()
            .position(|d| d.node_id == id)
            .expect("a node")
    }

    /// Whether a bus connects the two oracle nodes at `t` (no margin).
    fn linked(&self, s: usize, r: usize, t: Instant) -> bool {
        self.linked_by(s, r, t, false)
    }

    /// The same, by a bus on which neither receives late beyond the slack (now or within the
    /// last [`SLOW_MEMORY`]): their heartbeats reach each other in time.
    fn timely(&self, s: usize, r: usize, t: Instant) -> bool {
        self.linked_by(s, r, t, true)
    }

    fn linked_by(&self, s: usize, r: usize, t: Instant, timely: bool) -> bool {
        (0..2).any(|b| {
            let (ds, dr) = (&self.timeline.devs[s], &self.timeline.devs[r]);
            let (ps, pr) = (ds.port(b), dr.port(b));
            let since = t.saturating_sub(SLOW_MEMORY);
            let slow = timely && (ds.slow[ps].any(since, t) || dr.slow[pr].any(since, t));
            !slow
                && !self.timeline.cut[b].at(t)
                && !self.timeline.babbled[b].at(t)
                && !ds.unplugged[ps].at(t)
                && !ds.tx_dead[ps].at(t)
                && !dr.tx_dead[pr].at(t)
                && !ds.stalled[ps].at(t)
                && !dr.stalled[pr].at(t)
                && !dr.unplugged[pr].at(t)
                && !ds.off.at(t)
                && !dr.off.at(t)
        })
    }

    fn check(&mut self, t: Instant) {
        // Exactly once.
        {
            // Producer times the masters downloaded: the boards beat at another period since.
            let writes = std::mem::take(&mut self.plant.sdo.borrow_mut().producer_writes);
            for (board, at) in writes {
                let i = crate::faults::dev_index(self, board);
                self.plant.oracle.borrow_mut().producer_changed(i, at);
            }
            let tl = &self.timeline;
            let powered = |_: usize| true;
            self.plant.oracle.borrow_mut().judge(t, tl, &powered);
        }
        let sim = &self.plant.sim;
        // Masters.
        let on = [0, 1].map(|k| sim.is_powered(self.plant.masters[k]));
        let active =
            [0, 1].map(|k| on[k] && self.plant.sup(k as u8 + 1).role() == MasterRole::Active);
        let (m1, m2) = (self.oracle_node(STRONG), self.oracle_node(WEAK));
        let apart = on[0] && on[1] && !self.timely(m1, m2, t);
        // Pairs.
        let live_master = (0..2).find(|k| on[*k] && active[*k]);
        let mut pairs = vec![];
        for i in 0..self.plant.p.pairs {
            let members = [a(i), b(i)];
            let running = members.iter().any(|&id| {
                let (d, _) = self.plant.slave(id);
                sim.is_powered(d)
                    && sim.device(d).inner.machine.nmt_state() == NmtState::Operational
            });
            let reachable = live_master.is_some_and(|k| {
                let m = if k == 0 { m1 } else { m2 };
                members.iter().any(|&id| {
                    let (d, node) = self.plant.slave(id);
                    sim.is_powered(d) && self.timely(m, node, t)
                })
            });
            pairs.push(running || !reachable);
        }
        // SYNC at the observer.
        let obs = self.oracle_node(OBSERVER);
        let reached = (0..2).any(|k| on[k] && self.linked(if k == 0 { m1 } else { m2 }, obs, t));

        if apart {
            self.masters_apart = Some(t);
        }
        if active[0] && active[1] {
            let since = *self.two_since.get_or_insert(t);
            let split = self
                .masters_apart
                .is_some_and(|a| t.saturating_since(a) < SPLIT_ALLOWANCE);
            let allowed = if split {
                SPLIT_ALLOWANCE
            } else {
                self.on_masters_clocks(TWO_MASTERS_BOUND, since, t)
            };
            let d = t.saturating_since(since);
            if !split {
                self.worst[1] = self.worst[1].max(d);
            }
            if d > allowed {
                self.problem(t, format!("two active masters since {since}"));
                self.two_since = Some(t);
            }
        } else {
            self.two_since = None;
        }
        for (i, fine) in pairs.into_iter().enumerate() {
            if fine {
                self.no_board[i] = None;
                continue;
            }
            let since = (*self.no_board[i].get_or_insert(t)).max(self.settle_from[i]);
            let d = t.saturating_since(since);
            self.worst[0] = self.worst[0].max(d);
            if d > PAIR_BOUND {
                self.problem(t, format!("pair {i} without a running board since {since}"));
                self.no_board[i] = Some(t);
            }
        }
        let any_master = on[0] || on[1];
        if !reached && any_master {
            mark(&mut self.observer_cut, t);
        }
        if !any_master {
            mark(&mut self.no_master, t);
        }
        self.judge_syncs(t);
        self.note_stopped(t);
        self.judge_sdo(t);
    }

    /// Which slaves' SDO servers do not answer now (stopped, booting).
    fn note_stopped(&mut self, t: Instant) {
        for k in 0..self.plant.slaves.len() {
            let (_, d, node) = self.plant.slaves[k];
            let sim = &self.plant.sim;
            let mute = sim.is_powered(d)
                && matches!(
                    sim.device(d).inner.machine.nmt_state(),
                    NmtState::Stopped | NmtState::Initialising
                );
            let sp = &mut self.timeline.devs[node].stopped;
            if mute {
                sp.start(t);
            } else {
                sp.end(t);
            }
        }
    }

    /// The SDO transfers that ended, or should have by now.
    fn judge_sdo(&mut self, t: Instant) {
        let ledger = self.plant.sdo.clone();
        let mut l = ledger.borrow_mut();
        let lives = l.lives;
        let mut done = vec![];
        for (k, x) in l.open.iter().enumerate() {
            let m = (x.master - 1) as usize;
            let on = self.plant.sim.is_powered(self.plant.masters[m]);
            if x.life != lives[m] || !on {
                done.push((k, None));
                continue;
            }
            match x.end {
                Some((e, end)) => done.push((k, Some((e, end)))),
                None if t.saturating_since(x.start) > SDO_BOUND => {
                    self.problem(
                        t,
                        format!(
                            "SDO transfer m{} to {:#x} started at {} did not end",
                            x.master, x.server, x.start
                        ),
                    );
                    done.push((k, None));
                }
                None => {}
            }
        }
        for (k, end) in done.into_iter().rev() {
            let x = l.open.remove(k);
            let Some((e, end)) = end else {
                l.lost += 1;
                continue;
            };
            match end {
                End::Done => l.completed += 1,
                End::Aborted(code) => {
                    l.aborted += 1;
                    if std::env::var("CAMPAIGN_VERBOSE").is_ok() {
                        eprintln!(
                            "{e}: SDO m{} from {:#x} (segmented {}) started at {} aborted: {code:?}",
                            x.master, x.server, x.segmented, x.start
                        );
                    }
                }
                End::WrongData => {
                    self.problem(
                        e,
                        format!(
                            "SDO m{} from {:#x} started at {}: wrong data",
                            x.master, x.server, x.start
                        ),
                    );
                }
                End::Timeout => {
                    l.timeouts += 1;
                    if let Some(why) = self.sdo_unexplained(&x, e) {
                        self.problem(
                            e,
                            format!(
                                "SDO m{} from {:#x} (segmented {}) started at {} timed out: {why}",
                                x.master, x.server, x.segmented, x.start
                            ),
                        );
                    }
                }
            }
        }
    }

    /// Why a timeout of `x` at `e` breaks the promise, if it does.
    fn sdo_unexplained(&self, x: &Transfer, e: Instant) -> Option<&'static str> {
        let (m, s) = (self.oracle_node(x.master), self.oracle_node(x.server));
        let from = x.start.saturating_sub(MARGIN);
        let tl = &self.timeline;
        let server = &tl.devs[s];
        let jumped = tl.devs[m].jumps.iter().any(|(j, by)| {
            *j >= x.start && *j <= e && *by + e.saturating_since(x.start) >= crate::sdo::TIMEOUT
        });
        let explained = !tl.intact(m, s, from, e)
            || server.off.any(from, e)
            || server.reboots.iter().any(|b| *b >= from && *b <= e)
            || server.stopped.any(from, e)
            || jumped;
        (!explained).then_some("a bus connected them all along")
    }

    /// The observer's SYNCs sent before `t − JUDGE_AFTER` (all their copies have arrived):
    /// the gaps between them.
    fn judge_syncs(&mut self, t: Instant) {
        loop {
            let h = {
                let mut o = self.plant.oracle.borrow_mut();
                match o.syncs.first() {
                    Some(h) if t.saturating_since(*h) > JUDGE_AFTER => o.syncs.pop_first(),
                    _ => None,
                }
            };
            let Some(h) = h else { break };
            if let Some(l) = self.last_sync.replace(h) {
                let within = |spans: &[(Instant, Instant)]| {
                    spans
                        .iter()
                        .filter(|(a, b)| *a <= h && *b >= l)
                        .map(|(_, b)| *b.min(&h))
                        .max()
                };
                if within(&self.no_master).is_some() {
                    // No master at all meanwhile: the next one negotiates from a cold start;
                    // the gap until its first SYNC is not the redundancy's to bound.
                } else if let Some(c) = within(&self.observer_cut) {
                    // Cut off meanwhile: SYNC is back soon after it was reached again.
                    if h.saturating_since(c) > SYNC_AFTER_OUTAGE {
                        self.problem(h, format!("SYNC back only at {h}, reached again at {c}"));
                    }
                } else {
                    let gap = h.saturating_since(l);
                    self.worst[2] = self.worst[2].max(gap);
                    let lag = self
                        .timeline
                        .devs
                        .iter()
                        .filter(|d| d.node_id == STRONG || d.node_id == WEAK)
                        .map(|d| d.lag(l, h))
                        .max()
                        .unwrap_or(Duration::ZERO);
                    if gap > self.on_masters_clocks(SYNC_BOUND, l, h) + lag {
                        self.problem(h, format!("SYNC gap {gap} at the observer after {l}"));
                    }
                }
            }
            for spans in [&mut self.observer_cut, &mut self.no_master] {
                spans.retain(|(_, b)| *b >= h);
            }
        }
    }

    /// `bound`, timed by the masters' clocks over `[from, to]`: as much longer as the slower
    /// master's clock ran slow meanwhile (a master timeout of 50 ms on a clock 10 % slow is
    /// 55.6 ms of the simulated time).
    fn on_masters_clocks(&self, bound: Duration, from: Instant, to: Instant) -> Duration {
        let ppm = (self.timeline.devs.iter())
            .filter(|d| d.node_id == STRONG || d.node_id == WEAK)
            .map(|d| d.slowest(from, to))
            .min()
            .unwrap_or(0);
        let rate = (1_000_000 + ppm as i64) as u64;
        Duration::from_micros((bound.as_micros() * 1_000_000).div_ceil(rate))
    }

    /// No master holds the network at `t` (the last one alive was power-cycled): the next
    /// negotiates from a cold start.
    pub fn no_master_at(&mut self, t: Instant) {
        mark(&mut self.no_master, t);
    }

    pub fn problem(&mut self, t: Instant, what: String) {
        if self.problems.len() < 50 {
            self.problems.push(format!("{t}: {what}"));
        }
    }

    /// The end of the run: memory and queues, and everything found.
    pub fn finish(&mut self) -> Result<(), String> {
        let end = self.now() + crate::oracle::JUDGE_AFTER + Duration::from_millis(1);
        self.run_until(end);
        let sim = &self.plant.sim;
        let mut links = vec![];
        for (k, d) in self.plant.masters.iter().enumerate() {
            links.push((
                format!("m{}", k + 1),
                sim.device(*d).inner.link.inner.merger().stats(),
                sim.device(*d).inner.link.inner.stats(),
            ));
        }
        for (id, d, _) in &self.plant.slaves {
            links.push((
                format!("s{id:#x}"),
                sim.device(*d).inner.link.inner.merger().stats(),
                sim.device(*d).inner.link.inner.stats(),
            ));
        }
        for (name, m, s) in links {
            if m.evicted > 0 || s.tx_dropped > 0 || s.events_dropped > 0 || s.requests_dropped > 0 {
                self.problem(
                    end,
                    format!("{name}: memory or queues overflowed: {m:?} {s:?}"),
                );
            }
        }
        let o = self.plant.oracle.borrow();
        let mut report = String::new();
        if !o.violations.is_empty() {
            report += &format!(
                "{} exactly-once violations:\n{}",
                o.violations.len(),
                o.report(20)
            );
        }
        if !self.problems.is_empty() {
            report += &format!(
                "{} invariant violations:\n  {}\n",
                self.problems.len(),
                self.problems.join("\n  ")
            );
        }
        if report.is_empty() {
            Ok(())
        } else {
            Err(report)
        }
    }
}

/// Adds instant `t` (a millisecond after the previous check) to a list of spans.
fn mark(spans: &mut Vec<(Instant, Instant)>, t: Instant) {
    match spans.last_mut() {
        Some((_, b)) if t.saturating_since(*b) <= Duration::from_millis(1) => *b = t,
        _ => spans.push((t, t)),
    }
}
