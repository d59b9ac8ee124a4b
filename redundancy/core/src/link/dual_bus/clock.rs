//! The layer's clock contract (see [`crate::link`]): one watch for all its parts.

use super::DualBus;
use crate::link::capacity::{FunctionStorage, MergeCapacity, MergerStorage};
use crate::link::channel::ChannelPolicy;
use crate::link::classify::FrameClassifier;
use duocan_core::{Duration, Instant};

impl<C: FrameClassifier, K: MergeCapacity> DualBus<C, K> {
    /// Every input that carries a time passes it here first: one comparison on the frame path.
    #[inline]
    pub(super) fn watch_clock(&mut self, now: Instant) {
        if let Some(by) = self.clock.step_back(now) {
            self.step_back(by);
        }
    }

    /// The caller's clock stepped back `by`: every part moves the times it holds back with it.
    #[cold]
    #[inline(never)]
    fn step_back(&mut self, by: Duration) {
        self.policy.step_back(by);
        self.merger.step_back(by);
        #[cfg(feature = "sticky")]
        if let Some(s) = &mut self.sticky {
            s.step_back(by);
        }
        self.lag.step_back(by);
        if let Some(l) = &mut self.late {
            l.step_back(by);
        }
        self.health.step_back(by);
        self.reach.step_back(by);
        self.plausible.step_back(by);
        self.pairs.step_back(by);
    }
}
