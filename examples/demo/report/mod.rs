//! Reports a person reads after a run (`std`): the [`svg`] timeline chart (the demo's own; not part of the library) of buses, pair roles
//! and master roles per network.
//!
//! The input is plain data in simulated seconds, so the same chart serves the simulated demo,
//! a replay of a capture, or a field log; nothing here depends on the redundancy crate.

pub mod svg;

pub use svg::{render, ChartError, Fault, Lane, LaneKind, Network, Span, State, Timeline};
