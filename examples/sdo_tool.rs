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
//! Exit status: 0 done, 1 the transfer failed (the message names node, object and the abort
//! code's meaning), 2 bad arguments or the port cannot be opened.

use clap::{Parser, Subcommand, ValueEnum};
use duocan::machine::Station;
use duocan::port::udp::{UdpBusConfig, UdpPort};
use duocan::runtime::{Handle, Runtime, RuntimeError};
use duocan::sdo::{SdoClient, SdoError, SdoErrorKind, SdoOptions};
use duocan::{AbortCode, Duration, NodeId};
use std::net::Ipv4Addr;
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
    #[arg(long, short, value_parser = parse_node)]
    node: NodeId,
    /// How long to wait for each answer, in milliseconds
    #[arg(long, default_value_t = 1000)]
    timeout_ms: u64,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Read an entry: `read 0x1018 1`
    Read {
        /// Object index (0x-prefixed hex or decimal)
        #[arg(value_parser = parse_u16)]
        index: u16,
        /// Sub-index
        #[arg(value_parser = parse_u8)]
        sub: u8,
        /// How to show the value
        #[arg(long = "type", short, value_enum, default_value_t = Type::Auto)]
        ty: Type,
    },
    /// Write an entry: `write 0x1017 0 u16 100`
    Write {
        /// Object index (0x-prefixed hex or decimal)
        #[arg(value_parser = parse_u16)]
        index: u16,
        /// Sub-index
        #[arg(value_parser = parse_u8)]
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

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum Type {
    /// Bytes in hex, and the unsigned value for 1, 2, 4 or 8 bytes
    Auto,
    U8,
    U16,
    U32,
    U64,
    I8,
    I16,
    I32,
    I64,
    F32,
    /// Visible string
    Str,
    /// Raw bytes
    Hex,
}

fn parse_int(s: &str) -> Result<i128, String> {
    let t = s.trim();
    let (neg, t) = match t.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, t),
    };
    let v = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(h) => i128::from_str_radix(h, 16),
        None => t.parse::<i128>(),
    }
    .map_err(|_| format!("{s:?} is not a number (decimal, or hex with 0x)"))?;
    Ok(if neg { -v } else { v })
}

fn parse_u16(s: &str) -> Result<u16, String> {
    let v = parse_int(s)?;
    u16::try_from(v).map_err(|_| format!("{s} does not fit an object index (0-0xFFFF)"))
}

fn parse_u8(s: &str) -> Result<u8, String> {
    let v = parse_int(s)?;
    u8::try_from(v).map_err(|_| format!("{s} does not fit a sub-index (0-255)"))
}

fn parse_node(s: &str) -> Result<NodeId, String> {
    let v = parse_int(s)?;
    u8::try_from(v)
        .ok()
        .and_then(NodeId::new)
        .ok_or_else(|| format!("node-ID {s}: a node-ID is 1-127"))
}

/// The bytes to write for `value` as `ty`.
fn encode(ty: Type, value: &str) -> Result<Vec<u8>, String> {
    fn int<T: TryFrom<i128>>(
        value: &str,
        name: &str,
        le: impl Fn(T) -> Vec<u8>,
    ) -> Result<Vec<u8>, String> {
        let v = parse_int(value)?;
        T::try_from(v)
            .map(le)
            .map_err(|_| format!("{value} does not fit {name}"))
    }
    match ty {
        Type::U8 => int::<u8>(value, "u8", |v| v.to_le_bytes().to_vec()),
        Type::U16 => int::<u16>(value, "u16", |v| v.to_le_bytes().to_vec()),
        Type::U32 => int::<u32>(value, "u32", |v| v.to_le_bytes().to_vec()),
        Type::U64 => int::<u64>(value, "u64", |v| v.to_le_bytes().to_vec()),
        Type::I8 => int::<i8>(value, "i8", |v| v.to_le_bytes().to_vec()),
        Type::I16 => int::<i16>(value, "i16", |v| v.to_le_bytes().to_vec()),
        Type::I32 => int::<i32>(value, "i32", |v| v.to_le_bytes().to_vec()),
        Type::I64 => int::<i64>(value, "i64", |v| v.to_le_bytes().to_vec()),
        Type::F32 => value
            .trim()
            .parse::<f32>()
            .map(|v| v.to_le_bytes().to_vec())
            .map_err(|_| format!("{value:?} is not a number")),
        Type::Str => Ok(value.as_bytes().to_vec()),
        Type::Hex | Type::Auto => {
            let digits: String = value.chars().filter(|c| !c.is_whitespace()).collect();
            let digits = digits.strip_prefix("0x").unwrap_or(&digits);
            if digits.is_empty() || !digits.len().is_multiple_of(2) {
                return Err(format!("{value:?}: give whole bytes in hex, like 01020a"));
            }
            (0..digits.len())
                .step_by(2)
                .map(|i| {
                    u8::from_str_radix(&digits[i..i + 2], 16)
                        .map_err(|_| format!("{value:?} is not hex"))
                })
                .collect()
        }
    }
}

