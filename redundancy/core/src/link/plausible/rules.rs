//! The two rules and the verdicts, at each heartbeat and at each deadline.

use super::{Plausibility, Track, BABBLE_FACTOR, NEVER, ON};
use crate::link::events::{LinkEvent, LinkEventKind, Suspicion};
use crate::link::health::{Health, PortState};
use crate::link::outbox::{Outbox, MACHINE_QUEUE};
use duocan_core::machine::LinkRequest;
use duocan_core::{Frame, Id, Instant, NodeId};

impl Plausibility {
    /// An error-control frame of `node` (heartbeat or boot-up) arrived on port `p` at `now`.
    /// Returns true if it is to be dropped: that bus carries `node`'s heartbeats far too fast.
    ///
    /// The frame path of every watched heartbeat. The common case — a node heard on both buses
    /// at its pace, trusted, nothing pending — moves its bucket and its last heartbeat and
    /// nothing else; everything else is [`Plausibility::judge`], out of line.
    #[inline]
    pub(crate) fn on_heartbeat(
        &mut self,
        now: Instant,
        p: usize,
        node: NodeId,
        frame: &Frame,
        health: &Health,
        out: &mut Outbox,
    ) -> bool {
        if !ON {
            return false;
        }
        let t = now.as_micros();
        // Below 2^60 µs (36,000 years) no sum here can overflow: plain arithmetic.
        if let (true, false, Some(win), Some(table)) = (
            t < 1 << 60,
            self.unsynced,
            self.window,
            self.table.as_deref_mut(),
        ) {
            let i = table.index[(node.raw() & 0x7F) as usize];
            if i == super::NONE {
                return false;
            }
            if let Some(w) = table.watched.get_mut(i as usize) {
                // Quiet means heard on both buses (neither time is NEVER); with the other bus
                // heard and not late, this heartbeat changes nothing but the bucket.
                let other = w.ports[(p ^ 1) & 1].last;
                if w.quiet
                    && t < other + win
                    && t <= other + w.late
                    && frame.data().first() != Some(&0)
                {
                    let tr = &mut w.ports[p & 1];
                    let tq = t * 4;
                    let tat = tr.tat.max(tq) + w.drain;
                    if tat - tq <= w.limit {
                        (tr.last, tr.tat) = (t, tat);
                        self.last_any[p & 1] = t;
                        return false;
                    }
                }
            }
        }
        self.judge(now, p, node, frame, health, out)
    }

