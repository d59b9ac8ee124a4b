//! Tests of the simulator, driving small probe devices.

mod basic;
mod bridge;
mod determinism;
mod events;
mod faults;
mod fd;
mod latency;
mod passive;
mod power;
mod probe;
mod tx_dead;

use super::{BusConfig, BusId, SimNetwork, TraceRecord, TxRecord};

/// A network with `n` buses at `bitrate`.
fn network(seed: u64, n: usize, bitrate: u32) -> (SimNetwork, Vec<BusId>) {
    let mut sim = SimNetwork::new(seed);
    let buses = (0..n)
        .map(|i| sim.add_bus(BusConfig::new(format!("can{i}"), bitrate)))
        .collect();
    (sim, buses)
}

/// The transmission records of a trace.
fn tx_records(sim: &SimNetwork) -> Vec<TxRecord> {
    sim.trace()
        .iter()
        .filter_map(|r| match r {
            TraceRecord::Tx(t) => Some(t.clone()),
            _ => None,
        })
        .collect()
}
