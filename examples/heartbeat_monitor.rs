//! Watch nodes 1–10 without being seen: print boot-ups, state changes and lost heartbeats.
//!
//! ```text
//! cargo run --example heartbeat_monitor                                       # simulated nodes
//! DUOCAN_BUS=can0 cargo run --example heartbeat_monitor --features socketcan   # a real bus
//! ```
//!
//! The network is listen-only: it sends no boot-up, answers no NMT command and puts no frame on
//! the bus. A node silent for 500 ms is reported lost, one not heard at all for 500 ms too.
//! Stop with Ctrl-C.

use duocan::net::{NetError, Network};
use std::time::Duration;

/// Opens the port `DUOCAN_BUS` names (simulated nodes by default) and runs the example.
#[tokio::main]
pub async fn main() -> Result<(), NetError> {
    let port = std::env::var("DUOCAN_BUS").unwrap_or_else(|_| "sim-nodes".into());
    monitor(Network::monitor_named(&port)?, |line| println!("{line}")).await
}

/// Hands `print` one line per event (boot-ups, state changes, lost and returning heartbeats of
/// nodes 1–10, EMCY, …) until the network closes.
pub async fn monitor(net: Network, mut print: impl FnMut(String)) -> Result<(), NetError> {
    let mut events = net.events();
    let timeout = Duration::from_millis(500);
    for id in 1..=10 {
        net.node(id).watch_heartbeat(timeout).await?;
    }
    while let Some(e) = events.next().await {
        print(e.to_string());
    }
    Ok(())
}
