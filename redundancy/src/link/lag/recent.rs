//! The samples of the last half skew window, with their frames: what a copy on the other port
//! can still show to be no lag at all (see "Unchanged repeats" in [`crate::link::lag`]).
//!
//! A port keeps its [`RECENT`] newest; a newer sample takes the slot of the oldest, which can
//! then no longer be withdrawn (it stays kept, as every sample did before it had a chance).

use duocan::Frame;

/// Samples remembered per port: the frames of one bus that can arrive within half a skew
/// window at its first copies after an outage (a cycle of a few cyclic frames).
pub const RECENT: usize = 4;

/// One kept sample: the frame whose twin showed it, when, and its tag among the port's samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Recent {
    pub frame: Frame,
    pub at: u64,
    pub tag: u32,
}

/// A port's recent samples: fixed slots, the unused ones `None`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(super) struct RecentSamples {
    slots: [Option<Recent>; RECENT],
}

impl RecentSamples {
    /// True while any sample is held (the caller prunes them by age).
    #[inline]
    pub fn any(&self) -> bool {
        self.slots.iter().any(Option::is_some)
    }

    /// Keeps `r`, in a free slot or in place of the oldest.
    pub fn push(&mut self, r: Recent) {
        let slot = match self.slots.iter().position(Option::is_none) {
            Some(i) => i,
            None => (0..RECENT)
                .min_by_key(|&i| self.slots[i].map_or(0, |s| s.at))
                .unwrap_or(0),
        };
        self.slots[slot] = Some(r);
    }

    /// Forgets samples taken `max_age` µs or more before `now`; then takes out and returns the
    /// newest one of `frame`, if any is left.
    pub fn take(&mut self, now: u64, max_age: u64, frame: &Frame) -> Option<Recent> {
        let mut found: Option<usize> = None;
        for i in 0..RECENT {
            let Some(r) = self.slots[i] else { continue };
            if now.saturating_sub(r.at) >= max_age {
                self.slots[i] = None;
            } else if r.frame == *frame && found.is_none_or(|j| self.at(j) <= r.at) {
                found = Some(i);
            }
        }
        found.and_then(|i| self.slots[i].take())
    }

    fn at(&self, i: usize) -> u64 {
        self.slots[i].map_or(0, |r| r.at)
    }

    /// The clock stepped back `by` µs.
    pub fn step_back(&mut self, by: u64) {
        for r in self.slots.iter_mut().flatten() {
            r.at = r.at.saturating_sub(by);
        }
    }
}
