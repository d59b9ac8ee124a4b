//! Track-circuit mirrors: what the field board reported, checked, with the safe side taken on
//! anything doubtful.
//!
//! A report counts only if it comes from the field board's track-circuit port under the right
//! identifier, passes the railway CRC (which covers the identifier), names a track circuit the
//! gateway has, and carries one of the asymmetric codes (0x55 clear, 0xAA occupied). Then:
//!
//! - a valid report sets the mirror and re-arms its timeout;
//! - an invalid code (stuck-at 0x00/0xFF, flipped bits) makes that track circuit occupied;
//! - a frame failing its CRC or length check makes **every** track circuit of the port occupied:
//!   its sub-index is not trustworthy either, so it may have been about any of them;
//! - no valid report for the field timeout makes the track circuit occupied.
//!
//! A valid report restores a mirror at once: the field board's cyclic reports are the proof.

use crate::{FIELD_BOARD, FIELD_PORT, TRACKS};
use duocan::profile::railway::safety::{objects, FieldState, SafetyError, TrackCircuit};
use duocan::profile::railway::{split, Payload, PayloadError, RailFunction};
use duocan::{Duration, Frame, Instant};

/// Why a mirror holds its state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cause {
    /// Nothing reported since power-on: occupied.
    NoReport,
    /// The field board reported it.
    Report,
    /// No valid report within the field timeout: occupied.
    Timeout,
    /// A frame of the port failed its CRC or length check: occupied.
    Corrupted(PayloadError),
    /// The report's code is not a track-circuit code: occupied.
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

/// What a field frame means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Not a track-circuit report of the field board (its heartbeat, another board, another
    /// object): ignored.
    Foreign,
    /// A valid report.
    Report {
        /// Track circuit.
        track: u8,
        /// Its state.
        state: TrackCircuit,
    },
    /// A report of `track` whose code is invalid.
    InvalidCode {
        /// Track circuit.
        track: u8,
        /// What was wrong.
        error: SafetyError,
    },
    /// A frame of the track-circuit port that fails its check.
    Corrupted(PayloadError),
}

/// Reads one frame from the field bus.
pub fn classify(frame: &Frame) -> Verdict {
    let Some((code, address)) = split(frame.id()) else {
        return Verdict::Foreign;
    };
    if code != RailFunction::StateChange.code()
        || address.board_address() != FIELD_BOARD
        || address.port() != FIELD_PORT
    {
        return Verdict::Foreign;
    }
    let payload = match Payload::decode(frame) {
        Ok(p) => p,
        Err(e) => return Verdict::Corrupted(e),
    };
    let track = payload.sub();
    if payload.index() != objects::TRACK_CIRCUIT || !(1..=TRACKS).contains(&track) {
        return Verdict::Foreign;
    }
    match FieldState::from_payload(&payload) {
        Ok((_, FieldState::Track(state))) => Verdict::Report { track, state },
        Ok(_) => Verdict::Foreign,
        Err(error) => Verdict::InvalidCode { track, error },
    }
}

#[derive(Clone, Copy, Debug)]
struct Mirror {
    state: TrackCircuit,
    cause: Cause,
    /// When the last valid report goes stale.
    deadline: Option<Instant>,
}

/// The mirrors of the gateway's track circuits.
#[derive(Clone, Debug)]
pub struct Tracks {
    mirrors: [Mirror; TRACKS as usize],
}

/// Changes one field frame (or one instant) can cause: at most one per track circuit.
pub type Changes = heapless::Vec<TrackChange, { TRACKS as usize }>;

impl Default for Tracks {
    fn default() -> Self {
        Self::new()
    }
}

impl Tracks {
    /// Every track circuit occupied, nothing reported.
    #[must_use]
    pub const fn new() -> Self {
        Tracks {
            mirrors: [Mirror {
                state: TrackCircuit::Occupied,
                cause: Cause::NoReport,
                deadline: None,
            }; TRACKS as usize],
        }
    }

    /// State and cause of track circuit `track` (1-based).
    pub fn get(&self, track: u8) -> Option<(TrackCircuit, Cause)> {
        let m = self.mirrors.get(usize::from(track).checked_sub(1)?)?;
        Some((m.state, m.cause))
    }

    /// Applies a verdict received at `now`; `timeout` is the field timeout in force.
    pub fn apply(&mut self, now: Instant, verdict: Verdict, timeout: Duration) -> Changes {
        let mut out = Changes::new();
        match verdict {
            Verdict::Foreign => {}
            Verdict::Report { track, state } => {
                let deadline = Some(now.saturating_add(timeout));
                self.set(now, track, state, Cause::Report, deadline, &mut out);
            }
            Verdict::InvalidCode { track, error } => {
                let cause = Cause::InvalidCode(error);
                self.set(now, track, TrackCircuit::Occupied, cause, None, &mut out);
            }
            Verdict::Corrupted(e) => {
                for track in 1..=TRACKS {
                    let cause = Cause::Corrupted(e);
                    self.set(now, track, TrackCircuit::Occupied, cause, None, &mut out);
                }
            }
        }
        out
    }

