//! The tokio runtime (`duocan::runtime`) on the in-memory bus.

mod memory_bus;
#[path = "../common/runtime.rs"]
mod rt;
