//! CiA 304 SRDO and GFC (`duocan::cia304`): the consumer's rules with the frames on the wire,
//! the configuration a node must have to enter operational, producer and consumer nodes end to
//! end, and a property test over random fault schedules.

#[path = "../common/mod.rs"]
mod common;
mod config;
mod consumer;
mod master;
mod nodes;
mod properties;
mod support;
