//! `duocan pdo show NODE` and `duocan pdo map NODE tpdo|rpdo N …`: a node's PDO configuration,
//! read and changed over SDO.
//!
//! `show` reads every TPDO and RPDO the node has (those its description lists; without one,
//! PDO 1, 2, … up to the first the node does not have) with the library's
//! `RemoteNode::read_pdos`: COB-ID, enabled, transmission type, inhibit time, event timer and
//! the mapped entries, each as index:sub, bit length and its name in the description.
//!
//! `map` reads one PDO, changes what the options say (`--clear` first, then each `--add` in
//! order, then the communication parameters), and saves it the way CiA 301 requires: the PDO
//! disabled (COB-ID bit 31), the parameters and the mapping written (count 0, the entries, the
//! count), then enabled again as asked (`RemotePdo::save`; with `--store`, 0x1010 sub 1 "save"
//! after it). It then reads the PDO back over SDO and prints what the node holds now, so the
//! result shown is the node's, not the request's.
//!
//! `--add` takes `INDEX:SUB:BITS` (`0x6000:1:16`), `INDEX:SUB` (the length from the node's
//! description), or a name from the description (`"Input 1"`, `"Inputs.Status"`), optionally
//! with `:BITS`.

use crate::args::{parse_index, parse_node, parse_sub, parse_unsigned};
use crate::bus::{self, Bus};
use crate::fail::Fail;
use crate::out::{self, node_cell, Cell, Table};
use crate::Global;
use duocan::net::{PdoMap, RemoteNode};
use duocan::pdo::Dir;
use duocan::{CobId, NodeId};
use serde_json::{json, Value};

/// The subcommands of `duocan pdo`.
#[derive(clap::Subcommand, Debug)]
pub enum Pdo {
    /// Read and print a node's TPDOs and RPDOs: `pdo show 5`
    Show {
        /// The node-ID (1-127)
        #[arg(value_parser = parse_node)]
        node: NodeId,
    },
    /// Change one PDO's mapping and parameters, and print what the node holds afterwards:
    /// `pdo map 5 tpdo 2 --clear --add "Input 2" --add 0x6000:3:8 --trans-type 254 --enable`
    Map(MapArgs),
}

/// Which side of the node.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// One of the node's transmit PDOs
    Tpdo,
    /// One of the node's receive PDOs
    Rpdo,
}

/// The arguments of `pdo map`.
#[derive(clap::Args, Debug)]
pub struct MapArgs {
    /// The node-ID (1-127)
    #[arg(value_parser = parse_node)]
    node: NodeId,
    /// tpdo or rpdo
    #[arg(value_enum)]
    side: Side,
    /// The PDO number (1-512)
    #[arg(value_parser = parse_pdo_number)]
    pdo: u16,
    /// Empty the mapping first
    #[arg(long)]
    clear: bool,
    /// Map an entry next: INDEX:SUB:BITS, INDEX:SUB, or a name from the description (NAME,
    /// NAME:BITS); repeatable, in order
    #[arg(long, value_name = "ENTRY")]
    add: Vec<String>,
    /// Transmission type: 0 acyclic synchronous, 1-240 every n-th SYNC, 254/255 event-driven
    #[arg(long, value_name = "T", value_parser = parse_u8)]
    trans_type: Option<u8>,
    /// Event timer in milliseconds (TPDO: period; RPDO: reception timeout; 0 off)
    #[arg(long, value_name = "MS", value_parser = parse_u16)]
    event_timer: Option<u16>,
    /// Inhibit time in units of 100 µs (TPDO)
    #[arg(long, value_name = "N", value_parser = parse_u16)]
    inhibit: Option<u16>,
    /// The COB-ID (CAN identifier; bit 31 is set by --enable/--disable)
    #[arg(long, value_name = "ID", value_parser = parse_u32)]
    cob_id: Option<u32>,
    /// Enable the PDO (the default: as it was)
    #[arg(long, conflicts_with = "disable")]
    enable: bool,
    /// Disable the PDO
    #[arg(long)]
    disable: bool,
    /// Store the parameters on the node afterwards (0x1010 sub 1), to survive a power cycle
    #[arg(long)]
    store: bool,
}

fn parse_pdo_number(s: &str) -> Result<u16, String> {
    let n: u16 = parse_unsigned(s, "a PDO number (1-512)")?;
    if !(1..=512).contains(&n) {
        return Err(format!("PDO {n}: give 1 to 512"));
    }
    Ok(n)
}

