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
//! The layer's own frames, with a driver that confirms them (`TxOk`, `TxFailed`: an attempt
//! that ended then): each confirmation is the end of a frame on the bus, at the time the
//! driver reports it. A receive path that runs behind hands its frames over later than their
//! stamps, after confirmations of own frames that ended later on the wire; so the ends of the
//! own frames wait (`OWN` at most) until the received frames have passed them, and both are
//! merged in the order of their ends: the gaps measured are those of the wire, however far
//! behind the receive path runs. (Measured in the order they were handed over, a receive lag
//! longer than the SYNC period hid every gap, and an impostor of the highest node-ID of a
//! network was never caught by the master whose port lagged; taken from a confirmation at once,
//! the gap before it held received frames still on their way, and a lag looked like idle bus.)
//! A gap a received frame ends counts only up to the hand-over of an own frame that still
//! waits for its outcome, as if that frame had ended it: it may have been on the bus from
//! then on, not before. (Not
//! counted at all, the gap before each SYNC was lost to the master producing it whenever its
//! SYNC, queued at the gap's end, waited behind another frame: with cyclic traffic its bus was
//! not seen idle for a second, and an impostor of a dead member was caught that much late.)
//! Which frames wait is
//! port health's count ([`PortHealth::in_flight`](crate::link::health::PortHealth::in_flight)),
//! which forgets the frames a flush or a re-initialisation discards and no driver confirms (a
//! count kept here held them for ever after a babble: the bus was never seen idle again). When
//! more own frames end than wait here before a received frame passes them (nothing received
//! for a while), the oldest is merged without counting the gap before it.
//!
//! With a driver that does not confirm, each own frame is taken to occupy the bus for `F` from
//! its hand-over, or from the end so reckoned of the one handed over before it (right while its
//! frames are not held back by traffic of higher priority than theirs: the layer's are NMT,
//! SYNC, SDO and process data, above every heartbeat).
//!
//! Memory: a few words per bus, and the ends of up to `OWN` own frames per bus in the table
//! (allocated with the first watch); nothing per frame but a few comparisons.

use super::{Plausibility, NEVER, ON};
use crate::link::health::Health;
use duocan_core::machine::PortStatus;
use duocan_core::Instant;

/// Own frames' ends kept per bus until the received frames pass them: a receive path behind
/// by up to about this many of the layer's own frames (16: some 50 ms of a master's SYNC,
/// heartbeat and SDO traffic at a 10 ms SYNC period, beyond the largest lag a port stays
/// trusted with, 40 ms by default; rule 2 needs the port trusted).
pub(super) const OWN: usize = 16;

/// The ends of a bus's own frames not merged yet (µs, in order).
pub(super) type Ends = heapless::Deque<u64, OWN>;

/// One bus as a whole.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bus {
    /// The end of the latest frame merged, received or own (µs); `NEVER`: none yet.
    seen: u64,
    /// This layer's own frames are off the bus by then, as far as it can tell (µs; a driver
    /// that does not confirm).
    own: u64,
    /// The latest instant the bus is known to have been idle (µs); 0: never.
    pub(super) idle: u64,
}

impl Bus {
    pub(super) const NEW: Bus = Bus {
        seen: NEVER,
        own: 0,
        idle: 0,
    };

    /// The next frame end, at `t`: the bus was idle before it if the gap since the later of
    /// the last end and `busy` (`NEVER`: something may have been on the bus) is longer than
    /// `f`; an own frame that may be on the bus from `until` on (`NEVER`: none) ends the gap
    /// there if that is earlier.
    fn merge(&mut self, t: u64, f: u64, busy: u64, until: u64) {
        if self.seen == NEVER {
            self.seen = t;
            return;
        }
        let (from, end) = (self.seen.max(busy), t.min(until));
        if from != NEVER && end > from.saturating_add(f) {
            self.idle = self.idle.max(end - f);
        }
        self.seen = self.seen.max(t);
    }

    pub(super) fn step_back(&mut self, by: u64, ends: Option<&mut Ends>) {
        if self.seen != NEVER {
            self.seen = self.seen.saturating_sub(by);
        }
        self.own = self.own.saturating_sub(by);
        // A known idle instant stays known (at least 1 µs: 0 is "never").
        if self.idle != 0 {
            self.idle = self.idle.saturating_sub(by).max(1);
        }
        // A loop, not `flat_map`: its iterator adapter costs the bare-metal images flash.
        if let Some(end) = ends {
            for e in end.iter_mut() {
                *e = e.saturating_sub(by);
            }
        }
    }
}

impl Plausibility {
    /// The idle witness is kept: rule 2 is on, with a frame time, for watched nodes (from the
    /// first watch on: what went before is not known).
    #[inline]
    fn idle_on(&self) -> bool {
        ON && self.frame_time != 0 && self.window.is_some() && self.table.is_some()
    }

    /// Any frame arrived on port `p`, stamped `at` (every received frame, before its kind is
    /// known).
    #[inline]
    pub(crate) fn on_frame(&mut self, at: Instant, p: usize, health: &Health) {
        if !self.idle_on() {
            return;
        }
        let (t, f, p) = (at.as_micros().min(NEVER - 1), self.frame_time, p & 1);
        let Some(table) = self.table.as_deref_mut() else {
            return;
        };
        let b = &mut self.buses[p];
        // The own frames that ended before this one, in order.
        let ends = &mut table.ends[p];
        while let Some(c) = ends.front().copied().filter(|c| *c <= t) {
            ends.pop_front();
            b.merge(c, f, 0, NEVER);
        }
        let port = health.port(p);
        let (busy, until) = match (port.in_flight(), port.in_flight_since()) {
            // An own frame waiting for its outcome may have been on the bus since it was
            // handed over: the gap counts up to then.
            (Some(_), Some(h)) => (0, h.as_micros()),
            (Some(_), None) => (0, NEVER),
            (None, _) => (b.own, NEVER),
        };
        b.merge(t, f, busy, until);
    }

    /// This layer handed a frame to port `p` at `now`.
    #[inline]
    pub(crate) fn on_handed(&mut self, now: Instant, p: usize) {
        if self.idle_on() {
            let b = &mut self.buses[p & 1];
            b.own = b.own.max(now.as_micros()).saturating_add(self.frame_time);
        }
    }

    /// The driver of port `p` reported `status` at `now` (port health has counted it): an
    /// own frame's end (a failed attempt used the bus too).
    pub(crate) fn on_status(
        &mut self,
        now: Instant,
        p: usize,
        status: PortStatus,
        health: &Health,
    ) {
        if !self.idle_on() || !matches!(status, PortStatus::TxOk | PortStatus::TxFailed(_)) {
            return;
        }
        let (t, f, p) = (now.as_micros().min(NEVER - 1), self.frame_time, p & 1);
        let b = &mut self.buses[p];
        if health.port(p).in_flight() == Some(0) {
            // Every own frame is off the bus: the last one ended at the latest now.
            b.own = b.own.min(t);
        }
        let Some(table) = self.table.as_deref_mut() else {
            return;
        };
        let ends = &mut table.ends[p];
        if ends.is_full() {
            // Nothing received for a while: the oldest end is merged without its gap.
            if let Some(c) = ends.pop_front() {
                b.merge(c, f, NEVER, NEVER);
            }
        }
        let _ = ends.push_back(t);
    }

    /// The latest instant port `p`'s bus is known to have been idle (rule 2's witness).
    pub fn idle_seen(&self, p: usize) -> Option<Instant> {
        let idle = self.buses[p.min(1)].idle;
        (idle != 0).then(|| Instant::from_micros(idle))
    }
}
