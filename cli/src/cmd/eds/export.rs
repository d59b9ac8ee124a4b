//! `duocan eds export NODE [-o FILE] [--as-dcf] [--scan] [--range A-B]...`: a live node's
//! dictionary, read over SDO, written as an EDS or a DCF.
//!
//! (`--as-dcf`, not `--dcf`: that is the global option attaching a DCF.)
//!
//! CANopen has no service that lists a node's objects, so what is read is chosen here:
//!
//! - **with a description attached** to the node (`--eds`, `--dcf`; on `--bus sim-station` the
//!   simulated nodes' own): every entry it lists, read over SDO. Names, types, access and
//!   limits come from the description; an entry the node does not have (it aborts with "object
//!   does not exist" or "sub-index does not exist") is left out; write-only entries and DOMAINs
//!   are not read (a domain may be an image of megabytes) and keep the description's default.
//! - **without one, or with `--scan`**: each index of the standard communication range
//!   0x1000–0x1FFF and of every `--range` is asked for sub-index 0; an object that answers is
//!   read sub by sub: up to sub-index 0 (the highest sub-index, when sub 1 exists), but past it
//!   for the objects whose sub-index 0 counts instead (0x1003's recorded errors, a PDO
//!   mapping's mapped objects), to the first sub-index the node does not have. Names, types
//!   and access come from CiA 301 for the objects it defines (the library's standard
//!   dictionary, the error history, every SDO server and client and PDO parameter); an entry
//!   that answers with an abort other than "does not exist" (a history slot without an error)
//!   is kept with that definition and its default. Any other entry is named after its
//!   address, its type guessed from its size (1, 2, 4, 8 bytes: UNSIGNED8…64; printable text:
//!   VISIBLE_STRING; else DOMAIN) and marked read-only, since SDO cannot tell access. CiA 301
//!   makes some read-only entries `const` (0x1000, 0x1018, a record's sub-index 0), and so
//!   does the export, where a device's own EDS may say `ro`: SDO cannot tell them apart
//!   either. 0x1000–0x1FFF is 4096 requests: about a second on `--bus sim-station`, a few seconds on
//!   a 500 kbit/s bus.
//!
//! The EDS takes the values read as its `DefaultValue`s (so that it describes the node as it
//! is); `--as-dcf` writes the description's defaults and the values read as `ParameterValue`,
//! with `[DeviceComissioning] NodeID`. The file goes to `-o FILE`, or to standard output; a
//! summary (entries read, left out, not read) goes to standard error, or with `--json` to
//! standard output as one object.

use crate::args::{parse_index, parse_node};
use crate::bus::{self, Bus};
use crate::fail::Fail;
use crate::out;
use crate::Global;
use duocan::eds::{export_dcf, export_eds, Description, ExportOptions};
use duocan::net::{NetError, RemoteSdo};
use duocan::od::{
    comm, Access, DataType, DefaultValue, DynamicDictionary, ObjectDef, ObjectDictionary,
    ObjectType,
};
use duocan::pdo::params;
use duocan::sdo::SdoErrorKind;
use duocan::{AbortCode, NodeId};
use serde_json::json;
use std::path::PathBuf;

/// The arguments of `eds export`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// The node-ID (1-127)
    #[arg(value_parser = parse_node)]
    node: NodeId,
    /// Write the file here (default: standard output)
    #[arg(long, short)]
    output: Option<PathBuf>,
    /// Write a DCF: the description's defaults, the values read as ParameterValue
    #[arg(long)]
    as_dcf: bool,
    /// Scan 0x1000-0x1FFF (and --range) even with a description attached
    #[arg(long)]
    scan: bool,
    /// Also scan this index range, as 0x2000-0x2FFF; repeatable (implies --scan)
    #[arg(long, value_name = "FROM-TO", value_parser = parse_range)]
    range: Vec<(u16, u16)>,
}

fn parse_range(s: &str) -> Result<(u16, u16), String> {
    let (a, b) = s
        .split_once('-')
        .ok_or_else(|| format!("{s:?}: give FROM-TO, as 0x2000-0x2FFF"))?;
    let (a, b) = (parse_index(a)?, parse_index(b)?);
    if a > b {
        return Err(format!("{s:?}: the range ends before it starts"));
    }
    Ok((a, b))
}

/// What the export read.
#[derive(Default)]
struct Tally {
    read: usize,
    absent: usize,
    not_read: usize,
}

/// Runs `eds export`.
pub async fn run(g: &Global, a: ExportArgs) -> Result<(), Fail> {
    let bus = bus::open(g, false)?;
    let r = export(g, &bus, &a).await;
    bus.close().await;
    r
}

