//! One receive PDO: length check, synchronous buffering and reception timeout.
//!
//! - Types 0–240 (synchronous): the last frame received before a SYNC is written into the
//!   dictionary at that SYNC; types 254/255 (asynchronous) are written at once.
//! - A frame shorter than the mapping is refused (EMCY 0x8210, once per error episode, cleared by
//!   the next correct frame). A longer frame is accepted and its extra bytes ignored, as CiA 301
//!   allows; no EMCY 0x8220 is raised for it.
//! - Event timer (sub 5) > 0: deadline monitoring. It starts with the first frame; when no frame
//!   follows within the time, the PDO reports one timeout (EMCY 0x8250) and waits for the next
//!   frame, which clears it.

use super::mapping::Mapping;
use crate::frame::instant::{shift_back, Duration, Instant};
use crate::frame::Id;
use crate::od::abort::AbortCode;

/// Parameters read from 0x14xx/0x16xx.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct RpdoParams {
    pub id: Option<Id>,
    pub ttype: u8,
    pub timeout: Duration,
    pub mapping: Mapping,
    pub error: Option<AbortCode>,
    /// An MPDO (mapping count 0xFE or 0xFF): it receives multiplexed frames, not its mapping.
    #[cfg(feature = "mpdo")]
    pub mpdo: Option<crate::cia301::mpdo::Mode>,
}

impl RpdoParams {
    /// Valid COB-ID, usable mapping with at least one entry.
    #[cfg(not(feature = "mpdo"))]
    pub fn active(&self) -> bool {
        self.id.is_some() && self.error.is_none() && self.mapping.count() > 0
    }
    /// Valid COB-ID, usable mapping with at least one entry, or an MPDO. (Two versions so that
    /// an image without the feature is built as it was.)
    #[cfg(feature = "mpdo")]
    pub fn active(&self) -> bool {
        self.id.is_some() && self.error.is_none() && (self.mapping.count() > 0 || self.is_mpdo())
    }
    /// An MPDO receiver.
    #[cfg(feature = "mpdo")]
    pub fn is_mpdo(&self) -> bool {
        self.mpdo.is_some()
    }
    pub fn synchronous(&self) -> bool {
        self.ttype <= 240
    }
}

/// What a received frame means for the PDO.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum OnFrame {
    /// Not running: ignored.
    Ignore,
    /// Shorter than the mapping. `first` when this starts an error episode.
    TooShort { expected: u8, got: u8, first: bool },
    /// Write into the dictionary now.
    Apply,
    /// Kept for the next SYNC.
    Buffered,
}

/// An RPDO: parameters and run-time state.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Rpdo {
    pub p: RpdoParams,
    running: bool,
    pub buffered: Option<[u8; 8]>,
    deadline: Option<Instant>,
    last_rx: Option<Instant>,
    timed_out: bool,
    short: bool,
    pub received: u32,
}

/// Error episodes that ended with a correct frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Recovered {
    pub length: bool,
    pub timeout: bool,
}

impl Rpdo {
    #[must_use]
    pub const fn new() -> Rpdo {
        Rpdo {
            p: RpdoParams {
                id: None,
                ttype: 255,
                timeout: Duration::ZERO,
                mapping: Mapping::EMPTY,
                error: None,
                #[cfg(feature = "mpdo")]
                mpdo: None,
            },
            running: false,
            buffered: None,
            deadline: None,
            last_rx: None,
            timed_out: false,
            short: false,
            received: 0,
        }
    }

    pub fn running(&self) -> bool {
        self.running
    }
    pub fn last_rx(&self) -> Option<Instant> {
        self.last_rx
    }
    pub fn timed_out(&self) -> bool {
        self.timed_out
    }
    pub fn length_error(&self) -> bool {
        self.short
    }

    /// Starts accepting frames. Monitoring waits for the first one.
    pub fn start(&mut self) {
        self.running = self.p.active();
        self.buffered = None;
        self.deadline = None;
    }

    /// Stops; returns which error episodes were open (their EMCYs must be cleared).
    pub fn stop(&mut self) -> Recovered {
        let open = Recovered {
            length: self.short,
            timeout: self.timed_out,
        };
        self.running = false;
        self.buffered = None;
        self.deadline = None;
        self.timed_out = false;
        self.short = false;
        open
    }

