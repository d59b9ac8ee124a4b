//! The dual-bus layer's capacities as one type: how many merger slots and same-function values
//! a [`DualBus`](crate::DualBus) holds, fixed at compile time.
//!
//! # What it is
//!
//! The layer keeps two tables whose size is part of its type, so that it needs no allocator and
//! a firmware image's memory is known when it is linked: the exact merge's [`Merger<SLOTS>`]
//! (its ring, key arena and index are arrays of `SLOTS`) and the same-function table
//! [`SameFunction<FUNCTIONS>`] (a `heapless` map of `FUNCTIONS` entries). A [`MergeCapacity`]
//! names both: `DualBus<C, K>` holds a `K::Merger` and a `K::Functions`. [`Capacity<SLOTS,
//! FUNCTIONS>`](Capacity) is the capacity of any two sizes, and its defaults,
//! [`DEFAULT_MERGE_SLOTS`] and [`MAX_FUNCTIONS`], are what a layer
//! gets when it says nothing:
//!
//! ```
//! use duocan_core::profile::Predefined;
//! use duocan_redundancy_core::link::capacity::Capacity;
//! use duocan_redundancy_core::link::merge::Merger;
//! use duocan_redundancy_core::{DualBus, DualBusConfig};
//!
//! // A host's layer: the defaults (1,024 merger slots, 256 functions).
//! let host = DualBus::new(DualBusConfig::default());
//! assert_eq!(host.merger().capacity(), 768);
//! // A microcontroller's, sized to its network: 64 slots, 16 functions.
//! let board: DualBus<Predefined, Capacity<64, 16>> =
//!     DualBus::with_classifier(DualBusConfig::default(), Predefined);
//! let merger: &Merger<64> = board.merger();
//! assert_eq!(merger.capacity(), 48);
//! ```
//!
//! A firmware author may as well give the board's sizes a name of its own, which its types then
//! read as: a type that implements [`MergeCapacity`] with the tables it wants.
//!
//! ```
//! use duocan_core::profile::Predefined;
//! use duocan_redundancy_core::link::capacity::MergeCapacity;
//! use duocan_redundancy_core::link::merge::Merger;
//! use duocan_redundancy_core::link::same_function::SameFunction;
//! use duocan_redundancy_core::{DualBus, DualBusConfig};
//!
//! /// Four pairs of four TPDOs, eight heartbeats every 50 ms.
//! enum Board {}
//! impl MergeCapacity for Board {
//!     type Merger = Merger<64>;
//!     type Functions = SameFunction<16>;
//! }
//! let link: DualBus<Predefined, Board> = DualBus::with_classifier(DualBusConfig::default(), Predefined);
//! assert_eq!(link.pairs().len(), 0);
//! ```
//!
//! # Why one type, and why associated types
//!
//! The layer had both sizes as const parameters (`DualBus<C, SLOTS, FUNCTIONS>`), and the
//! redundant master that holds it had them too, beside its dictionary and identifier profile
//! (`SupervisedStation<D, P, SLOTS, FUNCTIONS>`): four parameters, which every function that
//! takes a station had to repeat, and which the documentation answered with aliases. A type a
//! user names now has at most two: what it is generic over, and one type that says how it is
//! stored (here `K`; for the station, its link, see [`SupervisedStation`](crate::SupervisedStation)).
//!
//! The sizes must still choose the arrays at compile time, on stable Rust. An associated
//! *constant* (`K::SLOTS`) cannot: an array `[Record; K::SLOTS]` in a generic type needs
//! `generic_const_exprs`, which is unstable. An associated *type* can: the capacity names the
//! tables themselves (`type Merger = Merger<SLOTS>`), whose arrays have a literal or a const
//! parameter for their length, as before. So:
//!
//! - the memory is the same: `DualBus<C, Capacity<S, F>>` holds exactly the `Merger<S>` and
//!   `SameFunction<F>` that `DualBus<C, S, F>` held, and the capacity type itself is empty (an
//!   enum without variants, never built);
//! - the merger runs the same code: the layer calls it through the [`MergerStorage`] trait,
//!   whose methods are the merger's own, forwarded and inlined; the call is resolved when the
//!   layer is monomorphised, as an inherent call was (no `dyn`, no indirection: the merge
//!   benchmarks measure the same path);
//! - the storage traits are sealed: only `Merger<SLOTS>` and `SameFunction<FUNCTIONS>`
//!   implement them, so the layer's invariants are the tables' own, while any type may be a
//!   [`MergeCapacity`] (a board's name for its sizes);
//! - a concrete layer's [`merger`](crate::DualBus::merger) and
//!   [`pairs`](crate::DualBus::pairs) are the concrete tables (`&Merger<64>` above): their
//!   whole API is there, not only the trait's.
//!
//! Two alternatives were weighed. Keeping the consts on `DualBus` and bundling only the
//! station's parameters would leave the layer with three, and every capacity a board chose would
//! still be spelt twice. Sizing the tables at run time from a slice the caller provides would
//! take the merger's masks and shifts out of the constants they are now, on the frame path the
//! merge benchmarks measure, and put a lifetime on the layer.

