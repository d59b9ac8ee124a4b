//! Asymmetric encodings of safety states: every valid code is a byte with four ones and four
//! zeros, and any two codes of one kind differ in at least four bits.
//!
//! So a byte stuck at 0x00 or 0xFF, a single flipped bit, or two or three flipped bits never
//! read as a valid state: they decode as [`SafetyError::InvalidCode`], and the interlocking
//! takes the safe side (track occupied, point not detected, signal at stop).
//!
//! [`FieldState`] puts one state in a railway [`Payload`] under the object indices of
//! [`objects`], the sub-index naming the field device on the board.

use super::payload::Payload;
use core::fmt;

/// Why a byte or a payload is not a valid safety state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SafetyError {
    /// Not one of the kind's codes.
    InvalidCode {
        /// The kind ("track circuit", "point position", "signal aspect").
        kind: &'static str,
        /// The byte received.
        byte: u8,
    },
    /// The payload's index is none of [`objects`].
    UnknownObject {
        /// The index.
        index: u16,
    },
    /// A state payload carries exactly one data byte.
    Length {
        /// The index.
        index: u16,
        /// Data bytes received.
        len: usize,
    },
}

impl fmt::Display for SafetyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SafetyError::InvalidCode { kind, byte } => write!(
                f,
                "{byte:#04x} is not a valid {kind} code (stuck-at or corrupted): take the safe side"
            ),
            SafetyError::UnknownObject { index } => {
                write!(f, "object {index:#06x} is not a railway field state")
            }
            SafetyError::Length { index, len } => write!(
                f,
                "field state {index:#06x} with {len} data bytes: exactly one expected"
            ),
        }
    }
}

impl core::error::Error for SafetyError {}

/// A safety state with an asymmetric byte code.
pub trait SafetyCode: Sized + Copy + 'static {
    /// What it is, for error messages.
    const KIND: &'static str;
    /// Every valid state.
    const ALL: &'static [Self];
    /// Its code on the bus.
    fn code(self) -> u8;
    /// The state a byte encodes; any byte that is not a code is an error.
    fn from_code(byte: u8) -> Result<Self, SafetyError> {
        Self::ALL
            .iter()
            .copied()
            .find(|s| s.code() == byte)
            .ok_or(SafetyError::InvalidCode {
                kind: Self::KIND,
                byte,
            })
    }
}

/// Track-circuit occupancy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum TrackCircuit {
    /// No train: 0x55.
    Clear = 0x55,
    /// Occupied (also the safe reading of anything invalid): 0xAA.
    Occupied = 0xAA,
}

impl SafetyCode for TrackCircuit {
    const KIND: &'static str = "track circuit";
    const ALL: &'static [Self] = &[TrackCircuit::Clear, TrackCircuit::Occupied];
    fn code(self) -> u8 {
        self as u8
    }
}

/// Point (turnout) position as the point machine detects it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum PointPosition {
    /// Detected in normal position: 0x33.
    Normal = 0x33,
    /// Detected in reverse position: 0xCC.
    Reverse = 0xCC,
    /// Moving between positions: 0x0F.
    Moving = 0x0F,
    /// No detection (trailed, obstructed, out of correspondence): 0xF0.
    Lost = 0xF0,
}

impl SafetyCode for PointPosition {
    const KIND: &'static str = "point position";
    const ALL: &'static [Self] = &[
        PointPosition::Normal,
        PointPosition::Reverse,
        PointPosition::Moving,
        PointPosition::Lost,
    ];
    fn code(self) -> u8 {
        self as u8
    }
}

/// Signal aspect (commanded, or proven by the lamp circuits).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum SignalAspect {
    /// Stop (red): 0x66.
    Stop = 0x66,
    /// Caution (yellow): 0x5A.
    Caution = 0x5A,
    /// Proceed (green): 0xA5.
    Proceed = 0xA5,
    /// Dark: lamp proving failed: 0x99.
    Dark = 0x99,
}

impl SafetyCode for SignalAspect {
    const KIND: &'static str = "signal aspect";
    const ALL: &'static [Self] = &[
        SignalAspect::Stop,
        SignalAspect::Caution,
        SignalAspect::Proceed,
        SignalAspect::Dark,
    ];
    fn code(self) -> u8 {
        self as u8
    }
}

/// Object indices of field states (device-profile area); the sub-index is the field device's
/// number on its board.
pub mod objects {
    /// Track-circuit occupancy ([`super::TrackCircuit`]).
    pub const TRACK_CIRCUIT: u16 = 0x6000;
    /// Point position ([`super::PointPosition`]).
    pub const POINT: u16 = 0x6100;
    /// Signal aspect ([`super::SignalAspect`]).
    pub const SIGNAL: u16 = 0x6200;
}

