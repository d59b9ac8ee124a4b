//! The field: point machines, signals, track circuits and level crossings, one per board pair.
//!
//! The A and B boards of a pair drive and read the same field device, so its state is shared
//! between them ([`Shared`]): what one board commands, the other sees. The state is a timeline
//! of changes, so a board knows when to wake up to report the next one.

use duocan::profile::railway::safety::{objects, PointPosition, SignalAspect, TrackCircuit};
use duocan::{Duration, Instant};
use std::cell::RefCell;
use std::rc::Rc;

/// How long a point machine takes to throw the point.
pub const THROW: Duration = Duration::from_millis(400);
/// How long a signal's lamp proving takes to confirm a new aspect.
pub const PROVE: Duration = Duration::from_millis(60);
/// How long level-crossing barriers take to go down or up.
pub const BARRIERS: Duration = Duration::from_millis(500);

/// Level-crossing barriers up (road open): an asymmetric code like the railway profile's (four ones,
/// four zeros, eight bits from "down").
pub const BARRIERS_UP: u8 = 0x3C;
/// Barriers down (road closed).
pub const BARRIERS_DOWN: u8 = 0xC3;
/// Barriers moving.
pub const BARRIERS_MOVING: u8 = 0x0F;
/// The object index of level crossings in the railway payload (next to the profile's own).
pub const CROSSING_OBJECT: u16 = 0x6300;

/// What kind of field device a rack's boards drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Point machines (turnouts).
    Point,
    /// Colour-light signals.
    Signal,
    /// Track circuits (read only: trains change them).
    Track,
    /// Level-crossing barriers.
    Crossing,
}

impl Kind {
    /// Short name of device `i` (0-based): "P1", "S3", "T2", "LC1".
    pub fn label(self, i: usize) -> String {
        let p = match self {
            Kind::Point => "P",
            Kind::Signal => "S",
            Kind::Track => "T",
            Kind::Crossing => "LC",
        };
        format!("{p}{}", i + 1)
    }
    /// The railway payload's object index for this kind.
    pub const fn object(self) -> u16 {
        match self {
            Kind::Point => objects::POINT,
            Kind::Signal => objects::SIGNAL,
            Kind::Track => objects::TRACK_CIRCUIT,
            Kind::Crossing => CROSSING_OBJECT,
        }
    }
    /// The state a device of this kind is in at power-on.
    pub const fn initial(self) -> u8 {
        match self {
            Kind::Point => PointPosition::Normal as u8,
            Kind::Signal => SignalAspect::Stop as u8,
            Kind::Track => TrackCircuit::Clear as u8,
            Kind::Crossing => BARRIERS_UP,
        }
    }
    /// A state code as a word, for printing.
    pub fn word(self, code: u8) -> &'static str {
        match (self, code) {
            (Kind::Point, 0x33) => "normal",
            (Kind::Point, 0xCC) => "reverse",
            (Kind::Point, 0x0F) => "moving",
            (Kind::Signal, 0x66) => "stop",
            (Kind::Signal, 0x5A) => "caution",
            (Kind::Signal, 0xA5) => "proceed",
            (Kind::Track, 0x55) => "clear",
            (Kind::Track, 0xAA) => "occupied",
            (Kind::Crossing, BARRIERS_UP) => "barriers up",
            (Kind::Crossing, BARRIERS_DOWN) => "barriers down",
            (Kind::Crossing, BARRIERS_MOVING) => "barriers moving",
            _ => "invalid",
        }
    }
}

/// One field device: its state over time.
#[derive(Debug)]
pub struct Field {
    /// Its kind.
    pub kind: Kind,
    /// `(from, state)` in time order; the first is the power-on state at zero.
    changes: Vec<(Instant, u8)>,
}

/// A field device shared by the two boards of a pair.
pub type Shared = Rc<RefCell<Field>>;

impl Field {
    /// A device of `kind` in its power-on state.
    pub fn new(kind: Kind) -> Shared {
        Rc::new(RefCell::new(Field {
            kind,
            changes: vec![(Instant::ZERO, kind.initial())],
        }))
    }
    /// The state at `t`.
    pub fn code_at(&self, t: Instant) -> u8 {
        self.changes
            .iter()
            .rev()
            .find(|c| c.0 <= t)
            .map_or(self.kind.initial(), |c| c.1)
    }
    /// The first change after `t`.
    pub fn next_after(&self, t: Instant) -> Option<Instant> {
        self.changes.iter().map(|c| c.0).find(|at| *at > t)
    }
    /// The state becomes `code` at `at` (a train entering or leaving a track circuit);
    /// later changes already planned are dropped.
    pub fn set(&mut self, at: Instant, code: u8) {
        self.changes.retain(|c| c.0 < at);
        self.changes.push((at, code));
    }
    /// A board drives the device to `target` at `now`: the point throws, the signal's lamps
    /// are proven, the barriers move. A command overrides a movement under way.
    pub fn command(&mut self, now: Instant, target: u8) {
        let (moving, takes) = match self.kind {
            Kind::Point => (Some(PointPosition::Moving as u8), THROW),
            Kind::Signal => (None, PROVE),
            Kind::Crossing => (Some(BARRIERS_MOVING), BARRIERS),
            // Track circuits take no commands.
            Kind::Track => return,
        };
        self.changes.retain(|c| c.0 <= now);
        if self.code_at(now) == target {
            return;
        }
        if let Some(m) = moving {
            self.changes.push((now, m));
        }
        self.changes.push((now + takes, target));
    }
}