use crate::link::merge::{Merger, Sample, Trust, Verdict};
use crate::link::outbox::Outbox;
use crate::link::same_function::{PairError, PairVerdict, SameFunction, MAX_FUNCTIONS};
use crate::pair::{Member, PairId};
use duocan_core::{Duration, Frame, Instant, NodeId};

/// Merger slots of a [`DualBus`](crate::DualBus) unless chosen otherwise: 768 records, enough
/// for a saturated 1 Mbit/s bus (about 8,000 frames/s) whose twins stay missing for the horizon
/// (80 ms: the other bus dead, or its reader that far behind).
pub const DEFAULT_MERGE_SLOTS: usize = 1024;

/// The capacities of a dual-bus layer: its merger and its same-function table (see the
/// [module](self)). Implemented by [`Capacity`] for any two sizes, and by whatever a firmware
/// author names its sizes with.
pub trait MergeCapacity {
    /// The exact merge: a [`Merger<SLOTS>`].
    type Merger: MergerStorage;
    /// The pair table and the members' latest values: a [`SameFunction<FUNCTIONS>`].
    type Functions: FunctionStorage;
}

/// `SLOTS` merger slots (a power of two, 4 to 32,768) and room for `FUNCTIONS` (pair, function)
/// values (a power of two): the [`MergeCapacity`] of any two sizes; by default the layer's
/// ([`DEFAULT_MERGE_SLOTS`], [`MAX_FUNCTIONS`]). A type, never a value.
pub enum Capacity<const SLOTS: usize = DEFAULT_MERGE_SLOTS, const FUNCTIONS: usize = MAX_FUNCTIONS>
{}

impl<const SLOTS: usize, const FUNCTIONS: usize> MergeCapacity for Capacity<SLOTS, FUNCTIONS> {
    type Merger = Merger<SLOTS>;
    type Functions = SameFunction<FUNCTIONS>;
}

mod sealed {
    pub trait SealedStorage {}
    impl<const SLOTS: usize> SealedStorage for super::Merger<SLOTS> {}
    impl<const FUNCTIONS: usize> SealedStorage for super::SameFunction<FUNCTIONS> {}
}

/// What the layer asks of its merger: implemented by [`Merger<SLOTS>`] only (sealed). The
/// methods are the merger's, forwarded.
pub trait MergerStorage: sealed::SealedStorage + core::fmt::Debug {
    #[doc(hidden)]
    fn with_horizon(window: Duration, horizon: Duration) -> Self;
    #[doc(hidden)]
    fn window(&self) -> Duration;
    #[doc(hidden)]
    fn set_stamped(&mut self, p: usize, stamped: bool);
    #[doc(hidden)]
    fn arrive_at(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &Frame,
        trust: Trust,
    ) -> (Verdict, Option<Sample>);
    #[doc(hidden)]
    #[cfg(feature = "fd")]
    fn arrive_fd_at(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &duocan_core::frame::FdFrame,
        trust: Trust,
    ) -> (Verdict, Option<Sample>);
    #[doc(hidden)]
    fn shift(&mut self, p: usize, by: i64);
    #[doc(hidden)]
    fn expire(&mut self, now: Instant);
    #[doc(hidden)]
    fn step_back(&mut self, by: Duration);
}