    /// [`Plausibility::on_heartbeat`] when anything may change: both rules in full.
    #[cold]
    #[inline(never)]
    fn judge(
        &mut self,
        now: Instant,
        p: usize,
        node: NodeId,
        frame: &Frame,
        health: &Health,
        out: &mut Outbox,
    ) -> bool {
        if self.unsynced {
            self.sync_all(now, health, out);
        }
        // A heartbeat at the end of time is not "never heard".
        let t = now.as_micros().min(NEVER - 1);
        let (window, one_bus_members) = (self.window, self.one_bus_members);
        let Some(table) = self.table.as_deref_mut() else {
            return false;
        };
        let i = table.index[node.raw() as usize];
        if i == super::NONE {
            return false;
        }
        let i = i as usize;
        let w = &mut table.watched[i];
        if w.id.is_none() {
            w.id = Some(frame.id());
            w.key = Some(frame.arbitration_key());
        }
        // Rule 1: the leaky bucket, in quarter microseconds.
        let (drain, limit, period, late_after) = (w.drain, w.limit, w.period, w.late);
        let tq = t.saturating_mul(4);
        let state = frame.data().first().copied();
        let boot_up = state == Some(0);
        let state = state.unwrap_or(u8::MAX);
        let reset = boot_up && w.reset & (1 << p) != 0;
        w.reset &= !(u8::from(boot_up) << p);
        let tr = &mut w.ports[p];
        let before = tr.last;
        tr.last = t;
        if reset {
            // The boot-up a master's reset asked for: the verdict ends (`reset.rs`).
            tr.tat = tr.tat.min(tq);
        }
        if boot_up {
            // A new life: what it sent before is not this life's burst (a board reset twice
            // in a few periods, by a failover and its repair). At most one boot-up per two
            // periods empties the bucket, so a babble of boot-ups is flagged like any other.
            let d = period.saturating_mul(8);
            let boots = tr.boots.max(tq).saturating_add(d);
            // Not while a verdict holds: a babble on that bus goes on whoever boots.
            if boots - tq <= d && !tr.fast {
                tr.tat = tr.tat.min(tq);
            }
            tr.boots = boots.min(tq.saturating_add(2 * d));
        }
        if tr.fast {
            tr.calm_beats(t, tq, period, state);
        }
        if tr.tat <= tq {
            // Drained: a verdict ended at `tat` (the sweep normally saw to it on time).
            tr.fast = false;
        }
        let tat = tr.tat.max(tq).saturating_add(drain);
        let excess = tat - tq > limit;
        // The cap keeps a babble's past from outliving it by more than `BURST + 2` drains.
        tr.tat = tat.min(tq.saturating_add(limit.saturating_add(drain)));
        if tr.measuring && t >= tr.since && t < tr.since.saturating_add(period) {
            tr.count = tr.count.saturating_add(1);
        }
        let started = excess && !tr.fast;
        if started {
            tr.fast = true;
            (tr.prev, tr.calm, tr.state) = (t, 0, state);
            if !tr.measuring {
                // The window is [t, t + T): this heartbeat and those of one period after it.
                tr.since = t;
                tr.count = 1;
                tr.measuring = true;
            }
        }
        let fast = tr.fast;
        let drained = tr.tat.div_ceil(4);
        // Rule 2's bookkeeping: a new life (booted, or heard nowhere for a window), heard on
        // the other bus again.
        let mut recheck = false;
        let mut due = None;
        if let Some(win) = window {
            let heard = |l: u64| l != NEVER && t < l.saturating_add(win);
            let other = w.ports[1 - p].last;
            if boot_up || w.life == NEVER || !(heard(before) || heard(other)) {
                // A boot-up, or heard nowhere for a window (here, or at a deadline that came
                // before a receive path running behind handed this over): a new life, judged
                // afresh (the other bus silent since it began, until it carries the node).
                w.life = t;
                w.booted = boot_up;
                w.one_bus = None;
            }
            if !boot_up && heard(other) && w.one_bus.is_some_and(|h| h as usize != p) {
                w.one_bus = None;
            }
            // The other bus's deadline is armed only once it missed a heartbeat: the frame
            // path of a node heard on both buses sets no timer.
            let silent = w.silent_on(1 - p, one_bus_members);
            let late = silent != NEVER && silent.saturating_add(late_after) < t;
            if w.one_bus.is_some() {
                due = Some(t.saturating_add(win));
            } else if late {
                due = Some(silent.saturating_add(win));
            }
            // A check that lacked a witness (or a deadline noticed late) is made at once.
            recheck = w.checked != NEVER || due.is_some_and(|d| d <= t);
        }
        let behind = behind(health);
        let mut onset = w
            .judge_fast(t, behind)
            .map(|port| Suspicion::TooFast { port });
        let speaks_until = w.speaks_until(t, behind);
        let changed = w.suspect() != w.told;
        if window.is_some() {
            self.last_any[p] = t;
        }
        if let Some(d) = due.filter(|d| *d > t) {
            self.wake(d);
        }
        if fast {
            self.wake(drained);
        }
        if let Some(d) = speaks_until {
            self.wake(d);
        }
        if started {
            self.wake(t.saturating_add(period));
        } else if recheck && self.one_bus_due(i, t, health) {
            self.at(i).one_bus = Some(p as u8);
            onset = Some(Suspicion::OneBus { heard: p as u8 });
        }
        if let Some(why) = onset {
            out.event(LinkEvent {
                at: now,
                kind: LinkEventKind::Suspect { node, why },
            });
        }
        if changed || onset.is_some() {
            self.sync(i, now, health, out);
        }
        self.at(i).settle();
        fast
    }

