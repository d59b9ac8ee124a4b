//! Process data on the redundant master: configure a pair's board's TPDO, read its inputs
//! once (whichever bus carries them), and set its outputs by RPDO (sent on both buses).
//!
//! ```text
//! cargo run --example redundant_pdo                       # a simulated station
//! DUOCAN_BUS=can0,can1 cargo run --example redundant_pdo \
//!     --features socketcan,duocan-redundancy/socketcan    # two real buses
//! ```
//!
//! The boards are pair 0x10/0x50 with `duocan::net`'s simulated dictionary (inputs 0x6000 on
//! TPDO 1, outputs 0x6200 on RPDO 1), as the simulated station runs it.

use duocan::net::sim_description;
use duocan_redundancy::net::RedundantNetwork;
use std::error::Error;
use std::time::Duration;

/// Opens the ports `DUOCAN_BUS` names (a simulated station by default) and runs the example.
#[tokio::main]
pub async fn main() -> Result<(), Box<dyn Error>> {
    let port = std::env::var("DUOCAN_BUS").unwrap_or_else(|_| "sim-pairs".into());
    run(&port).await.map(|_| ())
}

/// Opens the network on `port`, waits for a board of pair 0x10/0x50 to run, prints its
/// inputs and sets its outputs; returns what its first output reads back.
pub async fn run(port: &str) -> Result<u16, Box<dyn Error>> {
    let net = RedundantNetwork::builder()
        .node_id(2)
        .pair(0x10, 0x50)
        .open_named(port)?;
    // The pair's inputs come from whichever of its boards runs.
    let id = net.running_board(0x10, Duration::from_secs(10)).await?;
    let board = net.add_node(id, sim_description()?);
    board.tpdo(1).edit(|t| t.event_timer_ms = Some(100)).await?;
    let inputs = board.wait_for_pdo(1, Duration::from_secs(2)).await?;
    println!("inputs: {inputs:?}");
    // Its outputs by RPDO (the mapping is read from the board first).
    board.rpdo(1).send(&[1234u16.into(), (-3i8).into()]).await?;
    let output = board.sdo().read::<u16>(0x6200, 1).await?;
    println!("outputs: {output}");
    net.close().await;
    Ok(output)
}
