//! The logical network object (`duocan_redundancy::logical`) on the simulated dual bus.

mod builder;
mod logical;
