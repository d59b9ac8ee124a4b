//! The logical network object (`duocan_redundancy::network`) on the simulated dual bus.

mod builder;
mod logical;
