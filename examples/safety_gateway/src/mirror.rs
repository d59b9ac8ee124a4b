//! Track-circuit mirrors: what the field board sent as its safety data (a CiA 304 SRDO),
//! checked, with the safe side taken on anything doubtful.
//!
//! The track-circuit board (node [`FIELD_NODE`](crate::FIELD_NODE) of the field bus) sends its
//! [`TRACKS`] track circuits as one SRDO: their codes (0x55 clear, 0xAA occupied) plain on
//! [`FIELD_NORMAL`] and bitwise inverted on
//! [`FIELD_INVERTED`], byte *k* − 1 for track circuit *k*, every cycle.
//! The gateway consumes it with duocan's [`SrdoConsumer`]: the SCT is the field timeout (0x2001),
//! the SRVT [`FIELD_SRVT`](crate::FIELD_SRVT). Then:
//!
//! - an intact pair (the inverse within SRVT, in time) sets each mirror from its code;
//! - a code that is neither (stuck-at 0x00/0xFF, a flipped bit the producer inverted faithfully)
//!   makes that track circuit occupied;
//! - any violation of the SRDO rules (no pair within SCT: the board or its bus died; a half pair
//!   without the other within SRVT; halves that are not each other's inverse: a corrupted frame;
//!   a short frame; a changed half) makes **every** track circuit occupied, at the instant of
//!   the violation: the consumer's safe state.
//!
//! CiA 304 leaves the way out of the safe state to the application. The gateway's rule: it
//! acknowledges the consumer at once, so that checking starts again with the SCT from that
//! instant, and the mirrors stay occupied until the next intact pair: the field board's
//! cyclic pairs are the proof. Frames on other identifiers (the board's heartbeat, other
//! nodes) are not the SRDO's and are ignored.
//!
//! Memory: four mirrors and one consumer (its held half pair), fixed.

use crate::{FIELD_INVERTED, FIELD_NORMAL, TRACKS};
use duocan::cia304::srdo::consumer::{ConsumerStep, SrdoCause, SrdoConsumer, SrdoFault};
use duocan::profile::railway::safety::{SafetyCode, SafetyError, TrackCircuit};
use duocan::{Duration, Frame, Instant};

/// Why a mirror holds its state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cause {
    /// Nothing reported since power-on: occupied.
    NoReport,
    /// The field board reported it in an intact pair.
    Report,
    /// The field board's SRDO broke a rule (no pair in time, corrupted, …): occupied.
    Srdo {
        /// Which rule.
        cause: SrdoCause,
        /// The time measured (see [`SrdoFault::measured`]).
        measured: Duration,
    },
    /// The code in an intact pair is not a track-circuit code: occupied.
    InvalidCode(SafetyError),
}

/// A mirror changed state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TrackChange {
    /// When.
    pub at: Instant,
    /// Track circuit (1-based, the sub-index on both sides).
    pub track: u8,
    /// State before.
    pub from: TrackCircuit,
    /// State now.
    pub to: TrackCircuit,
    /// Why.
    pub cause: Cause,
}

/// What one field frame (or one instant) was.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Not the field SRDO's (the board's heartbeat, another node): ignored.
    Foreign,
    /// Nothing decided: half a pair held, or a copy of a half.
    Held,
    /// An intact pair; `invalid` of its codes were not track-circuit codes.
    Pair {
        /// Codes that were neither clear nor occupied.
        invalid: u8,
    },
    /// The SRDO broke a rule: every track circuit occupied.
    Trip(SrdoFault),
}

#[derive(Clone, Copy, Debug)]
struct Mirror {
    state: TrackCircuit,
    cause: Cause,
}

/// Changes one field frame (or one instant) can cause: at most one per track circuit.
pub type Changes = heapless::Vec<TrackChange, { TRACKS as usize }>;

/// The mirrors of the gateway's track circuits and the consumer of the field SRDO.
#[derive(Clone, Debug)]
pub struct Tracks {
    mirrors: [Mirror; TRACKS as usize],
    consumer: SrdoConsumer,
    sct: Duration,
    srvt: Duration,
}

impl Tracks {
    /// Every track circuit occupied, nothing reported; the consumer checks from `now` with
    /// SCT `sct` and SRVT `srvt`.
    #[must_use]
    pub fn new(now: Instant, sct: Duration, srvt: Duration) -> Self {
        let mut t = Tracks {
            mirrors: [Mirror {
                state: TrackCircuit::Occupied,
                cause: Cause::NoReport,
            }; TRACKS as usize],
            consumer: consumer(sct, srvt),
            sct,
            srvt,
        };
        t.consumer.start(now);
        t
    }

