//! The PDO engine (`duocan::pdo`): transmission types, mapping, timing on the simulated bus, properties.

#[path = "../common/mod.rs"]
mod common;
mod engine;
#[cfg(feature = "fd")]
mod fd;
#[cfg(feature = "mpdo")]
mod mpdo;
#[cfg(all(feature = "fd", feature = "mpdo"))]
mod mpdo_fd;
mod properties;
mod sim;
mod storage;