    /// Track circuits whose last valid report went stale by `now` become occupied.
    pub fn expire(&mut self, now: Instant) -> Changes {
        let mut out = Changes::new();
        for track in 1..=TRACKS {
            let i = usize::from(track - 1);
            if self.mirrors[i].deadline.is_some_and(|d| d <= now) {
                let at = self.mirrors[i].deadline.unwrap_or(now);
                self.set(
                    at,
                    track,
                    TrackCircuit::Occupied,
                    Cause::Timeout,
                    None,
                    &mut out,
                );
            }
        }
        out
    }

    /// The earliest instant a mirror goes stale.
    pub fn deadline(&self) -> Option<Instant> {
        self.mirrors.iter().filter_map(|m| m.deadline).min()
    }

    fn set(
        &mut self,
        at: Instant,
        track: u8,
        to: TrackCircuit,
        cause: Cause,
        deadline: Option<Instant>,
        out: &mut Changes,
    ) {
        let Some(m) = usize::from(track)
            .checked_sub(1)
            .and_then(|i| self.mirrors.get_mut(i))
        else {
            return;
        };
        let from = m.state;
        *m = Mirror {
            state: to,
            cause,
            deadline,
        };
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

#[cfg(test)]
mod tests {
    use super::*;
    use duocan::profile::railway::{id, DeviceAddress};
    use duocan::Id;

    const PORT_ID: Id = id(RailFunction::StateChange, FIELD_BOARD.with_port(FIELD_PORT));
    const T: Duration = Duration::from_millis(300);

    fn report(track: u8, code: u8) -> Frame {
        Payload::byte(objects::TRACK_CIRCUIT, track, code).encode(PORT_ID)
    }

    #[test]
    fn only_checked_reports_of_the_field_port_count() {
        assert_eq!(
            classify(&report(2, 0x55)),
            Verdict::Report {
                track: 2,
                state: TrackCircuit::Clear
            }
        );
        // Same content under another port or board, or another object: not ours.
        let other_port = id(RailFunction::StateChange, FIELD_BOARD.with_port(2));
        let f = Payload::byte(objects::TRACK_CIRCUIT, 1, 0x55).encode(other_port);
        assert_eq!(classify(&f), Verdict::Foreign);
        let other_board = id(
            RailFunction::StateChange,
            DeviceAddress::board_at(0, 0, 1, 2),
        );
        let f = Payload::byte(objects::TRACK_CIRCUIT, 1, 0x55).encode(other_board);
        assert_eq!(classify(&f), Verdict::Foreign);
        assert_eq!(classify(&report(TRACKS + 1, 0x55)), Verdict::Foreign);
        assert_eq!(
            classify(&Frame::from_array(Id::Standard(0x181), [1])),
            Verdict::Foreign
        );
        // A frame replayed from another identifier fails the CRC (it covers the identifier).
        let mut b = report(1, 0x55).data().to_vec();
        b[3] ^= 0xFF; // 0x55 → 0xAA without a new CRC
        let f = Frame::new(PORT_ID, &b).unwrap();
        assert!(matches!(
            classify(&f),
            Verdict::Corrupted(PayloadError::Crc { .. })
        ));
        assert!(matches!(
            classify(&report(3, 0xFF)),
            Verdict::InvalidCode { track: 3, .. }
        ));
    }

    #[test]
    fn safe_side_on_invalid_corrupted_and_stale() {
        let mut t = Tracks::new();
        let at = |ms| Instant::from_millis(ms);
        assert_eq!(t.get(1), Some((TrackCircuit::Occupied, Cause::NoReport)));
        let c = t.apply(at(10), classify(&report(1, 0x55)), T);
        assert_eq!(c.len(), 1);
        assert_eq!((c[0].track, c[0].to), (1, TrackCircuit::Clear));
        t.apply(at(10), classify(&report(2, 0x55)), T);
        assert_eq!(t.deadline(), Some(at(310)));
        // Stuck-at code on track 2 only.
        let c = t.apply(at(20), classify(&report(2, 0x00)), T);
        assert_eq!(c.len(), 1);
        assert!(matches!(c[0].cause, Cause::InvalidCode(_)));
        assert_eq!(t.get(1).unwrap().0, TrackCircuit::Clear);
        // A corrupted frame: every track circuit.
        t.apply(at(30), classify(&report(2, 0x55)), T);
        let bad = Frame::new(PORT_ID, &[0, 0x60, 1, 0x55, 0, 0]).unwrap();
        let c = t.apply(at(40), classify(&bad), T);
        assert_eq!(c.len(), 2, "tracks 1 and 2 were clear: {c:?}");
        assert!((1..=TRACKS).all(|k| t.get(k).unwrap().0 == TrackCircuit::Occupied));
        assert_eq!(t.deadline(), None);
        // Reports restore; silence expires exactly at last report + timeout.
        t.apply(at(50), classify(&report(4, 0x55)), T);
        assert!(t.expire(at(349)).is_empty());
        let c = t.expire(at(351));
        assert_eq!(c.len(), 1);
        assert_eq!(
            (c[0].at, c[0].track, c[0].cause),
            (at(350), 4, Cause::Timeout)
        );
        assert_eq!(t.get(0), None);
        assert_eq!(t.get(TRACKS + 1), None);
    }
}
