//! The dual-bus layer (`duocan_redundancy::link`): the merger, and each policy on the simulated dual bus.

mod active_active;
mod app_station;
mod cia302_6;
mod clock;
mod clock_modes;
mod clock_properties;
mod crossed;
mod cyclic_lag;
mod ecss;
#[cfg(feature = "fd")]
mod fd;
#[cfg(feature = "fd")]
#[path = "../common/fd_end.rs"]
mod fd_end;
#[cfg(all(feature = "fd", feature = "cia302-6", feature = "ecss"))]
mod fd_modes;
#[path = "../common/fd_station.rs"]
mod fd_station;
mod flapping;
mod lag;
mod lag_properties;
mod lss;
#[cfg(feature = "fd")]
mod merge_fd_properties;
mod merge_memory;
mod merge_properties;
mod plausible_properties;
mod railway;
mod sequence;
mod sim;
mod srdo;
#[cfg(feature = "sticky")]
mod sticky;
#[cfg(feature = "sticky")]
mod sticky_properties;
mod superseded;
#[path = "../common/time_line.rs"]
mod time_line;