/// How a value read shows.
fn show(ty: Type, data: &[u8]) -> String {
    fn fixed<const N: usize>(data: &[u8]) -> Option<[u8; N]> {
        data.try_into().ok()
    }
    let hex = data
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect::<Vec<_>>()
        .join(" ");
    let wrong = || format!("[{hex}] ({} bytes: not this type)", data.len());
    match ty {
        Type::Auto => {
            let unsigned = match data.len() {
                1 | 2 | 4 | 8 => {
                    let mut b = [0u8; 8];
                    b[..data.len()].copy_from_slice(data);
                    let v = u64::from_le_bytes(b);
                    format!(" = {v} ({v:#0w$x})", w = 2 + 2 * data.len())
                }
                _ => String::new(),
            };
            let text = match std::str::from_utf8(data) {
                Ok(s) if data.len() > 1 && s.chars().all(|c| !c.is_control()) => {
                    format!(" {s:?}")
                }
                _ => String::new(),
            };
            format!("[{hex}]{unsigned}{text}")
        }
        Type::U8 => fixed::<1>(data).map_or_else(wrong, |b| u8::from_le_bytes(b).to_string()),
        Type::U16 => fixed::<2>(data).map_or_else(wrong, |b| u16::from_le_bytes(b).to_string()),
        Type::U32 => fixed::<4>(data).map_or_else(wrong, |b| u32::from_le_bytes(b).to_string()),
        Type::U64 => fixed::<8>(data).map_or_else(wrong, |b| u64::from_le_bytes(b).to_string()),
        Type::I8 => fixed::<1>(data).map_or_else(wrong, |b| i8::from_le_bytes(b).to_string()),
        Type::I16 => fixed::<2>(data).map_or_else(wrong, |b| i16::from_le_bytes(b).to_string()),
        Type::I32 => fixed::<4>(data).map_or_else(wrong, |b| i32::from_le_bytes(b).to_string()),
        Type::I64 => fixed::<8>(data).map_or_else(wrong, |b| i64::from_le_bytes(b).to_string()),
        Type::F32 => fixed::<4>(data).map_or_else(wrong, |b| f32::from_le_bytes(b).to_string()),
        Type::Str => String::from_utf8_lossy(data).into_owned(),
        Type::Hex => hex,
    }
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

fn udp_config(spec: &str) -> Result<UdpBusConfig, String> {
    let rest = spec.strip_prefix("udp").unwrap_or(spec);
    let parts: Vec<&str> = rest.split(':').skip(1).collect();
    match parts.as_slice() {
        [] => Ok(UdpBusConfig::python_can_default()),
        [n] => n
            .parse::<u8>()
            .map(UdpBusConfig::numbered)
            .map_err(|_| format!("{spec}: udp:N takes a bus number 0-255")),
        [group, port] => {
            let g: Ipv4Addr = group
                .parse()
                .map_err(|_| format!("{spec}: {group} is not an IPv4 address"))?;
            let p: u16 = port
                .parse()
                .map_err(|_| format!("{spec}: {port} is not a UDP port"))?;
            Ok(UdpBusConfig::new(g, p))
        }
        _ => Err(format!("{spec}: use udp, udp:N or udp:GROUP:PORT")),
    }
}

fn start(spec: &str) -> Result<Handle<Device>, Failure> {
    let device = Station::single(SdoClient::new(64 * 1024));
    let rt = Runtime::new(device).name("sdo_tool");
    let rt = if spec == "udp" || spec.starts_with("udp:") {
        let cfg = udp_config(spec).map_err(Failure::Setup)?;
        let port = UdpPort::open(cfg).map_err(|e| Failure::Setup(e.to_string()))?;
        rt.port(port)
    } else {
        socketcan_port(rt, spec)?
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
