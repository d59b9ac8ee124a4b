//! The receive path into the merger: stamps corrected by the measured lag, trusted and
//! unproven ports, and what the lag meter changes; or into the sticky merge, if configured.

use super::DualBus;
use crate::link::capacity::{FunctionStorage, MergeCapacity, MergerStorage};
use crate::link::channel::{ChannelPolicy, RxRoute};
use crate::link::classify::FrameClassifier;
use crate::link::health::RxOutcome;
use crate::link::merge::{Sample, Trust, Verdict};
use crate::link::same_function::PairVerdict;
#[cfg(feature = "sticky")]
use crate::link::sticky::{StickyVerdict, StreamKey};
use duocan_core::{Frame, Instant};

/// The copy of the late sample the lag meter holds, on `port`: stamped more than the window
/// after its supposed twin on the other port; its own twin would be stamped before `until`
/// (µs; the copy is fresh: no earlier one of its content is about) ([`DualBus::settle_late`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct LateSample {
    port: u8,
    until: u64,
    frame: Frame,
}

impl LateSample {
    /// Whether a copy on `port` stamped `s`, not of this sample's frame, settles it: of the
    /// other port and stamped past where its own twin would be (the sample stands).
    #[cfg(feature = "fd")]
    pub(super) fn stands_after(&self, port: usize, s: Instant) -> bool {
        self.port as usize != port && s.as_micros() >= self.until
    }

    /// The caller's clock stepped back `by`.
    pub(super) fn step_back(&mut self, by: duocan_core::Duration) {
        self.until = self.until.saturating_sub(by.as_micros());
    }
}

impl<C: FrameClassifier, K: MergeCapacity> DualBus<C, K> {
    /// The start of both receive paths (classic and FD): the clock watched, `port` checked
    /// (false: no such port, counted) and whether it stamps noted.
    #[inline(always)]
    pub(super) fn rx_begins(&mut self, now: Instant, port: usize, stamped: bool) -> bool {
        self.watch_clock(now);
        if port > 1 {
            self.stats.bad_port += 1;
            return false;
        }
        if self.stamped[port] != stamped {
            self.stamped[port] = stamped;
            self.merger.set_stamped(port, stamped);
        }
        true
    }

    /// The route's `outcome` told to port health; true if the frame goes on up.
    #[inline(always)]
    pub(super) fn settled(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        outcome: RxOutcome,
    ) -> bool {
        self.health.rx_delay(port, now.saturating_since(at));
        self.health.on_rx(now, at, port, outcome, &mut self.out);
        matches!(
            outcome,
            RxOutcome::Delivered | RxOutcome::Direct | RxOutcome::Slipped
        )
    }

    /// Whether `frame` (for an FD frame, its classic stand-in) is a slave pair's standby
    /// member's process data, held back (counted) while the active member's goes up.
    #[inline(always)]
    pub(super) fn held_as_standby(&mut self, now: Instant, frame: &Frame) -> bool {
        if self.pairs.is_empty() {
            return false;
        }
        let Some((node, function)) = self.classifier.function(frame) else {
            return false;
        };
        let classifier = &self.classifier;
        let standby = self
            .pairs
            .on_frame_by(now, node, function, frame, &mut self.out, |a, b| {
                classifier.same_value(a, b)
            })
            == PairVerdict::Standby;
        if standby {
            self.stats.standby += 1;
        }
        standby
    }

