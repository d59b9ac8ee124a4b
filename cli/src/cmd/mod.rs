//! The commands, one module each.

pub mod dump;
pub mod eds;
pub mod flash;
pub mod gateway;
pub mod live;
pub mod monitor;
pub mod nmt;
pub mod pdo;
pub mod record;
pub mod scan;
pub mod sdo;
