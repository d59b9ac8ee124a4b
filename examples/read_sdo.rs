//! Read one object of one node: the vendor-ID (0x1018 sub 1) of node 5.
//!
//! ```text
//! cargo run --example read_sdo                                            # simulated nodes
//! DUOCAN_BUS=can0 cargo run --example read_sdo --features socketcan       # a real bus
//! ```
//!
//! `DUOCAN_BUS` names the port as `Network::open_named` takes it: `sim-nodes` (the default: an
//! in-memory bus with simulated nodes 1–10), `udp`, `udp:N`, or a SocketCAN interface.

use duocan::net::{NetError, Network};

/// Opens the port `DUOCAN_BUS` names (simulated nodes by default) and runs the example.
#[tokio::main]
pub async fn main() -> Result<(), NetError> {
    let port = std::env::var("DUOCAN_BUS").unwrap_or_else(|_| "sim-nodes".into());
    let net = Network::open_named(&port)?;
    let vendor: u32 = net.node(5).sdo().read(0x1018, 1).await?;
    println!("node 5 vendor-ID: {vendor:#010x}");
    Ok(())
}