    /// A frame from `port` stamped `at` (`stamped`: a receive timestamp; otherwise the time
    /// it was handed over), handled at `now`: the layer's receive path.
    pub(super) fn rx(
        &mut self,
        now: Instant,
        port: usize,
        frame: &Frame,
        at: Instant,
        stamped: bool,
    ) -> Option<Frame> {
        if !self.rx_begins(now, port, stamped) {
            return None;
        }
        // When the frame was on the bus: what heartbeat rates and the merger judge by (a
        // reader that ran late changes neither). Reachability and port health judge silence by
        // when frames reach this node, so that a port whose reader runs behind is not silent.
        let at = at.min(now);
        if self.reach_enabled {
            if let Some(n) = self.classifier.sender(frame) {
                self.reach.on_heard(now, n, port, &mut self.out);
            }
        }
        let info = self.info(frame);
        // Every frame: when each bus was idle (rule 2's witness).
        self.plausible.on_frame(at, port, &self.health);
        // A watched node reset, or its producer time downloaded and confirmed, by another
        // station.
        #[cfg(feature = "alloc")]
        self.plausible.on_command(frame);
        if let Some(n) = info.heartbeat.filter(|_| !self.plausible.is_empty()) {
            // A bus carrying this node's heartbeats far too fast: neither the policy, the
            // merger nor the stack above sees them.
            if self
                .plausible
                .on_heartbeat(at, port, n, frame, &self.health, &mut self.out)
            {
                self.stats.implausible += 1;
                self.health
                    .on_rx(now, at, port, RxOutcome::Ignored, &mut self.out);
                return None;
            }
        }
        let route = self.policy.on_rx(now, port, frame, &info, &mut self.out);
        self.show_status();
        let outcome = match route {
            RxRoute::Ignore => RxOutcome::Ignored,
            RxRoute::Direct => RxOutcome::Direct,
            #[cfg(feature = "sticky")]
            RxRoute::Merge if self.sticky.is_some() => self.stick(now, at, port, frame),
            RxRoute::Merge => self.merge(now, at, port, frame),
        };
        if !self.settled(now, at, port, outcome) {
            return None;
        }
        if let Some(n) = info.heartbeat.filter(|_| !self.plausible.is_empty()) {
            // A heartbeat older than one already handed up: a state the node has left.
            let s = self.lag.correct(port, at);
            let boot = frame.data().first() == Some(&0);
            let margin = self.merger.window();
            if !self.plausible.current(n, s, boot, margin) {
                self.stats.superseded += 1;
                return None;
            }
        }
        if self.held_as_standby(now, frame) {
            return None;
        }
        self.stats.delivered += 1;
        Some(*frame)
    }

    /// A frame stamped `at` on `port`, handled at `now`, through the merger: a port failed or
    /// recovering while the other one works is not proven yet (see
    /// [`crate::link::merge`]).
    #[inline]
    pub(super) fn merge(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &Frame,
    ) -> RxOutcome {
        let s = self.lag.correct(port, at);
        let trust = self.trust(port);
        let (verdict, sample) = self.merger.arrive_at(now, s, port, frame, trust);
        let sample = sample.filter(|m| !m.late || self.intact_between(port, s, m));
        if self.late.is_some() {
            self.settle_late(port, s, frame);
        }
        if let Some(m) = sample {
            // Stamped a window or more before its twin, which was stamped within half the
            // window before this copy came: the two came together, a receive clock is off
            // (see `link::lag`), and the sample is not one that may only shrink a correction.
            // Not a whole window: a twin late on its wire (retransmissions) beside a copy
            // whose reader runs behind by about as much also comes together with it (seed
            // 109: 8.3 ms against 13 ms, 4.7 ms apart, taken for a clock 8.9 ms off).
            let ahead = now.as_micros() as i64 - s.as_micros() as i64 + m.skew;
            // Doubled rather than the window halved: a 64-bit division brings its routine
            // (1 KB) into a 32-bit image.
            let window = self.merger.window().as_micros() as i64;
            let together = m.late && m.skew < 0 && ahead.saturating_mul(2) < window;
            let m = Sample {
                late: m.late && !together,
                ..m
            };
            let before = [self.lag.lag(0), self.lag.lag(1)];
            if self.lag.sample(now, port, m, &mut self.out) {
                for (p, was) in before.into_iter().enumerate() {
                    let by = self.lag.lag(p).as_micros() as i64 - was.as_micros() as i64;
                    self.merger.shift(p, by);
                }
                self.follow_lag(now);
            } else if m.late && m.skew > 0 {
                // Held, later than its supposed twin by more than the window: withdrawn if
                // its own twin comes within the window after all (below).
                let until = s.as_micros().saturating_add(self.lag.window().as_micros());
                self.late = Some(LateSample {
                    port: port as u8,
                    until,
                    frame: *frame,
                });
            }
        }
        match verdict {
            Verdict::Deliver if sample.is_some_and(|s| s.late) => RxOutcome::Slipped,
            Verdict::Deliver => RxOutcome::Delivered,
            Verdict::Duplicate => RxOutcome::Duplicate,
            Verdict::Late | Verdict::Unproven => RxOutcome::Stale,
        }
    }

