//! The CiA 302-2 master (`duocan::master`) and the master-side PDO configuration (`duocan::cia302::pdo_config`).

mod boot;
mod capacity;
mod concise_dcf;
mod control;
mod dcf_config;
mod failures;
#[cfg(feature = "mpdo")]
mod mpdo;
mod net;
mod network_boot;
mod pdo_config;
mod program_download;
mod properties;
mod queues;
mod reboot;
mod request_nmt;
mod slots;
mod standby;
mod two_step;
