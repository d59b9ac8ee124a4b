//! A watched node's entry: its state on each bus (a leaky bucket per bus for rule 1, the
//! measuring window, the calm heartbeats that end a verdict) and the judgements made from it
//! (rule 1's verdict, whether a bus speaks for the node). The rules themselves, and when they
//! are judged, are in the parent module's documentation.

use super::{CALM_BEATS, NEVER};
use duocan_core::{Id, NodeId};

/// One bus of a watched node.
#[derive(Clone, Copy, Debug)]
pub(super) struct Track {
    /// Theoretical arrival time of the leaky bucket, in quarter microseconds (0: empty).
    pub(super) tat: u64,
    /// Its last heartbeat on this bus (µs), `NEVER`.
    pub(super) last: u64,
    /// The start of the measuring window (µs): when its heartbeats here were last found too
    /// fast, or a later period measured while that verdict held (one with a single heartbeat
    /// measured nothing).
    pub(super) since: u64,
    /// Heartbeats in the measuring window, `[since, since + T)`.
    pub(super) count: u32,
    /// The window's report is still due.
    pub(super) measuring: bool,
    /// Rule 1 holds: its heartbeats here are dropped.
    pub(super) fast: bool,
    /// Theoretical arrival time of the boot-ups' own bucket, in quarter microseconds.
    pub(super) boots: u64,
    /// While the verdict holds: its last heartbeat here (µs), the heartbeats in a row since
    /// at its pace, and the state the last said.
    pub(super) prev: u64,
    pub(super) calm: u8,
    pub(super) state: u8,
}

impl Track {
    pub(super) const NEW: Track = Track {
        tat: 0,
        last: NEVER,
        since: NEVER,
        count: 0,
        measuring: false,
        fast: false,
        boots: 0,
        prev: 0,
        calm: 0,
        state: 0,
    };
    pub(super) fn fast(&self) -> bool {
        self.fast
    }
    /// While the verdict holds, a heartbeat saying `state` stamped `t` (`tq` in quarter
    /// microseconds): [`CALM_BEATS`] in a row each at least `3T/4` after the one before are the
    /// node alone at its pace, which would take 18 periods to drain the bucket (a quarter
    /// period each): the bucket is emptied, and the verdict ends; so does a boot-up after one
    /// such heartbeat (a master reset the node). A heartbeat saying another state than the one
    /// before, or any other boot-up, counts neither way (see rule 1).
    pub(super) fn calm_beats(&mut self, t: u64, tq: u64, period: u64, state: u8) {
        let gap = t.saturating_sub(core::mem::replace(&mut self.prev, t));
        if state == 0 && self.calm > 0 {
            // A boot-up after a heartbeat at its pace: a master reset the node, alone.
            self.tat = self.tat.min(tq);
            return;
        }
        if state == 0 || state != core::mem::replace(&mut self.state, state) {
            return;
        }
        if gap.saturating_mul(4) < period.saturating_mul(3) {
            self.calm = 0;
        } else {
            self.calm = self.calm.saturating_add(1);
            if self.calm >= CALM_BEATS {
                self.tat = self.tat.min(tq);
            }
        }
    }
}