async fn export(g: &Global, bus: &Bus, a: &ExportArgs) -> Result<(), Fail> {
    let id = a.node.raw();
    let sdo = bus.net.node(id).sdo();
    let desc = bus.desc(id).filter(|_| !a.scan && a.range.is_empty());
    let mut tally = Tally::default();
    let od = match desc {
        Some(d) => from_description(&sdo, d, id, &mut tally).await?,
        None => {
            let mut ranges = vec![(0x1000, 0x1FFF)];
            ranges.extend(&a.range);
            scan(&sdo, id, &ranges, &mut tally).await?
        }
    };
    if tally.read == 0 {
        return Err(Fail::protocol(format!(
            "node {id:#04x}: no entry could be read (is it on the bus? `duocan scan`)"
        )));
    }
    let file_name = a.output.as_ref().and_then(|p| p.file_name()).map_or_else(
        || format!("node{id}.{}", if a.as_dcf { "dcf" } else { "eds" }),
        |n| n.to_string_lossy().into_owned(),
    );
    let mut opts = ExportOptions::default()
        .with_file_name(&file_name)
        .with_description(&format!("node {id} as read over SDO by duocan eds export"));
    if let Some(d) = desc {
        opts = opts.with_vendor_name(&d.device_info.vendor_name);
    }
    let text = if a.as_dcf {
        export_dcf(&od, &opts)
    } else {
        export_eds(&rebased(&od), &opts)
    }
    .map_err(|e| Fail::protocol(format!("node {id:#04x}: {e}")))?;
    let source = match desc {
        Some(d) => format!("the entries of {}", d.source),
        None => "a scan".to_string(),
    };
    let summary = format!(
        "node {id:#04x}: {} entries read ({source}), {} not on the node, {} not read (write-only, DOMAIN or without a value)",
        tally.read, tally.absent, tally.not_read
    );
    let mut v = json!({
        "node": id,
        "kind": if a.as_dcf { "dcf" } else { "eds" },
        "read": tally.read,
        "absent": tally.absent,
        "not_read": tally.not_read,
    });
    match &a.output {
        Some(path) => {
            std::fs::write(path, &text)
                .map_err(|e| Fail::usage(format!("{}: {e}", path.display())))?;
            v["file"] = json!(path.display().to_string());
            out::result(
                g.json,
                &format!("{summary}; written to {}", path.display()),
                v,
            );
        }
        None if g.json => {
            v["text"] = json!(text);
            out::emit_json(&v);
        }
        None => {
            out::print_text(&text);
            if !g.quiet {
                eprintln!("{summary}");
            }
        }
    }
    Ok(())
}

/// A read the node refused because it does not have the entry.
fn absent(e: &NetError) -> bool {
    matches!(e, NetError::Sdo(s) if matches!(s.kind, SdoErrorKind::Server(c)
        if c == AbortCode::NO_OBJECT || c == AbortCode::NO_SUB_INDEX))
}

/// An answer from the node (an abort included), as opposed to none at all.
fn answered(e: &NetError) -> bool {
    matches!(e, NetError::Sdo(s) if matches!(s.kind, SdoErrorKind::Server(_)))
}

/// The description's dictionary with the values read from the node.
async fn from_description(
    sdo: &RemoteSdo,
    d: &Description,
    id: u8,
    tally: &mut Tally,
) -> Result<DynamicDictionary, Fail> {
    let mut od = d.dictionary(id);
    let mut keys = Vec::new();
    od.for_each(&mut |e| keys.push((e.def.index, e.def.sub, e.def.access, e.def.data_type)));
    keys.sort_unstable_by_key(|k| (k.0, k.1));
    for (index, sub, access, ty) in keys {
        if access == Access::Wo || ty == DataType::Domain {
            tally.not_read += 1;
            continue;
        }
        match sdo.read_bytes(index, sub).await {
            Ok(data) => {
                if od.store(index, sub, &data).is_ok() {
                    tally.read += 1;
                } else {
                    // Longer than the description allows: keep its default, say so.
                    tally.not_read += 1;
                }
            }
            Err(e) if absent(&e) => {
                od.remove(index, sub);
                tally.absent += 1;
            }
            Err(e) if answered(&e) => tally.not_read += 1,
            Err(e) => return Err(e.into()),
        }
    }
    Ok(od)
}

/// The standard objects CiA 301 names, with their definitions: the library's standard
/// dictionary, and (one index at a time) the error history, every SDO server and client and
/// every PDO's communication and mapping parameters.
struct Catalog {
    standard: DynamicDictionary,
}

impl Catalog {
    fn new(id: u8) -> Catalog {
        Catalog {
            standard: comm::standard_dictionary(id, comm::Identity::default()),
        }
    }

