//! The tokio runtime (`duocan::runtime`) on the in-memory bus.

mod fd;
mod memory_bus;
mod reader_thread;
mod rig;
#[path = "../common/runtime.rs"]
mod rt;
mod shutdown;
