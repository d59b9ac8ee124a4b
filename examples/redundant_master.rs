//! A redundant master on two buses with one A/B board pair and a peer master: print every bus,
//! pair and master failover.
//!
//! ```text
//! cargo run --example redundant_master                    # a simulated station, six seconds
//! DUOCAN_BUS=can0,can1 cargo run --example redundant_master \
//!     --features socketcan,duocan-redundancy/socketcan    # two real buses, until Ctrl-C
//! ```
//!
//! `DUOCAN_BUS` names the two ports as `RedundantNetworkBuilder::open_named` takes them: `sim-pairs`
//! (the default: two in-memory buses with boards 0x10 and 0x50 and master 1 on them, where bus 1
//! of this master fails at 2 s, master 1 stops at 3 s and the active board at 4 s) or two
//! SocketCAN interfaces `A,B`. This master is node 2; master 1 outranks it (same priority, lower
//! node-ID), so it stands by until master 1 falls silent.

use duocan_redundancy::net::RedundantNetwork;
use duocan_redundancy::RedundantError;
use std::time::Duration;

/// Opens the ports `DUOCAN_BUS` names (a simulated station by default) and runs the example.
#[tokio::main]
pub async fn main() -> Result<(), RedundantError> {
    let port = std::env::var("DUOCAN_BUS").unwrap_or_else(|_| "sim-pairs".into());
    run(&port, |line| println!("{line}")).await
}

/// Opens the network on `port` and hands `print` one line per failover until it closes.
pub async fn run(port: &str, mut print: impl FnMut(String)) -> Result<(), RedundantError> {
    let net = RedundantNetwork::builder()
        .node_id(2)
        .heartbeat(Duration::from_millis(50))
        .master_timeout(Duration::from_millis(200))
        .pair(0x10, 0x50)
        .peer_master(1)
        .open_named(port)?;
    let mut events = net.events();
    while let Some(e) = events.next().await {
        if e.is_failover() {
            print(e.to_string());
        }
    }
    Ok(())
}