/// One watched node.
#[derive(Clone, Copy, Debug)]
pub(super) struct Watch {
    pub(super) node: NodeId,
    /// Producer time (µs), not zero.
    pub(super) period: u64,
    /// What each heartbeat adds to the bucket: 3T/4, in quarter microseconds (3T).
    pub(super) drain: u64,
    /// The most the bucket may hold: `BURST + 1` heartbeats' worth.
    pub(super) limit: u64,
    /// A bus is late for it once its last heartbeat there is this old (µs): 1.5 T.
    pub(super) late: u64,
    /// Arbitration key of its heartbeat ([`Frame::arbitration_key`](duocan_core::Frame::arbitration_key)),
    /// once heard: higher is lower priority.
    pub(super) key: Option<u64>,
    /// Its heartbeat identifier, once heard.
    pub(super) id: Option<Id>,
    pub(super) ports: [Track; 2],
    /// Its first heartbeat of this life (µs): after its last boot-up, or after it was heard
    /// nowhere for `W`; `NEVER`: heard nowhere.
    pub(super) life: u64,
    /// The life began with a boot-up (not with a first appearance).
    pub(super) booted: bool,
    /// Rule 2 holds: heard on this port only.
    pub(super) one_bus: Option<u8>,
    /// What the machine above was last told.
    pub(super) told: bool,
    /// Rule 1 holds for the node ([`Watch::too_fast_at`]) as last judged.
    pub(super) fast_verdict: bool,
    /// Stamp (µs) of the newest of its heartbeats handed up, `NEVER` (see "Order").
    pub(super) newest: u64,
    /// Rule 2 failed for want of a witness at this instant: checked again once the silent bus
    /// carried another watched heartbeat.
    pub(super) checked: u64,
    /// Nothing pending: heard on both buses, trusted, no verdict, no window, no failed check.
    /// The frame path needs to look no further; recomputed ([`Watch::settle`]) after anything
    /// else touched the entry.
    pub(super) quiet: bool,
    /// A producer time (ms) downloaded to it, waiting for the server's confirmation
    /// (`producer.rs`; without an allocator nothing is watched).
    #[cfg(feature = "alloc")]
    pub(super) producer: Option<u16>,
    /// Per bus (bit `p`): a master reset the node and its boot-up has not come over that bus
    /// yet, so the boot-up ends a verdict there (`reset.rs`). A byte of the entry, not a flag
    /// per [`Track`]: that would have grown every entry by 16 bytes (alignment).
    pub(super) reset: u8,
}

impl Watch {
    pub(super) fn settle(&mut self) {
        self.quiet = (0..2).all(|q| self.ports[q].last != NEVER && self.ports[q].last >= self.life)
            && !self.told
            && self.one_bus.is_none()
            && self.checked == NEVER
            && !self.ports.iter().any(|tr| tr.fast || tr.measuring);
    }
    /// Since when bus `q` has not carried its heartbeat in this life: its last one there, or
    /// the life's start if it carried none, unless the life began with a boot-up or nodes may
    /// be on one bus only (`NEVER`: heard nowhere, or not judged).
    pub(super) fn silent_on(&self, q: usize, one_bus_members: bool) -> u64 {
        let l = self.ports[q].last;
        if l != NEVER && l >= self.life {
            l
        } else if one_bus_members || self.booted {
            NEVER
        } else {
            self.life
        }
    }
    /// Rule 1's verdict at `t`: a bus too fast for the node, and the other bus not speaking
    /// for it (see "Verdicts"); the fast bus, if so. `behind[q]`: how far (µs) port `q`'s
    /// reader runs behind.
    pub(super) fn too_fast_at(&self, t: u64, behind: [u64; 2]) -> Option<u8> {
        (0..2)
            .find(|&p| self.ports[p].fast && !self.speaks(1 - p, t, behind))
            .map(|p| p as u8)
    }
    /// Bus `q` carried the node's heartbeat within 1.5 periods of `t`, as far as its port has
    /// shown it (a reader running behind has handed over its bus only up to that far before
    /// `t`: its silence since is not known), and is not too fast.
    pub(super) fn speaks(&self, q: usize, t: u64, behind: [u64; 2]) -> bool {
        let tr = &self.ports[q];
        !tr.fast
            && tr.last != NEVER
            && t.saturating_sub(behind[q]) <= tr.last.saturating_add(self.late)
    }
    /// While one bus is too fast and the other speaks: when the other falls silent.
    pub(super) fn speaks_until(&self, t: u64, behind: [u64; 2]) -> Option<u64> {
        (0..2)
            .find(|&p| self.ports[p].fast && self.speaks(1 - p, t, behind))
            .map(|p| {
                self.ports[1 - p]
                    .last
                    .saturating_add(self.late + behind[1 - p])
                    + 1
            })
    }
    /// Judges rule 1 at `t`; the fast bus if its verdict begins now.
    pub(super) fn judge_fast(&mut self, t: u64, behind: [u64; 2]) -> Option<u8> {
        let v = self.too_fast_at(t, behind);
        let onset = v.filter(|_| !self.fast_verdict);
        self.fast_verdict = v.is_some();
        onset
    }
    pub(super) fn suspect(&self) -> bool {
        self.one_bus.is_some() || self.fast_verdict
    }
}
