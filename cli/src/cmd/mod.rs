//! The commands, one module each.

pub mod device;
pub mod dump;
pub mod eds;
pub mod flash;
pub mod gateway;
pub mod kit;
pub mod live;
pub mod lss;
pub mod monitor;
pub mod nmt;
pub mod pdo;
pub mod record;
pub mod scan;
pub mod sdo;
pub mod station;
