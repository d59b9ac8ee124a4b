//! The random and counted faults of one bus or one member, decided frame by frame, and what
//! they did.

use crate::frame::instant::Duration;
use crate::frame::Frame;
use crate::sim::{chance, either, flip_bit, FaultRates};

/// What happened to frames at one member (or, for bus-wide faults, on one bus). Every frame a
/// member was to receive and did not is in exactly one of the drop counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct MemberCounters {
    /// Frames received from the member's interface.
    pub rx: u64,
    /// Frames sent to the member's interface.
    pub tx: u64,
    /// Not delivered: the bus or the member was cut.
    pub cut: u64,
    /// Not delivered: sender and receiver in different partition groups.
    pub partitioned: u64,
    /// Not delivered: dropped (by rate or every n-th).
    pub dropped: u64,
    /// Not delivered: corrupted in a way the receiver's CRC catches (dropped as a controller
    /// drops it).
    pub corrupted: u64,
    /// Delivered with one data bit flipped (an undetected corruption).
    pub flipped: u64,
    /// Delivered twice.
    pub duplicated: u64,
    /// Delivered late by a random delay.
    pub delayed: u64,
    /// Frames the member babbled (sent to its bus on its behalf).
    pub babbled: u64,
    /// Not delivered: the member's queue was full. The only drop nobody asked for.
    pub overflow: u64,
    /// Frames the interface could not send (reported by its driver).
    pub tx_failed: u64,
    /// Times the interface went down.
    pub port_down: u64,
}

/// The faults of one bus or member.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Odds {
    pub rates: FaultRates,
    /// Drop every n-th frame (0: none).
    pub every: u32,
    pub count: u32,
}

/// What a frame becomes.
pub(super) struct Fate {
    pub frame: Frame,
    pub delay: Duration,
    pub twice: bool,
}

impl Odds {
    /// Counts a frame against the every-n-th drop; true when this one is the n-th.
    fn nth(&mut self) -> bool {
        if self.every == 0 {
            return false;
        }
        self.count += 1;
        if self.count >= self.every {
            self.count = 0;
            true
        } else {
            false
        }
    }

    /// The bus-wide part of the faults, decided once per frame for every receiver: every n-th
    /// frame lost, and corruption (an error frame destroys a frame for everyone; an undetected
    /// flip reaches everyone the same). `None` when the frame is lost (counted in `c`).
    pub fn decide_bus(
        &mut self,
        rng: &mut fastrand::Rng,
        frame: &Frame,
        c: &mut MemberCounters,
    ) -> Option<Frame> {
        if self.nth() {
            c.dropped += 1;
            return None;
        }
        let r = &self.rates;
        if chance(rng, r.corrupt_detected) {
            c.corrupted += 1;
            return None;
        }
        if chance(rng, r.corrupt_undetected) {
            if let Some(f) = flip_bit(rng, frame) {
                c.flipped += 1;
                return Some(f);
            }
        }
        Some(*frame)
    }

    /// The fate of `frame` at one receiver: its own every-n-th and corruption, and drop,
    /// duplicate and delay at the bus's and its own rates combined as independent chances (as
    /// the simulator combines them). `None` when the frame is lost (counted in `c`).
    pub fn decide_port(
        &mut self,
        rng: &mut fastrand::Rng,
        frame: &Frame,
        bus: &FaultRates,
        c: &mut MemberCounters,
    ) -> Option<Fate> {
        let mut fate = Fate {
            frame: *frame,
            delay: Duration::ZERO,
            twice: false,
        };
        if self.nth() {
            c.dropped += 1;
            return None;
        }
        let r = &self.rates;
        if r.is_none() && bus.is_none() {
            return Some(fate);
        }
        if chance(rng, either(bus.drop, r.drop)) {
            c.dropped += 1;
            return None;
        }
        if chance(rng, r.corrupt_detected) {
            c.corrupted += 1;
            return None;
        }
        if chance(rng, r.corrupt_undetected) {
            if let Some(f) = flip_bit(rng, frame) {
                fate.frame = f;
                c.flipped += 1;
            }
        }
        if chance(rng, either(bus.duplicate, r.duplicate)) {
            fate.twice = true;
            c.duplicated += 1;
        }
        if chance(rng, either(bus.delay, r.delay)) {
            let max = bus.max_delay.max(r.max_delay).as_micros().max(1);
            fate.delay = Duration::from_micros(rng.u64(1..=max));
            c.delayed += 1;
        }
        Some(fate)
    }
}