    /// The definition of (index, sub) and its name, if CiA 301 has it.
    fn def(&self, index: u16, sub: u8) -> Option<(ObjectDef, String)> {
        let zero = DefaultValue::Unsigned(0);
        let defs: Vec<ObjectDef> = match index {
            // The standard dictionary keeps 8 history slots; a device may have up to 254.
            comm::ERROR_HISTORY => comm::error_history::<255>().to_vec(),
            0x1201..=0x127F => sdo_parameter(index, false).to_vec(),
            0x1280..=0x12FF => sdo_parameter(index, true).to_vec(),
            0x1400..=0x15FF => params::rpdo_comm(index - 0x13FF, zero, 0, 0).to_vec(),
            0x1600..=0x17FF => params::rpdo_mapping::<65>(index - 0x15FF, &[]).to_vec(),
            0x1800..=0x19FF => params::tpdo_comm(index - 0x17FF, zero, 0, 0, 0).to_vec(),
            0x1A00..=0x1BFF => params::tpdo_mapping::<65>(index - 0x19FF, &[]).to_vec(),
            _ => {
                let e = self.standard.get(index, sub).ok()?;
                return Some((*e.def, e.name.to_string()));
            }
        };
        let d = defs.into_iter().find(|d| d.sub == sub)?;
        Some((d, d.name.to_string()))
    }

    /// The object type of `index`, if CiA 301 has it.
    fn object_type(&self, index: u16) -> Option<ObjectType> {
        self.def(index, 0).map(|(d, _)| d.object_type)
    }
}

/// An SDO server's (0x1201–0x127F) or client's (0x1280–0x12FF) parameter record: the two
/// COB-IDs and the node-ID of the other end, all writable.
fn sdo_parameter(index: u16, client: bool) -> [ObjectDef; 4] {
    let rec = |d: ObjectDef, n: &'static str| d.object_type(ObjectType::Record).named(n);
    let (name, tx, rx, node) = if client {
        (
            "SDO client parameter",
            "COB-ID client to server (tx)",
            "COB-ID server to client (rx)",
            "Node-ID of the SDO server",
        )
    } else {
        (
            "SDO server parameter",
            "COB-ID client to server (rx)",
            "COB-ID server to client (tx)",
            "Node-ID of the SDO client",
        )
    };
    [
        rec(ObjectDef::u8(index, 0, Access::Const, 3), name),
        rec(ObjectDef::u32(index, 1, Access::Rw, 0), tx),
        rec(ObjectDef::u32(index, 2, Access::Rw, 0), rx),
        rec(ObjectDef::u8(index, 3, Access::Rw, 0), node),
    ]
}

/// CiA 301's objects whose sub-index 0 counts what the others hold (errors recorded, objects
/// mapped) instead of naming the highest sub-index, with the highest sub-index they may have:
/// the entries past the count exist all the same.
fn counted(index: u16) -> Option<u8> {
    match index {
        comm::ERROR_HISTORY => Some(0xFE),
        0x1600..=0x17FF | 0x1A00..=0x1BFF => Some(0x40),
        _ => None,
    }
}

/// A dictionary of what answers in `ranges`.
async fn scan(
    sdo: &RemoteSdo,
    id: u8,
    ranges: &[(u16, u16)],
    tally: &mut Tally,
) -> Result<DynamicDictionary, Fail> {
    let known = Catalog::new(id);
    let mut od = DynamicDictionary::new(id);
    let mut indices: Vec<u16> = ranges.iter().flat_map(|&(a, b)| a..=b).collect();
    indices.sort_unstable();
    indices.dedup();
    for index in indices {
        let sub0 = match sdo.read_bytes(index, 0).await {
            Ok(d) => d,
            Err(e) if answered(&e) => continue,
            Err(e) => return Err(e.into()),
        };
        let catalog_type = known.object_type(index);
        let structured = match catalog_type {
            Some(t) => t != ObjectType::Var,
            None => sub0.len() == 1 && probe(sdo, index, 1).await?,
        };
        if !structured {
            add(&mut od, &known, index, 0, ObjectType::Var, Some(&sub0));
            tally.read += 1;
            continue;
        }
        let ot = catalog_type.unwrap_or(ObjectType::Record);
        add(&mut od, &known, index, 0, ot, Some(&sub0));
        tally.read += 1;
        let count = sub0.first().copied().unwrap_or(0);
        // A counting sub-index 0: read on past the count, to the first sub-index the node
        // does not have.
        let last = counted(index).map_or(count, |most| most.max(count));
        for sub in 1..=last {
            match sdo.read_bytes(index, sub).await {
                Ok(d) => {
                    add(&mut od, &known, index, sub, ot, Some(&d));
                    tally.read += 1;
                }
                Err(e) if absent(&e) && sub > count => break,
                Err(e) if absent(&e) => tally.absent += 1,
                Err(e) if answered(&e) => {
                    // There, but not to be read now (a history slot without an error, a
                    // write-only entry): kept with CiA 301's definition when it has one.
                    if known.def(index, sub).is_some() {
                        add(&mut od, &known, index, sub, ot, None);
                    }
                    tally.not_read += 1;
                }
                Err(e) => return Err(e.into()),
            }
        }
    }
    Ok(od)
}

