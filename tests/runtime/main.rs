//! The tokio runtime (`duocan::runtime`) on the in-memory bus.

mod fd;
mod memory_bus;
mod reader_thread;
#[path = "../common/runtime.rs"]
mod rt;
mod shutdown;
