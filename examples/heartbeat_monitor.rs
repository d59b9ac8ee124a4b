//! Watch nodes 1–10 without being seen: print boot-ups, state changes and lost heartbeats.
//!
//! ```text
//! cargo run --example heartbeat_monitor                                       # simulated nodes
//! DUOCAN_PORT=can0 cargo run --example heartbeat_monitor --features socketcan  # a real bus
//! ```
//!
//! The network is listen-only: it sends no boot-up, answers no NMT command and puts no frame on
//! the bus. A node silent for 500 ms is reported lost. Stop with Ctrl-C.

use duocan::net::{NetError, NetEvent, Network};
use std::time::Duration;

/// Opens the port `DUOCAN_PORT` names (simulated nodes by default) and runs the example.
#[tokio::main]
pub async fn main() -> Result<(), NetError> {
    let port = std::env::var("DUOCAN_PORT").unwrap_or_else(|_| "sim".into());
    monitor(Network::monitor_named(&port)?, |line| println!("{line}")).await
}

/// Hands `print` one line per boot-up, state change, lost or returning heartbeat of nodes
/// 1–10, until the network closes.
pub async fn monitor(net: Network, mut print: impl FnMut(String)) -> Result<(), NetError> {
    let mut events = net.events();
    for id in 1..=10 {
        net.node(id)
            .watch_heartbeat(Duration::from_millis(500))
            .await?;
    }
    while let Some(e) = events.next().await {
        let node = e.node().map_or(0, |n| n.raw());
        match e {
            NetEvent::BootUp { .. } => print(format!("node {node}: boot-up")),
            NetEvent::State { to, .. } => print(format!("node {node}: {to}")),
            NetEvent::HeartbeatLost { .. } => print(format!("node {node}: heartbeat lost")),
            NetEvent::HeartbeatResumed { .. } => print(format!("node {node}: heartbeat back")),
            NetEvent::Lagged(n) => print(format!("{n} events missed")),
            _ => {}
        }
    }
    Ok(())
}
