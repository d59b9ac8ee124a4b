//! `duocan lss …`: the Layer Setting Services (CiA 305) — find devices by their identity and
//! give them a node-ID and a bit rate over the bus.
//!
//! ```text
//! duocan --bus sim-station lss fastscan --assign 0x20     # every board without a node-ID gets one
//! duocan --bus can0 lss switch config             # every slave to configuration mode
//! duocan --bus can0 lss select 0x2A 7 1 0x1234    # or just the one with this identity
//! duocan --bus can0 lss inquire                   # its identity and node-ID
//! duocan --bus can0 lss set-id 5 && duocan --bus can0 lss store
//! duocan --bus can0 lss switch waiting            # a new node-ID takes effect (reset-comm)
//! duocan --bus sim-station lss --select 0xD0CA00:0x305:1:2 inquire   # select and inquire in one run
//! ```
//!
//! The master is the library's LSS master behind the network handle
//! ([`duocan::net::Network::lss`]): its requests leave on every bus of `--bus` (both of a
//! dual bus), the answers come back merged. LSS keeps a slave's mode between requests, so each
//! command is one service, and a sequence of commands is a configuration session: the mode a
//! `switch` or `select` set holds until the next `switch`. `--select V:P:R:S` selects the slave
//! in the same run as inquire, set-id, set-bitrate or store and switches every slave back to
//! waiting at the end (on `--bus sim-station`, whose station starts afresh with every run, that is the
//! only way to reach them).
//!
//! Every service that expects an answer waits `--answer-ms` for it (50 ms by default; identify
//! always waits that long, since any number of slaves may answer); a fastscan step that was
//! answered ends `--settle-ms` after the last answer. Exit 1 when no slave answered or one
//! refused, with what to do.

mod fastscan;
pub mod parse;
pub mod slave;

use crate::args::parse_timeout_ms;
use crate::fail::Fail;
use crate::out::{self, Cell, Table};
use crate::{bus, Global};
use duocan::cia305::{IdentifyRange, Inquiry, LssAddress, LssMasterConfig, LssMode};
use duocan::net::NetLss;
use parse::{parse_address, parse_kbit, parse_lss_node, parse_part, parse_range};
use serde_json::json;

/// The arguments of `duocan lss`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    cmd: Lss,
    /// How long a service waits for the slave's answer, in milliseconds
    #[arg(long, global = true, default_value = "50", value_parser = parse_timeout_ms, value_name = "MS")]
    answer_ms: u64,
    /// Fastscan: how long an answered step waits for further answers, in milliseconds
    #[arg(long, global = true, default_value = "5", value_parser = parse_timeout_ms, value_name = "MS")]
    settle_ms: u64,
    /// inquire, set-id, set-bitrate, store: first switch the slave with this identity to
    /// configuration mode (switch state selective), in the same run
    #[arg(long, global = true, value_parser = parse_address, value_name = "VENDOR:PRODUCT:REVISION:SERIAL")]
    select: Option<LssAddress>,
}

/// The LSS modes `lss switch` takes.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Waiting: only switching, identification and fastscan are served
    Waiting,
    /// Configuration: node-ID, bit rate, store and inquiry are served too
    Config,
}

/// What `lss inquire` asks.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// Vendor-ID
    Vendor,
    /// Product code
    Product,
    /// Revision number
    Revision,
    /// Serial number
    Serial,
    /// The active node-ID
    NodeId,
    /// All five
    All,
}

