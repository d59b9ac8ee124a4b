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
//! frame.
//!
//! The layer's own frames, with a driver that confirms them: a gap ending while one is
//! unconfirmed does not count, and a confirmation is a frame seen. Which frames wait is port
//! health's count ([`PortHealth::in_flight`](crate::link::health::PortHealth::in_flight)),
//! which forgets the frames a flush or a re-initialisation discards and no driver confirms (a
//! count kept here held them for ever after a babble: the bus was never seen idle again). A
//! gap a confirmation ends, with no other own frame waiting, counts once the first frame
//! received after it is stamped later than the confirmation: frames come in the order of their
//! stamps, so none of the gap was still on its way. That is the gap before a SYNC this layer
//! sends; on a cyclic network every gap may end so, and the SYNC producer would otherwise never
//! see its bus idle. A receive path that runs behind delivers frames the confirmation overtook
//! instead, and the gap is no witness.
//!
//! With a driver that does not confirm, each own frame is taken to occupy the bus for `F` from
//! its hand-over, or from the end so reckoned of the one handed over before it (right while its
//! frames are not held back by traffic of higher priority than theirs: the layer's are NMT,
//! SYNC, SDO and process data, above every heartbeat).
//!
//! Memory: a few words per bus; nothing per frame but two comparisons.

use super::{Plausibility, NEVER};
use crate::link::health::Health;
use duocan::machine::PortStatus;
use duocan::Instant;

/// One bus as a whole.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bus {
    /// The latest frame seen on it, received or confirmed sent (µs); `NEVER`: none yet.
    seen: u64,
    /// This layer's own frames are off the bus by then, as far as it can tell (µs).
    own: u64,
    /// The latest instant the bus is known to have been idle (µs); 0: never.
    pub(super) idle: u64,
    /// A gap that a confirmation ended: idle at this instant (µs; 0: none) once the receive
    /// path has handed over a frame stamped `upto` or later, and none before.
    maybe: u64,
    upto: u64,
}

impl Bus {
    pub(super) const NEW: Bus = Bus {
        seen: NEVER,
        own: 0,
        idle: 0,
        maybe: 0,
        upto: 0,
    };

    /// A frame seen at `t` would end a gap longer than `f`: the bus was idle at the instant
    /// returned. `own`: the layer's own frames are off the bus by then (`NEVER`: one may be in
    /// the gap).
    fn gap(&self, t: u64, f: u64, own: u64) -> Option<u64> {
        let from = self.seen.max(own);
        (from != NEVER && t > from.saturating_add(f)).then(|| t - f)
    }

    fn seen_at(&mut self, t: u64) {
        self.seen = if self.seen == NEVER {
            t
        } else {
            self.seen.max(t)
        };
    }

    /// A received frame stamped `t`.
    fn received(&mut self, t: u64, f: u64, own: u64) {
        if self.maybe != 0 {
            // Frames come in the order of their stamps: the first one after the confirmation
            // tells whether a frame of the gap was still on its way (a receive path behind).
            if t >= self.upto {
                self.idle = self.idle.max(self.maybe);
            }
            self.maybe = 0;
        }
        if let Some(i) = self.gap(t, f, own) {
            self.idle = self.idle.max(i);
        }
        self.seen_at(t);
    }

    /// An own frame confirmed at `t`; `alone`: no other own frame waits.
    fn confirmed(&mut self, t: u64, f: u64, alone: bool) {
        if let Some(i) = self.gap(t, f, 0).filter(|_| alone) {
            (self.maybe, self.upto) = (i, t);
        }
        self.seen_at(t);
    }

    pub(super) fn step_back(&mut self, by: u64) {
        if self.seen != NEVER {
            self.seen = self.seen.saturating_sub(by);
        }
        self.own = self.own.saturating_sub(by);
        // A known idle instant stays known (at least 1 µs: 0 is "never").
        for t in [&mut self.idle, &mut self.maybe] {
            if *t != 0 {
                *t = t.saturating_sub(by).max(1);
            }
        }
        self.upto = self.upto.saturating_sub(by);
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
    pub(crate) fn on_frame(&mut self, now: Instant, p: usize, health: &Health) {
        if self.idle_on() {
            let t = now.as_micros().min(NEVER - 1);
            let b = &mut self.buses[p & 1];
            let own = match health.port(p & 1).in_flight() {
                Some(n) if n > 0 => NEVER, // an own frame may be in the gap
                _ => b.own,
            };
            b.received(t, self.frame_time, own);
        }
    }

    /// This layer handed a frame to port `p` at `now`.
    #[inline]
    pub(crate) fn on_handed(&mut self, now: Instant, p: usize) {
        if self.idle_on() {
            let b = &mut self.buses[p & 1];
            b.own = b.own.max(now.as_micros()).saturating_add(self.frame_time);
        }
    }

    /// The driver of port `p` reported `status` at `now` (port health has counted it): a
    /// confirmation is a frame seen.
    pub(crate) fn on_status(
        &mut self,
        now: Instant,
        p: usize,
        status: PortStatus,
        health: &Health,
    ) {
        if !self.idle_on() {
            return;
        }
        let in_flight = health.port(p & 1).in_flight();
        let b = &mut self.buses[p & 1];
        let ok = match status {
            PortStatus::TxOk => true,
            PortStatus::TxFailed(_) => false,
            _ => return,
        };
        let t = now.as_micros().min(NEVER - 1);
        if in_flight == Some(0) {
            // Every own frame is off the bus: the last one ended at the latest now.
            b.own = b.own.min(t);
        }
        if ok {
            // A frame that just ended on the bus. The gap it ends held no other own frame if
            // none waits now (the earlier ones were confirmed before it), and no received
            // frame if the next one received is stamped after it.
            b.confirmed(t, self.frame_time, in_flight == Some(0));
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
