//! Read and write a remote node's object dictionary over SDO, on a chosen port.
//!
//! ```text
//! cargo run --example sdo_tool --features udp,socketcan -- --port vcan0 --node 5 read 0x1018 1
//! cargo run --example sdo_tool --features udp -- --port udp:0 --node 5 write 0x1017 0 u16 100
//! cargo run --example sdo_tool --features udp -- --port udp --node 0x22 info
//! ```
//!
//! Ports: `udp` (python-can's default `udp_multicast` bus, loopback only), `udp:N` (test bus N:
//! group 239.74.163.(2+N), port 43113+N), `udp:GROUP:PORT`, or a SocketCAN interface name
//! (`can0`, `vcan0`; needs the `socketcan` feature). The tool is a bare SDO client: it sends
//! no boot-up and no heartbeat, only requests to the node's default SDO channel
//! (0x600/0x580 + node-ID).
//!
//! Numbers are decimal or `0x` hex, checked whole and against their range (`args.rs`); a bad
//! argument is an error that quotes it, never a panic.
//!
//! Exit status: 0 done, 1 the transfer failed (the message names node, object and the abort
//! code's meaning), 2 bad arguments or the port cannot be opened.

mod args;

use args::{
    encode, parse_index, parse_node, parse_sub, parse_timeout_ms, parse_udp, show, Type, UdpSpec,
};
use clap::{Parser, Subcommand};
use duocan::machine::Station;
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::{Handle, Runtime, RuntimeError};
use duocan::sdo::{SdoClient, SdoError, SdoErrorKind, SdoOptions};
use duocan::{AbortCode, Duration, NodeId};
use std::process::ExitCode;

type Device = Station<duocan::machine::SinglePort, SdoClient>;

#[derive(Parser)]
#[command(
    name = "sdo_tool",
    about = "Read and write a CANopen node's object dictionary over SDO (duocan)"
)]
struct Cli {
    /// Where the node is: `udp`, `udp:N`, `udp:GROUP:PORT`, or a SocketCAN interface (vcan0)
    #[arg(long, short)]
    port: String,
    /// The node's node-ID, 1-127 (decimal or 0x-prefixed hex)
    #[arg(long, short, value_parser = parse_node, allow_hyphen_values = true)]
    node: NodeId,
    /// How long to wait for each answer, in milliseconds (1 to 3600000)
    #[arg(long, default_value = "1000", value_parser = parse_timeout_ms)]
    timeout_ms: u64,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Read an entry: `read 0x1018 1`
    Read {
        /// Object index (0x-prefixed hex or decimal)
        #[arg(value_parser = parse_index)]
        index: u16,
        /// Sub-index
        #[arg(value_parser = parse_sub)]
        sub: u8,
        /// How to show the value
        #[arg(long = "type", short, value_enum, default_value_t = Type::Auto)]
        ty: Type,
    },
    /// Write an entry: `write 0x1017 0 u16 100`
    Write {
        /// Object index (0x-prefixed hex or decimal)
        #[arg(value_parser = parse_index)]
        index: u16,
        /// Sub-index
        #[arg(value_parser = parse_sub)]
        sub: u8,
        /// Data type of the value
        #[arg(value_enum)]
        ty: Type,
        /// The value (integers in decimal or 0x hex; `hex`: bytes like 01020a or "01 02 0a")
        #[arg(allow_hyphen_values = true)]
        value: String,
    },
    /// Identity of the node: device type, name, versions, 0x1018, heartbeat time
    Info,
}

/// Why the tool stopped.
enum Failure {
    /// Bad arguments or the port: exit 2.
    Setup(String),
    /// The transfer failed: exit 1.
    Sdo(SdoError),
}

impl From<RuntimeError> for Failure {
    fn from(e: RuntimeError) -> Self {
        match e {
            RuntimeError::Sdo(e) => Failure::Sdo(e),
            // The runtime stopped under the tool: nothing the node did.
            e => Failure::Setup(e.to_string()),
        }
    }
}

fn udp_config(spec: UdpSpec) -> UdpBusConfig {
    match spec {
        UdpSpec::Default => UdpBusConfig::python_can_default(),
        UdpSpec::Numbered(n) => UdpBusConfig::numbered(n),
        UdpSpec::Group(g, p) => UdpBusConfig::new(g, p),
    }
}