/// `duocan lss` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum Lss {
    /// Switch every slave to waiting or configuration mode (switch state global)
    Switch {
        /// The mode
        #[arg(value_enum)]
        mode: Mode,
    },
    /// Switch the slave with this identity to configuration mode (switch state selective)
    Select {
        /// Vendor-ID (0x1018 sub 1)
        #[arg(value_parser = parse_part)]
        vendor: u32,
        /// Product code (sub 2)
        #[arg(value_parser = parse_part)]
        product: u32,
        /// Revision number (sub 3)
        #[arg(value_parser = parse_part)]
        revision: u32,
        /// Serial number (sub 4)
        #[arg(value_parser = parse_part)]
        serial: u32,
    },
    /// Ask the slave in configuration mode for its identity and node-ID
    Inquire {
        /// What to ask for
        #[arg(value_enum, default_value = "all")]
        part: Part,
    },
    /// Give the slave in configuration mode a node-ID: 1-127, or `none` (active at its next
    /// reset-communication, or at once when it had none and is switched to waiting)
    SetId {
        /// The node-ID
        #[arg(value_parser = parse_lss_node, value_name = "ID")]
        node: u8,
    },
    /// Give the slave in configuration mode a bit rate from the CiA 301 table
    SetBitrate {
        /// kbit/s: 1000, 800, 500, 250, 125, 50, 20 or 10
        #[arg(value_parser = parse_kbit, value_name = "KBIT")]
        rate: duocan::cia305::BitTiming,
        /// Then activate it: the slaves switch after DELAY_MS and speak after twice that
        #[arg(long, value_name = "DELAY_MS", value_parser = parse_delay)]
        activate: Option<u16>,
    },
    /// Have the slave in configuration mode store its node-ID and bit rate
    Store,
    /// Is any slave there: in the identity ranges given, or (--non-configured) without a
    /// node-ID?
    Identify {
        /// Any slave without a node-ID (instead of the ranges)
        #[arg(long, conflicts_with_all = ["vendor", "product", "revision", "serial"])]
        non_configured: bool,
        /// Vendor-ID, exact
        #[arg(value_parser = parse_part, required_unless_present = "non_configured")]
        vendor: Option<u32>,
        /// Product code, exact
        #[arg(value_parser = parse_part, required_unless_present = "non_configured")]
        product: Option<u32>,
        /// Revision numbers: LOW-HIGH or one
        #[arg(value_parser = parse_range, required_unless_present = "non_configured")]
        revision: Option<(u32, u32)>,
        /// Serial numbers: LOW-HIGH or one
        #[arg(value_parser = parse_range, required_unless_present = "non_configured")]
        serial: Option<(u32, u32)>,
    },
    /// Find every slave without a node-ID and give each one: from a plan, else the next free
    /// node-ID from --assign on
    Fastscan(fastscan::Args),
}

/// `--activate`: 1 to 65535 ms.
fn parse_delay(s: &str) -> Result<u16, String> {
    let v: u16 = crate::args::parse_unsigned(s, "a delay in milliseconds (1-65535)")?;
    if v == 0 {
        return Err(format!("{s}: give a delay of 1 to 65535 ms"));
    }
    Ok(v)
}

/// Runs `duocan lss`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    if let Lss::Fastscan(f) = &a.cmd {
        f.check()?;
    }
    let configures = matches!(
        a.cmd,
        Lss::Inquire { .. } | Lss::SetId { .. } | Lss::SetBitrate { .. } | Lss::Store
    );
    if a.select.is_some() && !configures {
        return Err(Fail::usage(
            "--select goes with inquire, set-id, set-bitrate and store",
        ));
    }
    let ms = duocan::Duration::from_millis;
    let cfg = LssMasterConfig::default()
        .with_timeout(ms(a.answer_ms))
        .with_settle(ms(a.settle_ms));
    let bus = bus::open_with(g, bus::options(g, false).with_lss(cfg))?;
    let r = match a.select {
        Some(address) => selected(g, &bus, address, a.cmd, &cfg).await,
        None => service(g, &bus, a.cmd, &cfg).await,
    };
    bus.close().await;
    r
}

/// `--select`: a configuration session in one run — the slave selected, the service, then every
/// slave back to waiting (a slave serves switch state selective in waiting mode only, so the
/// next run can select again; a slave that had no node-ID boots with the one just given).
async fn selected(
    g: &Global,
    bus: &bus::Bus,
    address: LssAddress,
    cmd: Lss,
    cfg: &LssMasterConfig,
) -> Result<(), Fail> {
    let lss = bus.net.lss();
    lss.switch_selective(address).await?;
    let r = service(g, bus, cmd, cfg).await;
    let back = lss.switch_global(LssMode::Waiting).await;
    r?;
    Ok(back?)
}

