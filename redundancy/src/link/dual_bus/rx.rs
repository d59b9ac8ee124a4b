//! The receive path into the merger: trusted, untrusted and lagging ports, and what the lag
//! meter changes.

use super::DualBus;
use crate::link::classify::FrameClassifier;
use crate::link::health::{PortState, RxOutcome};
use crate::link::merge::{Twin, Verdict};
use duocan::{Frame, Instant};

impl<C: FrameClassifier, const SLOTS: usize, const FUNCTIONS: usize> DualBus<C, SLOTS, FUNCTIONS> {
    /// A frame for the merger: through it on a trusted port, only as a twin on an untrusted
    /// one, and on a port lagging beyond the maximum only as a twin unless the other port is
    /// silent (see [`crate::link::lag`]).
    #[inline]
    pub(super) fn merge(&mut self, now: Instant, port: usize, frame: &Frame) -> RxOutcome {
        if port < 2
            && self.lag.withdrawable(1 - port)
            && self.lag.contradicted(now, port, frame, &mut self.out)
        {
            self.follow_lag(now);
        }
        if self.lag.distrusted(port) && self.health.port(1 - port).state().is_trusted() {
            return self.merge_distrusted(now, port, frame);
        }
        if self.health.trusted(port) {
            let (verdict, twin) = self.merger.arrive_measured(now, port, frame);
            if let Some(twin) = twin {
                self.measured(now, port, twin, frame);
            }
            match (verdict, twin) {
                (Verdict::Duplicate, _) => RxOutcome::Duplicate,
                (Verdict::Deliver, Some(_)) => RxOutcome::Slipped,
                (Verdict::Deliver, None) => RxOutcome::Delivered,
            }
        } else if self.merger.match_only(now, port, frame) {
            RxOutcome::Duplicate
        } else {
            RxOutcome::Untrusted
        }
    }

    /// A frame on a port lagging beyond the maximum while the other port works.
    #[cold]
    fn merge_distrusted(&mut self, now: Instant, port: usize, frame: &Frame) -> RxOutcome {
        if let Some(twin) = self.merger.match_measured(now, port, frame) {
            self.measured(now, port, twin, frame);
            return RxOutcome::Duplicate;
        }
        let other_last_rx = self.health.port(1 - port).counters().last_rx;
        if self.lag.other_silent(now, port, other_last_rx) {
            // Not recorded: the other port, silent, has no copy to come.
            return RxOutcome::Delivered;
        }
        RxOutcome::Untrusted
    }

    /// Copies of a port are kept as late records only while the other port can deliver their
    /// twins late: it is ok, or suspect only for its lag. Failed, recovering, or suspect for a
    /// fault (its transmissions fail, its controller reports errors), it is cut off, not slow:
    /// the copies it misses are lost, and when it is back, its first copies of unchanged
    /// repeats must not be taken for late twins of the ones it missed (a lag it does not have,
    /// distrusting it just when the other port may fail next).
    #[inline]
    pub(super) fn keep_late(&mut self, now: Instant) {
        if self.health.changes() == self.health_seen {
            return;
        }
        self.health_seen = self.health.changes();
        for p in 0..2 {
            let other = self.health.port(1 - p);
            let keep = match other.state() {
                PortState::Ok => true,
                PortState::Suspect => other.lagging().is_some(),
                PortState::Failed | PortState::Recovering => false,
            };
            if keep != self.merger.keeps_late(p) {
                self.merger.keep_late(p, keep, now);
            }
        }
    }

    /// A twin matched for `port`: a lag sample.
    #[inline]
    fn measured(&mut self, now: Instant, port: usize, twin: Twin, frame: &Frame) {
        if let Some(lag) = twin.lag {
            if self.lag.sample_frame(now, port, lag, frame, &mut self.out) {
                self.follow_lag(now);
            }
        }
    }

    /// The lag meter changed a window or a distrust: the merger, port health and the ports'
    /// states follow.
    pub(super) fn follow_lag(&mut self, at: Instant) {
        let window = self.lag.window();
        self.merger.set_window(window);
        self.health.set_window(window);
        self.reach.set_settle(window);
        for p in 0..2 {
            // A port known to lag matches the other port's late copies: its twins. What it
            // delivered before as first copies were twins too: forgotten, so that no later
            // repeat on the other port is taken for their twin.
            let lagging = self.lag.lagging(p);
            if lagging && !self.merger.late_match(p) {
                self.merger.forget(p);
            }
            self.merger.set_late_match(p, lagging);
            let (lag, beyond) = (self.lag.lag(p), self.lag.distrusted(p));
            self.health.set_lagging(at, p, lag, beyond, &mut self.out);
        }
    }
}
