//! `duocan`, the command-line tool: commission, watch and debug a single- or dual-bus CANopen
//! network from a terminal.
//!
//! ```text
//! duocan --bus sim-station scan               # the built-in simulated station
//! duocan --bus can0 sdo read 5 0x1018 1 u32
//! duocan --bus can0,can1 monitor              # two ports, one logical bus
//! duocan --bus udp nmt start all              # python-can's UDP bus
//! duocan --bus sim-station lss fastscan --assign 0x20 # LSS: boards without a node-ID get one
//! ```
//!
//! Exit status: 0 done, 1 the network did not do it (an abort code and its meaning, a node
//! that did not answer), 2 a usage error (a bad argument, an unreadable file), 3 a bus that
//! cannot be opened. With `--json` an error is a JSON object on standard error too
//! (`{"error": …, "exit": …}`). Every argument is parsed strictly (`args`); no input makes the
//! tool panic.

mod args;
mod bus;
mod cmd;
mod fail;
mod out;
mod ports;
mod progress;

use args::{parse_bus, parse_description, parse_timeout_ms};
use clap::{Parser, Subcommand};
use duocan::NodeId;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "duocan",
    version,
    about = "Commission, watch and debug a single- or dual-bus CANopen network",
    after_help = "Exit status: 0 done, 1 a protocol error (abort code, no answer), 2 usage, 3 no bus.\n\
                  Try it without hardware: duocan --bus sim-station scan"
)]
struct Cli {
    #[command(flatten)]
    global: Global,
    #[command(subcommand)]
    command: Command,
}

/// The options every command takes.
#[derive(clap::Args, Clone, Debug)]
pub struct Global {
    /// The bus: a SocketCAN interface (can0), two as one logical bus (can0,can1), python-can's
    /// UDP bus (udp, udp:N, udp:GROUP:PORT), or a built-in simulated network: `sim-station` (a
    /// redundant station on two buses), `sim-station:faults` (the same, failing and coming back),
    /// `sim-nodes` (one bus with nodes 1 to 10)
    #[arg(long, short, global = true, env = "DUOCAN_BUS", value_parser = bus_arg)]
    pub bus: Option<BusArg>,
    /// The address of the interface the UDP bus uses (default: loopback only)
    #[arg(long, global = true, value_name = "IPV4")]
    pub udp_interface: Option<std::net::Ipv4Addr>,
    /// Attach an EDS to a node: NODE=FILE (names and types for that node); repeatable
    #[arg(long, global = true, value_name = "NODE=FILE", value_parser = desc_arg)]
    pub eds: Vec<DescArg>,
    /// Attach a DCF: [NODE=]FILE (the node from the file's NodeID if not given); repeatable
    #[arg(long, global = true, value_name = "[NODE=]FILE", value_parser = desc_arg)]
    pub dcf: Vec<DescArg>,
    /// Print JSON instead of text (one value, or one object per line for streams)
    #[arg(long, global = true)]
    pub json: bool,
    /// How long to wait for each SDO answer, in milliseconds
    #[arg(long, global = true, default_value = "1000", value_parser = parse_timeout_ms, value_name = "MS")]
    pub timeout: u64,
    /// No progress bars or lines
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// The bus is a CANopen FD network (CiA 1301): reads and writes go over USDO in CAN FD
    /// frames, with this node-ID as the tool's own (one no node of the network has). The
    /// interface (or both, merged) is opened for CAN FD; every node must serve USDO
    #[arg(long, global = true, value_name = "NODE-ID", value_parser = crate::args::parse_node)]
    pub fd: Option<NodeId>,
}

/// The interfaces of `--bus`.
#[derive(Clone, Debug)]
pub struct BusArg(pub Vec<String>);

fn bus_arg(s: &str) -> Result<BusArg, String> {
    parse_bus(s).map(BusArg)
}

/// A description of `--eds`/`--dcf`: the node (if given) and the file.
#[derive(Clone, Debug)]
pub struct DescArg(pub Option<NodeId>, pub PathBuf);

fn desc_arg(s: &str) -> Result<DescArg, String> {
    parse_description(s).map(|(n, p)| DescArg(n, p))
}

#[derive(Subcommand)]
enum Command {
    /// Read or write a node's object dictionary over SDO
    #[command(subcommand)]
    Sdo(cmd::sdo::Sdo),
    /// Send an NMT command: start, stop, preop, reset, reset-comm
    Nmt(cmd::nmt::Args),
    /// Find the nodes on the network and print a table
    Scan(cmd::scan::Args),
    /// Layer setting services (CiA 305): give devices a node-ID and a bit rate by identity
    Lss(cmd::lss::Args),
    /// A live view of the network (plain lines when not on a terminal)
    Monitor(cmd::monitor::Args),
    /// Decode a candump log, a pcap, or the live bus into CANopen-aware lines
    Dump(cmd::dump::Args),
    /// Write what the bus carries to a candump log and/or a pcap
    Record(cmd::record::Args),
    /// Show or map a node's PDOs
    #[command(subcommand)]
    Pdo(cmd::pdo::Pdo),
    /// Check or export device descriptions (EDS/DCF)
    #[command(subcommand)]
    Eds(cmd::eds::Eds),
    /// Download a program to a node (CiA 302-3), with progress
    Flash(cmd::flash::Args),
    /// The CiA 309-3 ASCII gateway, on standard input, a loopback TCP port or a local socket
    Gateway(cmd::gateway::Args),
    /// Run a duocan board or redundant master on real interfaces (for failover tests)
    #[command(subcommand)]
    Device(cmd::device::Device),
    /// The failover test kit: scenarios of faults and what must happen
    #[command(subcommand)]
    Kit(cmd::kit::Kit),
    /// A whole station from a file: its redundant networks checked, or run until stopped
    #[command(subcommand)]
    Station(cmd::station::Station),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let rt = match tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("duocan: cannot start the async runtime: {e}");
            return ExitCode::from(1);
        }
    };
    let g = cli.global;
    let json = g.json;
    let r = rt.block_on(async move {
        match cli.command {
            Command::Sdo(c) => cmd::sdo::run(&g, c).await,
            Command::Nmt(a) => cmd::nmt::run(&g, a).await,
            Command::Scan(a) => cmd::scan::run(&g, a).await,
            Command::Lss(a) => cmd::lss::run(&g, a).await,
            Command::Monitor(a) => cmd::monitor::run(&g, a).await,
            Command::Dump(a) => cmd::dump::run(&g, a).await,
            Command::Record(a) => cmd::record::run(&g, a).await,
            Command::Pdo(c) => cmd::pdo::run(&g, c).await,
            Command::Eds(c) => cmd::eds::run(&g, c).await,
            Command::Flash(a) => cmd::flash::run(&g, a).await,
            Command::Gateway(a) => cmd::gateway::run(&g, a).await,
            Command::Kit(k) => cmd::kit::run(&g, k).await,
            Command::Device(d) => cmd::device::run(&g, d).await,
            Command::Station(s) => cmd::station::run(&g, s).await,
        }
    });
    match r {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) if json => {
            let error = serde_json::json!({ "error": f.to_string(), "exit": f.code() });
            eprintln!("{error}");
            ExitCode::from(f.code())
        }
        Err(f) => {
            eprintln!("duocan: {f}");
            ExitCode::from(f.code())
        }
    }
}
