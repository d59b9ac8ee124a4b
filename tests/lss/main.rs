//! LSS (CiA 305, `duocan::cia305`): every slave and master service with the frames on the wire,
//! timeouts and wrong answers, fastscan with its exact cost and its restarts after stray answers, properties, and 20 slaves found on
//! the simulated dual bus.

mod codec;
mod fastscan;
mod master;
mod node;
mod properties;
mod restart;
mod slave;
mod wire;
