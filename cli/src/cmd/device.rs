//! `duocan device board|master|lss-slave`: a duocan device on real interfaces, until stopped — what the
//! failover kit starts as the boards and the master of a scenario, and what an integrator
//! starts by hand beside devices that are not duocan's.
//!
//! ```text
//! duocan --bus vs1a,vs2a device board --node 0x10
//! duocan --bus vm1a,vm2a device master --node 1 --pair 0x10,0x50 --peer 2
//! ```
//!
//! A board is a CiA 301 slave on the dual-bus layer (one member of an A/B pair: identity with
//! the vendor-ID of duocan's simulated devices and the node-ID as product code, heartbeat
//! every `--heartbeat-ms`); a master is the CiA 302-2 redundant master with the pair
//! supervisor and the flying master, printing each of its events as a line. Both run until
//! interrupted (SIGINT, SIGTERM) or `--duration-ms` has passed.

use crate::args::{parse_node, parse_timeout_ms};
use crate::fail::Fail;
use crate::{ports, Global};
use duocan::od::{comm, ObjectDictionary};
use duocan::runtime::Runtime;
use duocan::{Duration, Instant, Node, NodeConfig, NodeId, Station};
use duocan_redundancy::net::RedundantNetwork;
use duocan_redundancy::RedundantNetworkBuilder;
use duocan_redundancy::{DualBus, DualBusConfig};

/// `duocan device` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum Device {
    /// A redundant board: a CiA 301 slave on both buses of `--bus A,B`
    Board {
        /// Its node-ID
        #[arg(long, value_parser = parse_node)]
        node: NodeId,
        /// Its heartbeat period (0x1017), ms
        #[arg(long, default_value = "50", value_parser = parse_timeout_ms)]
        heartbeat_ms: u64,
        /// Stop after this long (default: run until interrupted)
        #[arg(long, value_parser = parse_timeout_ms)]
        duration_ms: Option<u64>,
    },
    /// A device with an LSS slave (CiA 305), without a node-ID until a master gives it one,
    /// on one bus or two (`--bus udp`, `--bus can0,can1`)
    LssSlave(crate::cmd::lss::slave::Args),
    /// A redundant master: CiA 302-2, A/B pair supervisor, flying master, on `--bus A,B`
    Master {
        /// Its node-ID
        #[arg(long, value_parser = parse_node)]
        node: NodeId,
        /// An A/B pair it supervises: A,B (node-IDs); repeatable
        #[arg(long, value_parser = parse_pair)]
        pair: Vec<(u8, u8)>,
        /// Another master of the network (flying master); repeatable
        #[arg(long, value_parser = parse_node)]
        peer: Vec<NodeId>,
        /// Its flying-master priority (lower wins)
        #[arg(long, default_value = "0")]
        priority: u8,
        /// Its heartbeat period, ms (and the pair members')
        #[arg(long, default_value = "50", value_parser = parse_timeout_ms)]
        heartbeat_ms: u64,
        /// How long a master or a pair member may be silent before it has failed, ms
        #[arg(long, default_value = "150", value_parser = parse_timeout_ms)]
        timeout_ms: u64,
        /// Stop after this long (default: run until interrupted)
        #[arg(long, value_parser = parse_timeout_ms)]
        duration_ms: Option<u64>,
    },
}

/// An A/B pair: `A,B`.
fn parse_pair(s: &str) -> Result<(u8, u8), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("{s:?}: give a pair as A,B (two node-IDs)"))?;
    let (a, b) = (parse_node(a)?, parse_node(b)?);
    if a == b {
        return Err(format!("{s}: the members of a pair differ"));
    }
    Ok((a.raw(), b.raw()))
}

/// The two interfaces of `--bus`.
fn two(g: &Global) -> Result<[String; 2], Fail> {
    match g.bus.as_ref().map(|b| b.0.as_slice()) {
        Some([a, b]) => Ok([a.clone(), b.clone()]),
        _ => Err(Fail::usage("a device runs on two interfaces: --bus A,B")),
    }
}