async fn service(g: &Global, bus: &bus::Bus, cmd: Lss, cfg: &LssMasterConfig) -> Result<(), Fail> {
    let lss = bus.net.lss();
    match cmd {
        Lss::Switch { mode } => {
            let (m, name) = match mode {
                Mode::Waiting => (LssMode::Waiting, "waiting"),
                Mode::Config => (LssMode::Configuration, "configuration"),
            };
            lss.switch_global(m).await?;
            let text = format!("every slave switched to {name} mode");
            out::result(g.json, &text, json!({"switched": name}));
        }
        Lss::Select {
            vendor,
            product,
            revision,
            serial,
        } => {
            let address = LssAddress {
                vendor,
                product,
                revision,
                serial,
            };
            lss.switch_selective(address).await?;
            let text = format!("{address}: in configuration mode");
            out::result(g.json, &text, json!({"selected": address_json(&address)}));
        }
        Lss::Inquire { part } => inquire(g, &lss, part).await?,
        Lss::SetId { node } => {
            lss.configure_node_id(node).await?;
            let shown = if node == 0xFF {
                "none".into()
            } else {
                format!("{node:#04x}")
            };
            let text = format!(
                "node-ID {shown} configured (active at the slave's next reset-communication)"
            );
            let v = if node == 0xFF {
                json!(null)
            } else {
                json!(node)
            };
            out::result(g.json, &text, json!({"node_id": v}));
        }
        Lss::SetBitrate { rate, activate } => {
            lss.configure_bit_timing(rate).await?;
            let kbit = rate.kbit().unwrap_or(0);
            let mut text = format!("bit rate {kbit} kbit/s configured");
            if let Some(d) = activate {
                lss.activate_bit_timing(d).await?;
                text.push_str(&format!(
                    "; activated: the slaves switch in {d} ms and speak again after {} ms: switch this bus to {kbit} kbit/s too",
                    u32::from(d) * 2
                ));
            }
            out::result(
                g.json,
                &text,
                json!({"kbit": kbit, "activate_ms": activate}),
            );
        }
        Lss::Store => {
            lss.store().await?;
            out::result(g.json, "configuration stored", json!({"stored": true}));
        }
        Lss::Identify {
            non_configured: true,
            ..
        } => {
            let heard = lss.identify_non_configured().await?;
            let text = if heard {
                "a slave without a node-ID answered"
            } else {
                "no slave without a node-ID answered"
            };
            out::result(g.json, text, json!({"answered": heard}));
        }
        Lss::Identify {
            vendor,
            product,
            revision,
            serial,
            ..
        } => {
            // clap requires all four without --non-configured.
            let (Some(vendor), Some(product), Some((rl, rh)), Some((sl, sh))) =
                (vendor, product, revision, serial)
            else {
                return Err(Fail::usage(
                    "give VENDOR PRODUCT REVISION SERIAL, or --non-configured",
                ));
            };
            let range = IdentifyRange {
                vendor,
                product,
                revision_low: rl,
                revision_high: rh,
                serial_low: sl,
                serial_high: sh,
            };
            let heard = lss.identify_remote(range).await?;
            let text = if heard {
                "a slave in the ranges answered"
            } else {
                "no slave in the ranges answered"
            };
            out::result(g.json, text, json!({"answered": heard}));
        }
        Lss::Fastscan(f) => fastscan::run(g, &bus.net, f, cfg).await?,
    }
    Ok(())
}

/// An identity as JSON.
pub fn address_json(a: &LssAddress) -> serde_json::Value {
    json!({"vendor": a.vendor, "product": a.product, "revision": a.revision, "serial": a.serial})
}

async fn inquire(g: &Global, lss: &NetLss, part: Part) -> Result<(), Fail> {
    let all = [
        (Part::Vendor, Inquiry::Vendor, "vendor"),
        (Part::Product, Inquiry::Product, "product"),
        (Part::Revision, Inquiry::Revision, "revision"),
        (Part::Serial, Inquiry::Serial, "serial"),
        (Part::NodeId, Inquiry::NodeId, "node-id"),
    ];
    let mut t = Table::new(&["part", "value"]);
    let mut obj = serde_json::Map::new();
    for (p, q, name) in all
        .into_iter()
        .filter(|(p, _, _)| part == Part::All || part == *p)
    {
        let v = lss.inquire(q).await?;
        let (text, value) = match (p, v & 0xFF) {
            (Part::NodeId, 0xFF) => ("none".to_string(), serde_json::Value::Null),
            (Part::NodeId, n) => (format!("{n:#04x}"), json!(n)),
            _ => (format!("{v:#010x}"), json!(v)),
        };
        obj.insert(name.replace('-', "_"), value.clone());
        t.row(vec![name.into(), Cell::new(text, value)]);
    }
    if g.json {
        out::emit_json(&serde_json::Value::Object(obj));
    } else {
        t.print(false);
    }
    Ok(())
}
