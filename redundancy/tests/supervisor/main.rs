//! The supervisor (`duocan_redundancy::supervisor`): pair and flying-master machines, and the supervisor with the CiA 302-2 master on the simulated dual bus.

mod chaos;
mod clock;
mod cold_start;
mod combined;
mod fd_heartbeats;
mod fd_rig;
#[path = "../common/fd_station.rs"]
mod fd_station;
mod flying_master;
mod impostor;
mod impostor_idle;
mod jump;
mod late_start;
mod lss;
mod master;
mod net;
mod not_operational;
mod on_bus;
mod pairs;
mod partition;
mod producer_time;
mod queues;
mod seen_failover;
mod sequence;
mod step_properties;
mod stepped;
#[path = "../common/time_line.rs"]
mod time_line;
mod trust;
