//! The simulated redundant station.