fn start(spec: &str) -> Result<Handle<Device>, Failure> {
    let device = Station::single(SdoClient::new(64 * 1024));
    let rt = Runtime::new(device).name("sdo_tool");
    let rt = match parse_udp(spec) {
        Some(udp) => {
            let cfg = udp_config(udp.map_err(Failure::Setup)?);
            let port = UdpPort::open(cfg).map_err(|e| Failure::Setup(e.to_string()))?;
            rt.port(port)
        }
        None => socketcan_port(rt, spec)?,
    };
    rt.spawn().map_err(|e| Failure::Setup(e.to_string()))
}

#[cfg(all(feature = "socketcan", target_os = "linux"))]
fn socketcan_port(rt: Runtime<Device>, ifname: &str) -> Result<Runtime<Device>, Failure> {
    let port = duocan::port::socketcan::SocketCanPort::open(ifname)
        .map_err(|e| Failure::Setup(e.to_string()))?;
    Ok(rt.port(port))
}

#[cfg(not(all(feature = "socketcan", target_os = "linux")))]
fn socketcan_port(_: Runtime<Device>, ifname: &str) -> Result<Runtime<Device>, Failure> {
    Err(Failure::Setup(format!(
        "port {ifname:?}: this build has no SocketCAN; use udp[:N|:GROUP:PORT], or rebuild with `--features udp,socketcan` (Linux)"
    )))
}

async fn read(h: &Handle<Device>, cli: &Cli, index: u16, sub: u8) -> Result<Vec<u8>, Failure> {
    let opts = SdoOptions::default().with_timeout(Duration::from_millis(cli.timeout_ms));
    Ok(h.sdo_read(cli.node, index, sub, opts).await?)
}

async fn run(cli: &Cli) -> Result<(), Failure> {
    let h = start(&cli.port)?;
    let r = match &cli.command {
        Command::Read { index, sub, ty } => read(&h, cli, *index, *sub).await.map(|data| {
            println!("{index:#06x}:{sub:02x} = {}", show(*ty, &data));
        }),
        Command::Write {
            index,
            sub,
            ty,
            value,
        } => match encode(*ty, value) {
            Err(e) => Err(Failure::Setup(e)),
            Ok(data) => {
                let opts =
                    SdoOptions::default().with_timeout(Duration::from_millis(cli.timeout_ms));
                let n = data.len();
                h.sdo_write(cli.node, *index, *sub, data, opts)
                    .await
                    .map_err(Failure::from)
                    .map(|()| println!("{index:#06x}:{sub:02x} written ({n} bytes)"))
            }
        },
        Command::Info => info(&h, cli).await,
    };
    h.shutdown().await;
    r
}

async fn info(h: &Handle<Device>, cli: &Cli) -> Result<(), Failure> {
    let rows: [(&str, u16, u8, Type); 9] = [
        ("device type", 0x1000, 0, Type::Auto),
        ("device name", 0x1008, 0, Type::Str),
        ("hardware version", 0x1009, 0, Type::Str),
        ("software version", 0x100A, 0, Type::Str),
        ("vendor-ID", 0x1018, 1, Type::Auto),
        ("product code", 0x1018, 2, Type::Auto),
        ("revision", 0x1018, 3, Type::Auto),
        ("serial number", 0x1018, 4, Type::Auto),
        ("heartbeat (ms)", 0x1017, 0, Type::U16),
    ];
    println!(
        "node {} ({:#04x}) on {}",
        cli.node.raw(),
        cli.node.raw(),
        cli.port
    );
    for (name, index, sub, ty) in rows {
        match read(h, cli, index, sub).await {
            Ok(d) => println!("  {name:<17} {}", show(ty, &d)),
            // Optional entries a node may not have.
            Err(Failure::Sdo(e))
                if matches!(
                    e.kind,
                    SdoErrorKind::Server(AbortCode::NO_OBJECT | AbortCode::NO_SUB_INDEX)
                ) =>
            {
                println!("  {name:<17} - (the node has no {index:#06x}:{sub:02x})")
            }
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let rt = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            eprintln!("sdo_tool: cannot start the async runtime: {e}");
            return ExitCode::from(2);
        }
    };
    match rt.block_on(run(&cli)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Sdo(e)) => {
            eprintln!("sdo_tool: {e}");
            ExitCode::from(1)
        }
        Err(Failure::Setup(msg)) => {
            eprintln!("sdo_tool: {msg}");
            ExitCode::from(2)
        }
    }
}