    /// Rule 2 for watched node `i` at `t`: heard on one bus only for `W`, the other healthy.
    fn one_bus_due(&mut self, i: usize, t: u64, health: &Health) -> bool {
        let Some(win) = self.window else {
            return false;
        };
        let one_bus_members = self.one_bus_members;
        let w = &self.entries()[i];
        if w.life == NEVER || w.one_bus.is_some() {
            return false;
        }
        let Some(q) = (0..2).find(|&q| {
            let (sq, lp) = (w.silent_on(q, one_bus_members), w.ports[1 - q].last);
            sq.saturating_add(win) <= t && lp != NEVER && t < lp.saturating_add(win)
        }) else {
            return false;
        };
        // Its heartbeat was due on the silent bus by then at the latest: 1.5 periods after
        // the later of its last heartbeat there and the port's return from a fault that may
        // lose frames (a heartbeat sent while the bus was cut is lost, not waiting).
        let since = health.port(q).back().as_micros();
        let after = w
            .silent_on(q, one_bus_members)
            .max(since)
            .saturating_add(w.period + w.period / 2);
        // The bus idle after that: the heartbeat was not waiting for it (`idle.rs`).
        let idle = self.buses[q].idle > after;
        if !idle && w.checked != NEVER && self.last_any[q] <= w.checked {
            return false; // nothing new on the silent bus since the last failed check
        }
        let ok = health.port(q).state() == PortState::Ok && (idle || self.witnessed(i, q, after));
        self.at(i).checked = if ok { NEVER } else { t };
        ok
    }

    /// A lower-priority watched heartbeat arrived on `q` after `after`.
    fn witnessed(&self, i: usize, q: usize, after: u64) -> bool {
        let Some(k) = self.entries()[i].key else {
            return false;
        };
        self.entries().iter().any(|m| {
            m.key.is_some_and(|mk| mk > k) && m.ports[q].last != NEVER && m.ports[q].last > after
        })
    }

    /// Ends, reports and judges what is due at `now`, each at its own instant, and recomputes
    /// the next deadline.
    pub(crate) fn handle_timeout(&mut self, now: Instant, health: &Health, out: &mut Outbox) {
        if !ON {
            return;
        }
        if self.unsynced {
            self.sync_all(now, health, out);
        }
        let t = now.as_micros();
        if self.next.is_none_or(|n| n > t) {
            return;
        }
        let one_bus_members = self.one_bus_members;
        let mut next: Option<u64> = None;
        let mut soonest = |d: u64| {
            if d > t {
                next = Some(next.map_or(d, |n: u64| n.min(d)));
            }
        };
        for i in 0..self.entries().len() {
            let node = self.at(i).node;
            for p in 0..2 {
                let w = self.at(i);
                let period = w.period;
                let id = w.id;
                let tr = &mut w.ports[p];
                if tr.measuring {
                    let end = tr.since.saturating_add(period);
                    if end <= t && tr.count <= 1 && tr.fast {
                        // One heartbeat in the period is the node's own pace: no rate to
                        // report yet. While the verdict holds, the next period is measured (a
                        // second device beating slower may have skipped this one); a verdict
                        // that ends first was a burst (a sender or reader stalled and caught
                        // up), and nothing is reported.
                        (tr.since, tr.count) = (end, 0);
                        soonest(end.saturating_add(period));
                    } else if end <= t {
                        tr.measuring = false;
                        if tr.count > 1 {
                            out.event(report(node, id, p, tr, period, end));
                        }
                    } else {
                        soonest(end);
                    }
                }
                if tr.fast {
                    let drained = tr.tat.div_ceil(4);
                    if drained <= t {
                        tr.fast = false;
                    } else {
                        soonest(drained);
                    }
                }
            }
            let w = self.at(i);
            let behind = behind(health);
            if let Some(port) = w.judge_fast(t, behind) {
                out.event(LinkEvent {
                    at: now,
                    kind: LinkEventKind::Suspect {
                        node,
                        why: Suspicion::TooFast { port },
                    },
                });
            }
            if let Some(d) = w.speaks_until(t, behind) {
                soonest(d);
            }
            if let Some(win) = self.window {
                self.sweep_one_bus(i, t, win, health, out);
                let w = &self.entries()[i];
                let late = |l: u64| l.saturating_add(w.late) < t;
                for s in (0..2)
                    .map(|q| w.silent_on(q, one_bus_members))
                    .filter(|s| *s != NEVER)
                {
                    // The end of a one-bus verdict; the fall of a bus that missed a heartbeat.
                    if w.one_bus.is_some() || late(s) {
                        soonest(s.saturating_add(win));
                    }
                }
            }
            self.sync(i, now, health, out);
            self.at(i).settle();
        }
        self.next = next;
    }