/// True if (index, sub) answers a read (with a value or an abort other than "does not exist").
async fn probe(sdo: &RemoteSdo, index: u16, sub: u8) -> Result<bool, Fail> {
    match sdo.read_bytes(index, sub).await {
        Ok(_) => Ok(true),
        Err(e) if absent(&e) => Ok(false),
        Err(e) if answered(&e) => Ok(true),
        Err(e) => Err(e.into()),
    }
}

/// Adds an entry found by a scan, with the bytes read (`None`: there but not read, its
/// default kept): CiA 301's definition if the catalog has one, else one guessed from the bytes.
fn add(
    od: &mut DynamicDictionary,
    known: &Catalog,
    index: u16,
    sub: u8,
    ot: ObjectType,
    data: Option<&[u8]>,
) {
    let (mut def, name) = match known.def(index, sub) {
        Some(d) => d,
        None => {
            let ty = guess(data.unwrap_or_default());
            let name = if sub == 0 && ot == ObjectType::Var {
                format!("Object {index:04X}")
            } else if sub == 0 {
                format!("Object {index:04X} highest sub-index")
            } else {
                format!("Object {index:04X} sub {sub}")
            };
            let def = ObjectDef::new(index, sub, ty)
                .access(Access::Ro)
                .object_type(ot);
            (def, name)
        }
    };
    def.hook = None;
    let data = data.unwrap_or_default();
    if def.data_type.fixed_size().is_none() {
        def.capacity = def.capacity.max(data.len() as u32);
    }
    let _ = od.insert_owned(def, &name, None);
    if !data.is_empty() {
        let _ = od.store(index, sub, data);
    }
}

/// A type for bytes of an entry nothing describes.
fn guess(data: &[u8]) -> DataType {
    match data.len() {
        1 => DataType::Unsigned8,
        2 => DataType::Unsigned16,
        4 => DataType::Unsigned32,
        8 => DataType::Unsigned64,
        _ if !data.is_empty() && data.iter().all(|b| (0x20..0x7F).contains(b)) => {
            DataType::VisibleString
        }
        _ => DataType::Domain,
    }
}

/// The same dictionary with every entry's current value as its default (an EDS describes the
/// node as it was read).
fn rebased(od: &DynamicDictionary) -> DynamicDictionary {
    let mut out = DynamicDictionary::new(od.node_id());
    od.for_each(&mut |e| {
        let mut def = *e.def;
        def.hook = None;
        let owned = match def.data_type.fixed_size() {
            Some(n) => {
                let mut b = [0u8; 8];
                let n = n.min(8).min(e.data.len());
                b[..n].copy_from_slice(&e.data[..n]);
                def = def.default(DefaultValue::Unsigned(u64::from_le_bytes(b)));
                None
            }
            None => {
                def = def.default(DefaultValue::Zero);
                def.capacity = def.capacity.max(e.data.len() as u32);
                Some(e.data)
            }
        };
        let _ = out.insert_owned(def, e.name, owned);
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_parse_strictly() {
        assert_eq!(parse_range("0x2000-0x2FFF"), Ok((0x2000, 0x2FFF)));
        assert_eq!(parse_range("8192-8192"), Ok((0x2000, 0x2000)));
        for bad in [
            "0x2000",
            "0x3000-0x2000",
            "0x2000-",
            "-0x2000",
            "0x2000-0x10000",
            "a-b",
        ] {
            assert!(parse_range(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn guessed_types_follow_the_size() {
        assert_eq!(guess(&[1]), DataType::Unsigned8);
        assert_eq!(guess(&[1, 2, 3, 4]), DataType::Unsigned32);
        assert_eq!(guess(b"abc"), DataType::VisibleString);
        assert_eq!(guess(&[0, 1, 2]), DataType::Domain);
        assert_eq!(guess(&[]), DataType::Domain);
    }

    proptest::proptest! {
        #[test]
        fn range_never_panics(s in ".*") {
            let _ = parse_range(&s);
        }
    }
}
