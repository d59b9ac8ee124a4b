//! The logical network object under the tokio runtime (in-memory buses).

mod memory_bus;
