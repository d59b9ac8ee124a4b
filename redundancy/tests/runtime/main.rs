//! The logical network object under the tokio runtime (in-memory buses).

mod fd;
mod front_door;
mod memory_bus;
mod stall;