/// One field device's state, as a state change, state answer or command carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FieldState {
    /// A track circuit.
    Track(TrackCircuit),
    /// A point machine.
    Point(PointPosition),
    /// A signal.
    Signal(SignalAspect),
}

impl FieldState {
    /// The payload for field device `sub` of the board.
    pub const fn payload(self, sub: u8) -> Payload {
        let (index, code) = match self {
            FieldState::Track(s) => (objects::TRACK_CIRCUIT, s as u8),
            FieldState::Point(s) => (objects::POINT, s as u8),
            FieldState::Signal(s) => (objects::SIGNAL, s as u8),
        };
        Payload::byte(index, sub, code)
    }
    /// (field device, state) of a payload whose CRC was checked already.
    pub fn from_payload(p: &Payload) -> Result<(u8, FieldState), SafetyError> {
        let index = p.index();
        let byte = match p.data() {
            [b] => *b,
            d => {
                return Err(SafetyError::Length {
                    index,
                    len: d.len(),
                })
            }
        };
        let state = match index {
            objects::TRACK_CIRCUIT => FieldState::Track(TrackCircuit::from_code(byte)?),
            objects::POINT => FieldState::Point(PointPosition::from_code(byte)?),
            objects::SIGNAL => FieldState::Signal(SignalAspect::from_code(byte)?),
            _ => return Err(SafetyError::UnknownObject { index }),
        };
        Ok((p.sub(), state))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::Id;
    use proptest::prelude::*;

    fn check_kind<S: SafetyCode + core::fmt::Debug + PartialEq>() {
        for (i, a) in S::ALL.iter().enumerate() {
            assert_eq!(a.code().count_ones(), 4, "{} {a:?}", S::KIND);
            assert_eq!(S::from_code(a.code()), Ok(*a));
            for b in &S::ALL[i + 1..] {
                let d = (a.code() ^ b.code()).count_ones();
                assert!(d >= 4, "{} {a:?} / {b:?}: distance {d}", S::KIND);
            }
        }
        for stuck in [0x00, 0xFF] {
            assert_eq!(
                S::from_code(stuck),
                Err(SafetyError::InvalidCode {
                    kind: S::KIND,
                    byte: stuck
                })
            );
        }
        // Every byte within three bit flips of a code is invalid.
        for a in S::ALL {
            for byte in 0..=255u8 {
                let d = (byte ^ a.code()).count_ones();
                if (1..=3).contains(&d) {
                    assert!(S::from_code(byte).is_err(), "{byte:#x} near {a:?}");
                }
            }
        }
        let valid = (0..=255u8).filter(|b| S::from_code(*b).is_ok()).count();
        assert_eq!(valid, S::ALL.len());
    }

    #[test]
    fn codes_are_balanced_and_four_bits_apart() {
        check_kind::<TrackCircuit>();
        check_kind::<PointPosition>();
        check_kind::<SignalAspect>();
        assert_eq!(TrackCircuit::Clear.code(), 0x55);
        assert_eq!(TrackCircuit::Occupied.code(), 0xAA);
    }

    #[test]
    fn field_states_travel_in_checked_payloads() {
        let id = Id::Extended(0x0201_2341);
        for s in [
            FieldState::Track(TrackCircuit::Occupied),
            FieldState::Point(PointPosition::Reverse),
            FieldState::Signal(SignalAspect::Proceed),
        ] {
            let f = s.payload(2).encode(id);
            let p = Payload::decode(&f).unwrap();
            assert_eq!(FieldState::from_payload(&p), Ok((2, s)));
        }
        let bad = Payload::byte(objects::POINT, 1, 0x00);
        assert_eq!(
            FieldState::from_payload(&bad),
            Err(SafetyError::InvalidCode {
                kind: "point position",
                byte: 0
            })
        );
        assert_eq!(
            FieldState::from_payload(&Payload::byte(0x2000, 1, 0x55)),
            Err(SafetyError::UnknownObject { index: 0x2000 })
        );
        let two = Payload::new(objects::SIGNAL, 1, &[0x66, 0]).unwrap();
        assert_eq!(
            FieldState::from_payload(&two),
            Err(SafetyError::Length {
                index: objects::SIGNAL,
                len: 2
            })
        );
        assert!(SafetyError::InvalidCode {
            kind: "track circuit",
            byte: 0xFF
        }
        .to_string()
        .contains("safe side"));
    }

    proptest! {
        #[test]
        fn any_payload_decodes_or_errs(index in any::<u16>(), sub in any::<u8>(), data in proptest::collection::vec(any::<u8>(), 0..=3)) {
            let p = Payload::new(index, sub, &data).unwrap();
            if let Ok((s, state)) = FieldState::from_payload(&p) {
                prop_assert_eq!(s, sub);
                prop_assert_eq!(state.payload(sub), p);
            }
        }
    }
}
