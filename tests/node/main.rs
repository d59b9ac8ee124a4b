//! The node (`duocan::node`): every CiA 301 service through a node, properties, static RAM, timing on the simulated bus.

mod clock;
#[path = "../common/mod.rs"]
mod common;
mod error_control;
mod memory;
mod program_store;
mod properties;
mod services;
mod sim;
mod storage;
mod storage_file;
mod storage_properties;
