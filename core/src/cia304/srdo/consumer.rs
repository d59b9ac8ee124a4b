//! The SRDO consumer: accepts data only as a normal frame followed, within SRVT, by its exact
//! bitwise inverse, and a new such pair within every SCT; anything else is its safe state.
//!
//! **The rule.** Started (entering operational) at `t0`, the consumer expects:
//! - the two halves of a pair, normal and inverted, less than SRVT apart
//!   ([`SrdoCause::Validation`] when SRVT passes first after the first half);
//! - the inverted data equal to the bitwise inverse of the normal data, byte by byte over the
//!   SRDO's length ([`SrdoCause::NotInverted`]); both frames at least that long
//!   ([`SrdoCause::Length`]);
//! - no second frame of the same half with other data before the other half
//!   ([`SrdoCause::Sequence`]); the same frame again is taken as what it is, a copy (a dual-bus
//!   layer may hand a frame over twice after a bus recovers: a copy carries nothing new, and the
//!   SRVT still runs from the first);
//! - the order of the halves is not judged: the producer sends the normal frame first, but a
//!   dual-bus layer hands over each frame from whichever bus brought it first, and while a bus
//!   recovers the two halves of one pair can come from different buses, swapped. Either half
//!   waits for the other; what is checked (exact inverse, within SRVT, one value per pair) is
//!   the same either way, and the data delivered is always the normal frame's;
//! - a complete pair less than SCT after the previous one, the first less than SCT after `t0`
//!   ([`SrdoCause::CycleTime`]).
//!
//! A deadline reached is a violation at that instant: a frame arriving exactly SRVT (or SCT)
//! late is late. Only a complete, checked pair is delivered ([`ConsumerStep::Deliver`], the
//! normal data); a half pair is held and never delivered on its own.
//!
//! **The safe state.** Any violation gives [`ConsumerStep::Trip`] with the cause and the time
//! measured (from the first half for SRVT and inversion, from the previous pair or the start
//! for SCT), and the consumer then ignores the bus: CiA 304 leaves the way back to the
//! application, and this consumer never leaves the safe state by itself. It is left by a new
//! start (entering operational again) or by [`SrdoConsumer::acknowledge`], after which the SCT
//! runs from the acknowledgement and only a new intact pair delivers data again.
//!
//! **Memory.** The held half of a pair (8 bytes) and three times: nothing grows.

use crate::frame::instant::{Duration, Instant};
use crate::frame::{Frame, Id};

/// Why a consumer entered its safe state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SrdoCause {
    /// No other half within SRVT of the first half of a pair.
    Validation,
    /// No complete pair within SCT.
    CycleTime,
    /// The two halves are not each other's bitwise inverse.
    NotInverted,
    /// A frame shorter than the SRDO's data.
    Length,
    /// A half with other data while the same half still waited for the other.
    Sequence,
    /// A global fail-safe command (GFC) was received.
    Gfc,
}

/// A consumer's entry into its safe state: the cause and the time measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdoFault {
    /// Why.
    pub cause: SrdoCause,
    /// When: the deadline for the timeouts, the frame's arrival otherwise.
    pub at: Instant,
    /// The time measured: from the first half of the pair (SRVT, inversion, sequence), from
    /// the previous pair or the start (SCT); zero for a short frame or a GFC.
    pub measured: Duration,
}

/// What one input did to a consumer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConsumerStep {
    /// A frame of this SRDO taken (the normal half held, or an inverted one ignored).
    Held,
    /// A complete, checked pair: the normal data, `len` bytes used.
    Deliver([u8; 8]),
    /// The safe state was entered.
    Trip(SrdoFault),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Stopped,
    Running {
        /// Start, acknowledgement or the previous pair: the SCT runs from here.
        since: Instant,
        /// The first half of a pair waiting for the other: when, its data, true for the
        /// normal frame.
        pending: Option<(Instant, [u8; 8], bool)>,
    },
    Safe(SrdoFault),
}

/// One SRDO consumer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SrdoConsumer {
    normal: u16,
    inverted: u16,
    sct: Duration,
    srvt: Duration,
    len: u8,
    state: State,
}