    /// State and cause of track circuit `track` (1-based).
    pub fn get(&self, track: u8) -> Option<(TrackCircuit, Cause)> {
        let m = self.mirrors.get(usize::from(track).checked_sub(1)?)?;
        Some((m.state, m.cause))
    }

    /// A field frame at `now`; `sct` is the field timeout in force. It applies from the next
    /// intact pair or trip on (each of them starts the next SCT, so nothing else changes).
    pub fn handle_frame(
        &mut self,
        now: Instant,
        frame: &Frame,
        sct: Duration,
    ) -> (Verdict, Changes) {
        let mut out = Changes::new();
        let verdict = match self.consumer.handle_frame(now, frame) {
            None if self.consumer.accepts(frame.id()) => Verdict::Held,
            None => Verdict::Foreign,
            Some(ConsumerStep::Held) => Verdict::Held,
            Some(ConsumerStep::Deliver(data)) => {
                if sct != self.sct {
                    self.restart(now, sct);
                }
                Verdict::Pair {
                    invalid: self.pair(now, &data, &mut out),
                }
            }
            Some(ConsumerStep::Trip(f)) => {
                self.tripped(now, f, sct, &mut out);
                Verdict::Trip(f)
            }
        };
        (verdict, out)
    }

    /// The deadlines reached by `now` (SRVT of a half pair, SCT): the trip, if one was, and
    /// what it changed. The consumer checks again from `now` with SCT `sct`.
    pub fn handle_timeout(&mut self, now: Instant, sct: Duration) -> (Option<SrdoFault>, Changes) {
        let mut out = Changes::new();
        match self.consumer.handle_timeout(now) {
            Some(ConsumerStep::Trip(f)) => {
                self.tripped(now, f, sct, &mut out);
                (Some(f), out)
            }
            _ => (None, out),
        }
    }

    /// The consumer's next deadline.
    pub fn deadline(&self) -> Option<Instant> {
        self.consumer.poll_timeout()
    }

    /// Sets every mirror from an intact pair; returns how many codes were invalid.
    fn pair(&mut self, now: Instant, data: &[u8; 8], out: &mut Changes) -> u8 {
        let mut invalid = 0;
        for track in 1..=TRACKS {
            let code = data[usize::from(track - 1)];
            let (state, cause) = match TrackCircuit::from_code(code) {
                Ok(state) => (state, Cause::Report),
                Err(e) => {
                    invalid += 1;
                    (TrackCircuit::Occupied, Cause::InvalidCode(e))
                }
            };
            self.set(now, track, state, cause, out);
        }
        invalid
    }

    /// The safe state: every mirror occupied at the fault's instant (a mirror nothing was ever
    /// reported for keeps that cause); then checking starts again (see the module doc).
    fn tripped(&mut self, now: Instant, f: SrdoFault, sct: Duration, out: &mut Changes) {
        let cause = Cause::Srdo {
            cause: f.cause,
            measured: f.measured,
        };
        for track in 1..=TRACKS {
            let unreported = self.get(track).is_some_and(|m| m.1 == Cause::NoReport);
            let c = if unreported { Cause::NoReport } else { cause };
            self.set(f.at, track, TrackCircuit::Occupied, c, out);
        }
        self.restart(now, sct);
    }

    /// Checking from `now` with SCT `sct`.
    fn restart(&mut self, now: Instant, sct: Duration) {
        self.sct = sct;
        self.consumer = consumer(sct, self.srvt);
        self.consumer.start(now);
    }

    fn set(&mut self, at: Instant, track: u8, to: TrackCircuit, cause: Cause, out: &mut Changes) {
        let Some(m) = usize::from(track)
            .checked_sub(1)
            .and_then(|i| self.mirrors.get_mut(i))
        else {
            return;
        };
        let from = m.state;
        *m = Mirror { state: to, cause };
        if from != to {
            // One change per track per call: the capacity is the number of tracks.
            let _ = out.push(TrackChange {
                at,
                track,
                from,
                to,
                cause,
            });
        }
    }
}

fn consumer(sct: Duration, srvt: Duration) -> SrdoConsumer {
    SrdoConsumer::new(FIELD_NORMAL, FIELD_INVERTED, sct, srvt, TRACKS)
}

