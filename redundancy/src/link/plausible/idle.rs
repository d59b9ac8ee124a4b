//! Rule 2's idle witness: when was each bus last known idle?
//!
//! CAN arbitration lets a frame wait only while the bus is busy: a frame queued when the bus
//! goes idle starts at once. So a bus seen idle after a node's heartbeat was due on it did not
//! starve that heartbeat, whatever the node's priority, and its absence there is real.
//!
//! The layer sees a bus through the times it is given: each received frame's, and for its own
//! frames the hand-over and, if the driver reports them, the confirmations (`TxOk`,
//! `TxFailed`). A gap between two consecutive frames longer than the frame time `F` (the
//! longest a frame with its intermission occupies the bus, plus the jitter of the times given;
//! [`DualBusConfig::frame_time`](crate::DualBusConfig::frame_time)) means the bus was idle just
//! before the later frame began: at `t − F` at the latest, `t` being the time of the later
//! frame. The layer's own frames: with a driver that confirms them, a gap ending while one is
//! unconfirmed does not count, and a confirmation is a frame seen; with one that does not, each
//! is taken to occupy the bus for `F` from its hand-over, or from the end so reckoned of the one
//! handed over before it (right while its frames are not held back by traffic of higher priority
//! than theirs: the layer's are NMT, SYNC, SDO and process data, above every heartbeat).
//!
//! Memory: a few words per bus; nothing per frame but two comparisons.

use super::{Plausibility, NEVER};
use duocan::machine::PortStatus;
use duocan::Instant;

/// Own frames counted as unconfirmed at most (the health module keeps as many).
const PENDING: u16 = 64;

/// One bus as a whole.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bus {
    /// The latest frame seen on it, received or confirmed sent (µs); `NEVER`: none yet.
    seen: u64,
    /// This layer's own frames are off the bus by then, as far as it can tell (µs).
    own: u64,
    /// Own frames handed over and not yet confirmed (counted once the driver confirms).
    pending: u16,
    /// The driver confirms successful transmissions.
    confirms: bool,
    /// The latest instant the bus is known to have been idle (µs); 0: never.
    pub(super) idle: u64,
}

impl Bus {
    pub(super) const NEW: Bus = Bus {
        seen: NEVER,
        own: 0,
        pending: 0,
        confirms: false,
        idle: 0,
    };

    /// A frame seen at `t` ends a gap: idle before it if the gap is longer than `f`.
    fn frame(&mut self, t: u64, f: u64) {
        if self.seen != NEVER {
            let own = if self.confirms && self.pending > 0 {
                NEVER // an own frame may be in the gap
            } else {
                self.own
            };
            let from = self.seen.max(own);
            if from != NEVER && t > from.saturating_add(f) {
                self.idle = self.idle.max(t - f);
            }
            self.seen = self.seen.max(t);
        } else {
            self.seen = t;
        }
    }

    pub(super) fn step_back(&mut self, by: u64) {
        if self.seen != NEVER {
            self.seen = self.seen.saturating_sub(by);
        }
        self.own = self.own.saturating_sub(by);
        // A known idle instant stays known (at least 1 µs: 0 is "never").
        if self.idle != 0 {
            self.idle = self.idle.saturating_sub(by).max(1);
        }
    }
}

impl Plausibility {
    /// The idle witness is kept: rule 2 is on, with a frame time, for watched nodes (from the
    /// first watch on: what went before is not known).
    #[inline]
    fn idle_on(&self) -> bool {
        self.frame_time != 0 && self.window.is_some() && self.table.is_some()
    }

    /// Any frame arrived on port `p` at `now` (every received frame, before its kind is known).
    #[inline]
    pub(crate) fn on_frame(&mut self, now: Instant, p: usize) {
        if self.idle_on() {
            let t = now.as_micros().min(NEVER - 1);
            self.buses[p & 1].frame(t, self.frame_time);
        }
    }

    /// This layer handed a frame to port `p` at `now`.
    #[inline]
    pub(crate) fn on_handed(&mut self, now: Instant, p: usize) {
        if self.idle_on() {
            let b = &mut self.buses[p & 1];
            b.pending = (b.pending + 1).min(PENDING);
            b.own = b.own.max(now.as_micros()).saturating_add(self.frame_time);
        }
    }

    /// The driver of port `p` reported `status` at `now`: a confirmation is a frame seen.
    pub(crate) fn on_status(&mut self, now: Instant, p: usize, status: PortStatus) {
        if !self.idle_on() {
            return;
        }
        let b = &mut self.buses[p & 1];
        let ok = match status {
            PortStatus::TxOk => true,
            PortStatus::TxFailed(_) => false,
            _ => return,
        };
        b.confirms |= ok;
        b.pending = b.pending.saturating_sub(1);
        let t = now.as_micros().min(NEVER - 1);
        if b.confirms && b.pending == 0 {
            // Every own frame is off the bus: the last one ended at the latest now.
            b.own = b.own.min(t);
        }
        if ok {
            // A frame that just ended on the bus, as a received one.
            b.frame(t, self.frame_time);
        } else if b.seen == NEVER || b.seen < t {
            // A failed attempt is no frame to measure a gap by, but may have used the bus.
            b.seen = t;
        }
    }

    /// The latest instant port `p`'s bus is known to have been idle (rule 2's witness).
    pub fn idle_seen(&self, p: usize) -> Option<Instant> {
        let idle = self.buses[p.min(1)].idle;
        (idle != 0).then(|| Instant::from_micros(idle))
    }
}