impl<const SLOTS: usize> MergerStorage for Merger<SLOTS> {
    #[inline]
    fn with_horizon(window: Duration, horizon: Duration) -> Self {
        Merger::with_horizon(window, horizon)
    }
    #[inline]
    fn window(&self) -> Duration {
        Merger::window(self)
    }
    #[inline]
    fn set_stamped(&mut self, p: usize, stamped: bool) {
        Merger::set_stamped(self, p, stamped);
    }
    #[inline]
    fn arrive_at(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &Frame,
        trust: Trust,
    ) -> (Verdict, Option<Sample>) {
        Merger::arrive_at(self, now, at, port, frame, trust)
    }
    #[inline]
    #[cfg(feature = "fd")]
    fn arrive_fd_at(
        &mut self,
        now: Instant,
        at: Instant,
        port: usize,
        frame: &duocan_core::frame::FdFrame,
        trust: Trust,
    ) -> (Verdict, Option<Sample>) {
        Merger::arrive_fd_at(self, now, at, port, frame, trust)
    }
    #[inline]
    fn shift(&mut self, p: usize, by: i64) {
        Merger::shift(self, p, by);
    }
    #[inline]
    fn expire(&mut self, now: Instant) {
        Merger::expire(self, now);
    }
    #[inline]
    fn step_back(&mut self, by: Duration) {
        Merger::step_back(self, by);
    }
}

/// What the layer asks of its same-function table: implemented by [`SameFunction<FUNCTIONS>`]
/// only (sealed). The methods are the table's, forwarded.
pub trait FunctionStorage: sealed::SealedStorage {
    #[doc(hidden)]
    fn new(discrepancy_time: Duration) -> Self;
    #[doc(hidden)]
    fn is_empty(&self) -> bool;
    #[doc(hidden)]
    fn add_pair(
        &mut self,
        a: NodeId,
        b: NodeId,
        active: Option<Member>,
    ) -> Result<PairId, PairError>;
    #[doc(hidden)]
    fn set_active(&mut self, pair: PairId, member: Option<Member>) -> bool;
    #[doc(hidden)]
    fn forget(&mut self, pair: PairId, member: Member);
    #[doc(hidden)]
    fn on_frame_by(
        &mut self,
        now: Instant,
        node: NodeId,
        function: u32,
        frame: &Frame,
        out: &mut Outbox,
        same: impl Fn(&Frame, &Frame) -> bool,
    ) -> PairVerdict;
    #[doc(hidden)]
    fn poll_timeout(&self) -> Option<Instant>;
    #[doc(hidden)]
    fn handle_timeout(&mut self, now: Instant, out: &mut Outbox);
    #[doc(hidden)]
    fn step_back(&mut self, by: Duration);
}

impl<const FUNCTIONS: usize> FunctionStorage for SameFunction<FUNCTIONS> {
    #[inline]
    fn new(discrepancy_time: Duration) -> Self {
        SameFunction::new(discrepancy_time)
    }
    #[inline]
    fn is_empty(&self) -> bool {
        SameFunction::is_empty(self)
    }
    #[inline]
    fn add_pair(
        &mut self,
        a: NodeId,
        b: NodeId,
        active: Option<Member>,
    ) -> Result<PairId, PairError> {
        SameFunction::add_pair(self, a, b, active)
    }
    #[inline]
    fn set_active(&mut self, pair: PairId, member: Option<Member>) -> bool {
        SameFunction::set_active(self, pair, member)
    }
    #[inline]
    fn forget(&mut self, pair: PairId, member: Member) {
        SameFunction::forget(self, pair, member);
    }
    #[inline]
    fn on_frame_by(
        &mut self,
        now: Instant,
        node: NodeId,
        function: u32,
        frame: &Frame,
        out: &mut Outbox,
        same: impl Fn(&Frame, &Frame) -> bool,
    ) -> PairVerdict {
        SameFunction::on_frame_by(self, now, node, function, frame, out, same)
    }
    #[inline]
    fn poll_timeout(&self) -> Option<Instant> {
        SameFunction::poll_timeout(self)
    }
    #[inline]
    fn handle_timeout(&mut self, now: Instant, out: &mut Outbox) {
        SameFunction::handle_timeout(self, now, out);
    }
    #[inline]
    fn step_back(&mut self, by: Duration) {
        SameFunction::step_back(self, by);
    }
}
