//! The logical network object under the tokio runtime (in-memory buses).

mod fd;
mod fd_door;
#[path = "../common/fd_end.rs"]
mod fd_end;
mod front_door;
mod memory_bus;
mod stall;