    /// A copy `frame` on `port` stamped `s`: it settles the late sample the lag meter holds,
    /// if any. This copy is, on the other port and within the window, that sample's copy's own
    /// twin: the copy it was paired with was an earlier occurrence the other bus missed (its
    /// sender repeated it: an SDO request and its answer after a flap did so 5 ms later, two
    /// samples that agreed on a lag that was none). The sample is withdrawn. Once the other
    /// port's copies are stamped a window past it, it stands.
    #[cold]
    #[inline(never)]
    fn settle_late(&mut self, port: usize, s: Instant, frame: &Frame) {
        let Some(l) = self.late.filter(|l| l.port as usize != port) else {
            return;
        };
        if s.as_micros() < l.until {
            if *frame != l.frame {
                return;
            }
            self.lag.withdraw();
        }
        self.late = None;
    }

    /// Whether the merge may take a first copy from `port`: not while it is failed or
    /// recovering and the other port works (see [`crate::link::merge`]).
    #[inline]
    pub(super) fn trust(&self, port: usize) -> Trust {
        if self.health.trusted(port) {
            Trust::Trusted
        } else {
            Trust::Unproven
        }
    }

    /// A frame stamped `at` on `port`, handled at `now`, through the sticky merge: its stream
    /// is its sender's, or its identifier's (see [`crate::link::sticky`]). Stamps are taken as
    /// they come: the sticky merge stands any lag below its timeout, and measures none.
    #[cfg(feature = "sticky")]
    #[inline]
    pub(super) fn stick(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &Frame,
    ) -> RxOutcome {
        let key = StreamKey::of(frame, self.classifier.sender(frame));
        let trust = self.trust(port);
        let other_failed =
            self.health.port(1 - port).state() == crate::link::health::PortState::Failed;
        let Some(sticky) = self.sticky.as_mut() else {
            return RxOutcome::Ignored;
        };
        sticky.set_failed(1 - port, other_failed);
        match sticky.arrive_at(now, at, port, key, trust) {
            StickyVerdict::Deliver | StickyVerdict::Switched => RxOutcome::Delivered,
            // The other bus's copy: as a twin is for the exact merge (the port is not silent).
            StickyVerdict::Dropped => RxOutcome::Duplicate,
            StickyVerdict::Unproven => RxOutcome::Stale,
        }
    }

    /// Whether a late sample of a copy stamped `s` on `port` can be a lag: the port of the
    /// later of the two copies was intact from the earlier one's stamp on (see
    /// [`crate::link::lag`]). If that port came back since from a state in which frames may
    /// not have reached it, it may have lost the earlier occurrence, and its copy be a later
    /// one of the same content.
    pub(super) fn intact_between(&self, port: usize, s: Instant, m: &Sample) -> bool {
        let (later, earlier) = if m.skew > 0 {
            (port, s.as_micros().saturating_sub(m.skew as u64))
        } else {
            (1 - port, s.as_micros())
        };
        // Without receive timestamps a port whose copies come late looks silent until its lag
        // is measured: its silence is that lag, not frames lost.
        self.health
            .port(later)
            .intact_since(self.stamped[later])
            .is_some_and(|t| t.as_micros() <= earlier)
    }

    /// The lag meter changed its correction: port health, reachability and the ports' states
    /// follow (the merger gets corrected stamps and keeps its window).
    pub(super) fn follow_lag(&mut self, at: Instant) {
        let window = self.lag.window();
        self.health.set_window(window);
        self.reach.set_settle(window);
        for p in 0..2 {
            let (lag, beyond) = (self.lag.lag(p), self.lag.beyond(p));
            self.health.set_lagging(at, p, lag, beyond, &mut self.out);
        }
    }
}