impl SrdoConsumer {
    /// A stopped consumer of `len` bytes (at most 8) on the 11-bit identifiers `normal` and
    /// `inverted`.
    #[must_use]
    pub const fn new(normal: u16, inverted: u16, sct: Duration, srvt: Duration, len: u8) -> Self {
        SrdoConsumer {
            normal,
            inverted,
            sct,
            srvt,
            len: if len > 8 { 8 } else { len },
            state: State::Stopped,
        }
    }
    /// True for the two identifiers of this SRDO.
    #[must_use]
    pub fn accepts(&self, id: Id) -> bool {
        id == Id::Standard(self.normal) || id == Id::Standard(self.inverted)
    }
    /// Starts checking at `now` (entering operational): the first pair is due within SCT.
    pub fn start(&mut self, now: Instant) {
        self.state = State::Running {
            since: now,
            pending: None,
        };
    }
    /// Stops checking (leaving operational); a safe state ends with it.
    pub fn stop(&mut self) {
        self.state = State::Stopped;
    }
    /// The application acknowledges a safe state at `now`: checking starts again, the SCT from
    /// now. False (and nothing changes) when the consumer is not in its safe state.
    pub fn acknowledge(&mut self, now: Instant) -> bool {
        if !matches!(self.state, State::Safe(_)) {
            return false;
        }
        self.start(now);
        true
    }
    /// The fault that put the consumer in its safe state, if it is there.
    #[must_use]
    pub const fn fault(&self) -> Option<SrdoFault> {
        match self.state {
            State::Safe(f) => Some(f),
            _ => None,
        }
    }
    /// True while checking (started and not safe).
    #[must_use]
    pub const fn is_running(&self) -> bool {
        matches!(self.state, State::Running { .. })
    }
    /// The next deadline: SRVT of a held half or the SCT, whichever is first.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Instant> {
        match self.state {
            State::Running { since, pending } => {
                let sct = since.saturating_add(self.sct);
                Some(match pending {
                    Some((t, _, _)) => sct.min(t.saturating_add(self.srvt)),
                    None => sct,
                })
            }
            _ => None,
        }
    }
    /// Enters the safe state at `at` with `cause` (a GFC, or the caller's own reason).
    pub fn trip(&mut self, at: Instant, cause: SrdoCause, measured: Duration) -> ConsumerStep {
        let f = SrdoFault {
            cause,
            at,
            measured,
        };
        self.state = State::Safe(f);
        ConsumerStep::Trip(f)
    }
    /// The deadlines reached by `now`: `Some` with the trip if one was.
    pub fn handle_timeout(&mut self, now: Instant) -> Option<ConsumerStep> {
        let State::Running { since, pending } = self.state else {
            return None;
        };
        let sct = since.saturating_add(self.sct);
        let srvt = pending.map(|(t, _, _)| (t, t.saturating_add(self.srvt)));
        // The earlier deadline is the one that was missed first.
        match srvt {
            Some((t, d)) if d <= sct && now >= d => {
                Some(self.trip(d, SrdoCause::Validation, d - t))
            }
            _ if now >= sct => Some(self.trip(sct, SrdoCause::CycleTime, sct - since)),
            _ => None,
        }
    }
    /// A frame at `now`. `None` when the frame is not this SRDO's or the consumer is not
    /// checking (stopped or safe).
    pub fn handle_frame(&mut self, now: Instant, frame: &Frame) -> Option<ConsumerStep> {
        if !self.accepts(frame.id()) || frame.is_remote() {
            return None;
        }
        // A deadline passed before this frame counts first, at its own instant.
        if let Some(trip) = self.handle_timeout(now) {
            return Some(trip);
        }
        let State::Running { since, pending } = self.state else {
            return None;
        };
        let n = self.len as usize;
        let data = frame.data();
        if data.len() < n {
            return Some(self.trip(now, SrdoCause::Length, Duration::ZERO));
        }
        let normal = frame.id() == Id::Standard(self.normal);
        let mut this = [0u8; 8];
        this[..n].copy_from_slice(&data[..n]);
        let Some((t, held, held_normal)) = pending else {
            self.state = State::Running {
                since,
                pending: Some((now, this, normal)),
            };
            return Some(ConsumerStep::Held);
        };
        if held_normal == normal {
            if held[..n] == this[..n] {
                return Some(ConsumerStep::Held);
            }
            return Some(self.trip(now, SrdoCause::Sequence, now - t));
        }
        if held[..n].iter().zip(&this[..n]).any(|(a, b)| !a != *b) {
            return Some(self.trip(now, SrdoCause::NotInverted, now - t));
        }
        self.state = State::Running {
            since: now,
            pending: None,
        };
        Some(ConsumerStep::Deliver(if normal { this } else { held }))
    }
    /// The caller's clock stepped back `by`.
    pub fn step_back(&mut self, by: Duration) {
        if let State::Running { since, pending } = &mut self.state {
            *since = *since - by;
            if let Some((t, _, _)) = pending {
                *t = *t - by;
            }
        }
    }
}