/// Waits for `duration_ms`, or for SIGINT/SIGTERM.
pub async fn until_stopped(duration_ms: Option<u64>) -> Result<(), Fail> {
    let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())?;
    let timer = async {
        match duration_ms {
            Some(ms) => tokio::time::sleep(std::time::Duration::from_millis(ms)).await,
            None => std::future::pending().await,
        }
    };
    tokio::select! {
        () = timer => {}
        _ = tokio::signal::ctrl_c() => {}
        _ = term.recv() => {}
    }
    Ok(())
}

/// A duocan board: node `node`, heartbeat every `heartbeat_ms`, booted at `at`.
pub fn board(node: NodeId, heartbeat_ms: u64, at: Instant) -> Result<Board, Fail> {
    let ident = comm::Identity {
        vendor: duocan::net::SIM_VENDOR,
        product: u32::from(node.raw()),
        ..Default::default()
    };
    let mut od = comm::standard_dictionary(node.raw(), ident);
    let hb =
        u16::try_from(heartbeat_ms).map_err(|_| Fail::usage("--heartbeat-ms: at most 65535"))?;
    let _ = od.write_local(comm::HEARTBEAT_PRODUCER, 0, &hb.to_le_bytes());
    let mut n = Node::new(NodeConfig::slave(node), od);
    n.boot(at);
    Ok(Station::new(DualBus::new(DualBusConfig::default()), n))
}

/// The builder of a duocan redundant master with these settings.
pub fn master(
    node: NodeId,
    pairs: &[(u8, u8)],
    peers: &[NodeId],
    priority: u8,
    heartbeat_ms: u64,
    timeout_ms: u64,
) -> RedundantNetworkBuilder {
    let ms = Duration::from_millis;
    let mut bld = RedundantNetwork::builder()
        .node_id(node.raw())
        .priority(priority)
        .heartbeat(ms(heartbeat_ms))
        .master_timeout(ms(timeout_ms))
        .pair_heartbeat(ms(heartbeat_ms))
        .pair_timeout(ms(timeout_ms));
    for &(x, y) in pairs {
        bld = bld.pair(x, y);
    }
    for p in peers {
        bld = bld.peer_master(p.raw());
    }
    bld
}

/// A duocan board as [`board`] builds it.
pub type Board = duocan_redundancy::DualBusNode<duocan::od::DynamicDictionary>;

/// Runs `duocan device`.
pub async fn run(g: &Global, d: Device) -> Result<(), Fail> {
    if let Device::LssSlave(a) = d {
        return crate::cmd::lss::slave::run(g, a).await;
    }
    let [a, b] = two(g)?;
    let (pa, pb) = (
        ports::open(&a, g.udp_interface)?,
        ports::open(&b, g.udp_interface)?,
    );
    match d {
        Device::Board {
            node,
            heartbeat_ms,
            duration_ms,
        } => {
            let board = board(node, heartbeat_ms, Instant::ZERO)?;
            let h = Runtime::boxed(Box::new(board))
                .name(format!("board {:#04x}", node.raw()))
                .port(pa)
                .port(pb)
                .spawn()
                .map_err(|e| Fail::usage(e.to_string()))?;
            eprintln!("board {:#04x} on {a},{b}", node.raw());
            until_stopped(duration_ms).await?;
            h.shutdown().await;
            Ok(())
        }
        Device::Master {
            node,
            pair,
            peer,
            priority,
            heartbeat_ms,
            timeout_ms,
            duration_ms,
        } => {
            let bld = master(node, &pair, &peer, priority, heartbeat_ms, timeout_ms);
            let net = bld.open(pa, pb).map_err(|e| Fail::usage(e.to_string()))?;
            eprintln!("master {:#04x} on {a},{b}", node.raw());
            let mut events = net.events();
            let printing = async {
                while let Some(e) = events.next().await {
                    println!("{e}");
                }
            };
            tokio::select! {
                () = printing => {}
                r = until_stopped(duration_ms) => r?,
            }
            net.close().await;
            Ok(())
        }
        Device::LssSlave(_) => Err(Fail::usage("lss-slave runs above")),
    }
}