fn parse_u8(s: &str) -> Result<u8, String> {
    parse_unsigned(s, "0-255")
}

fn parse_u16(s: &str) -> Result<u16, String> {
    parse_unsigned(s, "0-65535")
}

fn parse_u32(s: &str) -> Result<u32, String> {
    parse_unsigned(s, "32 bits")
}

/// What one `--add` names.
#[derive(Debug, PartialEq, Eq)]
enum Add {
    /// Index, sub-index and bits (from the description if not given).
    At(u16, u8, Option<u8>),
    /// A name from the description, and bits if given.
    Named(String, Option<u8>),
}

/// Parses one `--add`: strict numbers, a name for anything that does not start with a digit.
fn parse_add(s: &str) -> Result<Add, String> {
    let bits = |b: &str| -> Result<u8, String> {
        let n: u8 = parse_unsigned(b, "a bit length (1-64)")?;
        if !(1..=64).contains(&n) {
            return Err(format!("{n} bits: give 1 to 64"));
        }
        Ok(n)
    };
    if s.starts_with(|c: char| c.is_ascii_digit()) {
        let parts: Vec<&str> = s.split(':').collect();
        return match parts.as_slice() {
            [i, sub] => Ok(Add::At(parse_index(i)?, parse_sub(sub)?, None)),
            [i, sub, b] => Ok(Add::At(parse_index(i)?, parse_sub(sub)?, Some(bits(b)?))),
            _ => Err(format!(
                "{s:?}: give INDEX:SUB:BITS (0x6000:1:16), INDEX:SUB, or a name"
            )),
        };
    }
    match s.rsplit_once(':') {
        Some((name, b)) if b.starts_with(|c: char| c.is_ascii_digit()) && !name.is_empty() => {
            Ok(Add::Named(name.to_string(), Some(bits(b)?)))
        }
        _ if s.trim().is_empty() => Err("--add needs an entry".into()),
        _ => Ok(Add::Named(s.to_string(), None)),
    }
}

/// Runs `duocan pdo`.
pub async fn run(g: &Global, c: Pdo) -> Result<(), Fail> {
    let bus = bus::open(g, false)?;
    let r = match c {
        Pdo::Show { node } => show(g, &bus, node).await,
        Pdo::Map(a) => map(g, &bus, a).await,
    };
    bus.close().await;
    r
}

async fn show(g: &Global, bus: &Bus, id: NodeId) -> Result<(), Fail> {
    let node = bus.net.node(id.raw());
    let mut maps = node.read_pdos(Dir::Transmit).await?;
    maps.extend(node.read_pdos(Dir::Receive).await?);
    print(g, &maps);
    Ok(())
}

async fn map(g: &Global, bus: &Bus, a: MapArgs) -> Result<(), Fail> {
    // Parsed before anything is sent: a bad --add changes nothing on the node.
    let adds = a
        .add
        .iter()
        .map(|s| parse_add(s).map_err(Fail::usage))
        .collect::<Result<Vec<_>, _>>()?;
    let node = bus.net.node(a.node.raw());
    let pdo = match a.side {
        Side::Tpdo => node.tpdo(a.pdo),
        Side::Rpdo => node.rpdo(a.pdo),
    };
    let mut m = pdo.read().await?;
    if a.clear {
        m.clear();
    }
    for add in &adds {
        apply_add(&node, &mut m, add)?;
    }
    if let Some(t) = a.trans_type {
        m.transmission_type = t;
    }
    if let Some(ms) = a.event_timer {
        m.event_timer_ms = Some(ms);
    }
    if let Some(n) = a.inhibit {
        if a.side == Side::Rpdo {
            return Err(Fail::usage("--inhibit is a TPDO parameter"));
        }
        m.inhibit_100us = Some(n);
    }
    if let Some(id) = a.cob_id {
        m.cob_id = CobId(id & !CobId::INVALID);
    }
    if a.enable {
        m.enabled = true;
    } else if a.disable {
        m.enabled = false;
    }
    if a.store {
        pdo.save_and_store(&m).await?;
    } else {
        pdo.save(&m).await?;
    }
    // What the node holds now, read back over SDO.
    let back = pdo.read().await?;
    print(g, &[back]);
    Ok(())
}