    /// A frame with `data` arrived at `now`.
    pub fn frame(&mut self, now: Instant, data: &[u8], rec: &mut Recovered) -> OnFrame {
        if !self.running {
            return OnFrame::Ignore;
        }
        let expected = self.p.mapping.bytes();
        if data.len() < expected as usize {
            let first = !self.short;
            self.short = true;
            return OnFrame::TooShort {
                expected,
                got: data.len() as u8,
                first,
            };
        }
        rec.length = core::mem::take(&mut self.short);
        rec.timeout = core::mem::take(&mut self.timed_out);
        self.received = self.received.wrapping_add(1);
        self.last_rx = Some(now);
        if !self.p.timeout.is_zero() {
            self.deadline = Some(now + self.p.timeout);
        }
        if self.p.synchronous() {
            // The first 8 bytes: all of a classic frame; the engine keeps a longer CAN FD
            // payload itself (feature `fd`).
            let mut b = [0u8; 8];
            for (d, s) in b.iter_mut().zip(data) {
                *d = *s;
            }
            self.buffered = Some(b);
            OnFrame::Buffered
        } else {
            OnFrame::Apply
        }
    }

    /// The reception timeout, if it expired at or before `now`: reports the last reception.
    pub fn due(&mut self, now: Instant) -> Option<Instant> {
        match self.deadline {
            Some(t) if t <= now => {
                self.deadline = None;
                self.timed_out = true;
                self.last_rx
            }
            _ => None,
        }
    }

    /// The caller's clock stepped back `by` (the clock contract, [`crate::frame::instant`]).
    pub fn step_back(&mut self, by: Duration) {
        shift_back(&mut self.last_rx, by);
        shift_back(&mut self.deadline, by);
    }

    pub fn deadline(&self) -> Option<Instant> {
        self.deadline
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cia301::pdo::mapping::MapEntry;

    fn rpdo(ttype: u8, timeout_ms: u64) -> Rpdo {
        let mut r = Rpdo::new();
        r.p = RpdoParams {
            id: Some(Id::Standard(0x201)),
            ttype,
            timeout: Duration::from_millis(timeout_ms),
            mapping: Mapping::with(&[MapEntry::new(0x2000, 0, 16)]),
            error: None,
            #[cfg(feature = "mpdo")]
            mpdo: None,
        };
        r.start();
        r
    }

    #[test]
    fn short_frames_open_one_episode_and_a_good_frame_closes_it() {
        let mut r = rpdo(255, 0);
        let mut rec = Recovered::default();
        let t = Instant::ZERO;
        assert_eq!(
            r.frame(t, &[1], &mut rec),
            OnFrame::TooShort {
                expected: 2,
                got: 1,
                first: true
            }
        );
        assert!(matches!(
            r.frame(t, &[], &mut rec),
            OnFrame::TooShort { first: false, .. }
        ));
        assert_eq!(r.frame(t, &[1, 2, 3], &mut rec), OnFrame::Apply);
        assert!(rec.length);
    }

    #[test]
    fn synchronous_frames_are_buffered() {
        let mut r = rpdo(1, 0);
        let mut rec = Recovered::default();
        assert_eq!(r.frame(Instant::ZERO, &[1, 2], &mut rec), OnFrame::Buffered);
        assert_eq!(r.buffered, Some([1, 2, 0, 0, 0, 0, 0, 0]));
    }

    #[test]
    fn timeout_monitoring_starts_with_the_first_frame() {
        let ms = Instant::from_millis;
        let mut r = rpdo(255, 100);
        let mut rec = Recovered::default();
        assert_eq!(r.deadline(), None);
        r.frame(ms(5), &[0, 0], &mut rec);
        assert_eq!(r.deadline(), Some(ms(105)));
        assert_eq!(r.due(ms(104)), None);
        assert_eq!(r.due(ms(105)), Some(ms(5)));
        assert_eq!(r.deadline(), None, "one timeout per loss");
        r.frame(ms(200), &[0, 0], &mut rec);
        assert!(rec.timeout);
        assert!(!r.timed_out());
    }
}