/// The field board's SRDO for `codes`: the normal frame and its inverse.
#[must_use]
pub fn field_pair(codes: [u8; TRACKS as usize]) -> [Frame; 2] {
    let inverted = codes.map(|c| !c);
    [
        Frame::from_array(duocan::Id::Standard(FIELD_NORMAL), codes),
        Frame::from_array(duocan::Id::Standard(FIELD_INVERTED), inverted),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use duocan::Id;

    const SCT: Duration = Duration::from_millis(300);
    const SRVT: Duration = Duration::from_millis(20);

    fn at(ms: u64) -> Instant {
        Instant::from_millis(ms)
    }

    /// Both halves of a pair at `t`.
    fn send(t: &mut Tracks, now: Instant, codes: [u8; 4]) -> Vec<(Verdict, Changes)> {
        field_pair(codes)
            .iter()
            .map(|f| t.handle_frame(now, f, SCT))
            .collect()
    }

    #[test]
    fn an_intact_pair_sets_the_mirrors_and_a_bad_code_only_its_track() {
        let mut t = Tracks::new(at(0), SCT, SRVT);
        assert_eq!(t.get(1), Some((TrackCircuit::Occupied, Cause::NoReport)));
        let r = send(&mut t, at(10), [0x55, 0x55, 0xAA, 0xFF]);
        assert_eq!(
            r[0].0,
            Verdict::Held,
            "the normal half waits for its inverse"
        );
        assert_eq!(r[1].0, Verdict::Pair { invalid: 1 });
        let changed: Vec<u8> = r[1].1.iter().map(|c| c.track).collect();
        assert_eq!(changed, [1, 2], "3 and 4 stay occupied");
        assert_eq!(t.get(1), Some((TrackCircuit::Clear, Cause::Report)));
        assert_eq!(t.get(3), Some((TrackCircuit::Occupied, Cause::Report)));
        assert!(matches!(
            t.get(4),
            Some((TrackCircuit::Occupied, Cause::InvalidCode(_)))
        ));
        // Other identifiers are not the SRDO's.
        let hb = Frame::from_array(Id::Standard(0x701), [5]);
        assert_eq!(t.handle_frame(at(11), &hb, SCT).0, Verdict::Foreign);
        assert_eq!(t.get(0), None);
        assert_eq!(t.get(TRACKS + 1), None);
    }

    #[test]
    fn a_corrupted_half_makes_every_track_occupied_until_the_next_intact_pair() {
        let mut t = Tracks::new(at(0), SCT, SRVT);
        send(&mut t, at(10), [0x55; 4]);
        let [normal, _] = field_pair([0x55; 4]);
        t.handle_frame(at(40), &normal, SCT);
        // One bit of the inverse flipped on the wire.
        let bad = Frame::from_array(Id::Standard(FIELD_INVERTED), [0xAA, 0xAA, 0xAB, 0xAA]);
        let (v, c) = t.handle_frame(at(40), &bad, SCT);
        assert!(matches!(v, Verdict::Trip(f) if f.cause == SrdoCause::NotInverted));
        assert_eq!(c.len(), 4);
        assert!(c
            .iter()
            .all(|c| c.at == at(40) && c.to == TrackCircuit::Occupied));
        // Checking again at once: the next intact pair restores them.
        let r = send(&mut t, at(110), [0x55; 4]);
        assert_eq!(r[1].1.len(), 4);
        assert_eq!(t.get(2), Some((TrackCircuit::Clear, Cause::Report)));
    }

    #[test]
    fn silence_trips_exactly_sct_after_the_last_pair_and_a_half_pair_srvt_after_it() {
        let mut t = Tracks::new(at(0), SCT, SRVT);
        send(&mut t, at(50), [0x55; 4]);
        assert_eq!(t.deadline(), Some(at(350)));
        assert!(t.handle_timeout(at(349), SCT).0.is_none());
        let (f, c) = t.handle_timeout(at(400), SCT);
        let f = f.unwrap();
        assert_eq!(
            (f.cause, f.at, f.measured),
            (SrdoCause::CycleTime, at(350), SCT)
        );
        assert!(c.iter().all(|c| c.at == at(350)));
        let cause = Cause::Srdo {
            cause: SrdoCause::CycleTime,
            measured: SCT,
        };
        assert_eq!(t.get(1), Some((TrackCircuit::Occupied, cause)));
        // Checking again from 400 ms. A normal half alone: SRVT later, every track occupied.
        send(&mut t, at(450), [0x55; 4]);
        let [normal, _] = field_pair([0xAA; 4]);
        t.handle_frame(at(500), &normal, SCT);
        assert_eq!(t.deadline(), Some(at(520)));
        let (f, c) = t.handle_timeout(at(520), SCT);
        assert_eq!(f.map(|f| f.cause), Some(SrdoCause::Validation));
        assert_eq!(c.len(), 4, "the half pair's data was never used");
    }

    #[test]
    fn a_track_never_reported_keeps_its_cause_through_a_trip() {
        let mut t = Tracks::new(at(0), SCT, SRVT);
        let (f, c) = t.handle_timeout(at(300), SCT);
        assert_eq!(f.map(|f| f.at), Some(at(300)));
        assert!(c.is_empty(), "occupied already");
        assert_eq!(t.get(1), Some((TrackCircuit::Occupied, Cause::NoReport)));
    }
}