/// Adds one entry; what the mapping cannot take (too many bits, an unknown name) is the
/// command line's fault: nothing was written yet.
fn apply_add(node: &RemoteNode, m: &mut PdoMap, add: &Add) -> Result<(), Fail> {
    add_entry(node, m, add).map_err(|f| match f {
        Fail::Protocol(why) => Fail::Usage(why),
        usage => usage,
    })
}

fn add_entry(node: &RemoteNode, m: &mut PdoMap, add: &Add) -> Result<(), Fail> {
    let desc = node.description();
    match add {
        Add::At(i, s, Some(bits)) => m.add(*i, *s, *bits).map(drop)?,
        Add::At(i, s, None) => {
            let bits = desc
                .and_then(|d| d.entry_at(*i, *s))
                .and_then(|e| e.data_type.bit_size())
                .and_then(|b| u8::try_from(b).ok())
                .ok_or_else(|| {
                    Fail::usage(format!(
                        "{i:#06x}:{s}: its length is not known (no description entry of a fixed size): give INDEX:SUB:BITS"
                    ))
                })?;
            m.add(*i, *s, bits).map(drop)?;
        }
        Add::Named(name, None) => m.add_variable(name).map(drop)?,
        Add::Named(name, Some(bits)) => {
            let d = desc.ok_or_else(|| {
                Fail::usage(format!(
                    "{name:?} is a name, and this node has no description: attach one with --eds NODE=FILE, or give INDEX:SUB:BITS"
                ))
            })?;
            let e = d.entry(name).map_err(|e| Fail::usage(e.to_string()))?;
            m.add(e.index, e.sub, *bits).map(drop)?;
        }
    }
    Ok(())
}

/// `0x6000:01/16 Input 1, …` for a person; an array of objects for a script.
fn entries_cell(m: &PdoMap) -> Cell {
    let text = m
        .entries
        .iter()
        .map(|e| {
            let name = e
                .name
                .as_deref()
                .map(|n| format!(" {n}"))
                .unwrap_or_default();
            format!("{:#06x}:{:02x}/{}{name}", e.index, e.sub, e.bits)
        })
        .collect::<Vec<_>>()
        .join(", ");
    let json: Vec<Value> = m
        .entries
        .iter()
        .map(|e| json!({"index": e.index, "sub": e.sub, "bits": e.bits, "name": e.name}))
        .collect();
    Cell::new(if text.is_empty() { "-".into() } else { text }, json)
}

fn print(g: &Global, maps: &[PdoMap]) {
    let mut t = Table::new(&[
        "node",
        "pdo",
        "cob-id",
        "enabled",
        "trans type",
        "inhibit",
        "event timer",
        "entries",
    ]);
    for m in maps {
        let cob = m.cob_id.0 & !CobId::INVALID;
        t.row(vec![
            node_cell(m.node.raw()),
            Cell::new(m.label(), m.label()),
            Cell::new(format!("{cob:#05x}"), cob),
            m.enabled.into(),
            u64::from(m.transmission_type).into(),
            m.inhibit_100us.map(u64::from).into(),
            m.event_timer_ms
                .map(|ms| Cell::new(format!("{ms} ms"), ms))
                .unwrap_or_else(Cell::none),
            entries_cell(m),
        ]);
    }
    if t.is_empty() {
        out::result(g.json, "the node has no PDOs", json!([]));
        return;
    }
    t.print(g.json);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn add_specs_parse_strictly() {
        assert_eq!(parse_add("0x6000:1:16"), Ok(Add::At(0x6000, 1, Some(16))));
        assert_eq!(parse_add("0x6000:3"), Ok(Add::At(0x6000, 3, None)));
        assert_eq!(parse_add("Input 1"), Ok(Add::Named("Input 1".into(), None)));
        assert_eq!(
            parse_add("Inputs.Status:8"),
            Ok(Add::Named("Inputs.Status".into(), Some(8)))
        );
        for bad in [
            "0x6000",
            "0x6000:1:0",
            "0x6000:1:65",
            "0x6000:1:16:1",
            "1x:1",
            " ",
            "a:99999",
        ] {
            assert!(parse_add(bad).is_err(), "{bad:?}");
        }
    }

    proptest::proptest! {
        #[test]
        fn add_never_panics(s in ".*") {
            let _ = parse_add(&s);
        }
    }
}