    /// Rule 2's deadlines for node `i` up to `t`.
    fn sweep_one_bus(&mut self, i: usize, t: u64, win: u64, health: &Health, out: &mut Outbox) {
        let one_bus_members = self.one_bus_members;
        let w = self.at(i);
        let heard = |l: u64| l != NEVER && t < l.saturating_add(win);
        if !heard(w.ports[0].last) && !heard(w.ports[1].last) {
            // Heard nowhere: nothing left to doubt; a new appearance is judged afresh.
            w.life = NEVER;
            w.one_bus = None;
            return;
        }
        let falls = (0..2)
            .map(|q| w.silent_on(q, one_bus_members).saturating_add(win))
            .filter(|d| *d <= t)
            .max();
        if let Some(fall) = falls {
            // Judged at the deadline, unless an earlier check lacked a witness.
            let at = if self.at(i).checked == NEVER { fall } else { t };
            if self.one_bus_due(i, t, health) {
                let w = self.at(i);
                let p = if heard(w.ports[0].last) { 0 } else { 1 };
                w.one_bus = Some(p as u8);
                out.event(LinkEvent {
                    at: Instant::from_micros(at),
                    kind: LinkEventKind::Suspect {
                        node: w.node,
                        why: Suspicion::OneBus { heard: p as u8 },
                    },
                });
            }
        }
    }

    /// Hands node `i`'s state to the machine above if it changed (and reports the end of a
    /// suspicion); if the queue is full it is retried at the next input.
    fn sync(&mut self, i: usize, now: Instant, health: &Health, out: &mut Outbox) {
        let w = self.at(i);
        let suspect = w.suspect();
        if suspect == w.told {
            return;
        }
        if out.machine.len() >= MACHINE_QUEUE {
            self.unsynced = true;
            return;
        }
        // Too fast on every bus that works (a failed port's bus may be the one cut, a
        // recovering one's too: re-initialised, it has not shown it hears anything), silent on
        // none: a second device beats beside the node. (With one bus only by the first check,
        // a duplicate was taken for an impostor while the other bus was cut: the member was
        // reset, its boot-up lost among the duplicate's heartbeats, and its pair was left
        // without a running board when the other member died.)
        let working = |q: usize| {
            !matches!(
                health.port(q).state(),
                PortState::Failed | PortState::Recovering
            )
        };
        let fast = |q: usize| w.ports[q].fast();
        let duplicated = suspect
            && w.one_bus.is_none()
            && (0..2).any(fast)
            && (0..2).all(|q| fast(q) || !working(q));
        out.machine(LinkRequest::NodeSuspect {
            node: w.node,
            suspect,
            duplicated,
        });
        w.told = suspect;
        if !suspect {
            out.event(LinkEvent {
                at: now,
                kind: LinkEventKind::Trusted { node: w.node },
            });
        }
    }

    fn sync_all(&mut self, now: Instant, health: &Health, out: &mut Outbox) {
        self.unsynced = false;
        for i in 0..self.entries().len() {
            self.sync(i, now, health, out);
            self.at(i).settle();
        }
    }
}

/// The rate measured in the window after a too-fast verdict, as a babble or a duplicate.
/// How far (µs) each port's reader runs behind: how long after its stamp its last frame was
/// handed over.
fn behind(health: &Health) -> [u64; 2] {
    [0, 1].map(|q| health.port(q).rx_delay().as_micros())
}

fn report(node: NodeId, id: Option<Id>, p: usize, tr: &Track, period: u64, end: u64) -> LinkEvent {
    let per_s = |n: u64| (n.saturating_mul(1_000_000) / period.max(1)).min(u32::MAX as u64) as u32;
    let (rate, allowed) = (per_s(tr.count as u64), per_s(1));
    let since = Instant::from_micros(tr.since);
    let port = p as u8;
    let kind = if tr.count as u64 > BABBLE_FACTOR {
        LinkEventKind::Babbling {
            node,
            id: id.unwrap_or(Id::Standard(0)),
            port,
            rate,
            allowed,
            since,
        }
    } else {
        LinkEventKind::DuplicateNode {
            node,
            port,
            rate,
            allowed,
            since,
        }
    };
    LinkEvent {
        at: Instant::from_micros(end),
        kind,
    }
}
