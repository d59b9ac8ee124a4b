//! `duocan eds export NODE [-o FILE] [--as-dcf] [--scan] [--range A-B]...`: a live node's
//! dictionary, read over SDO, written as an EDS or a DCF.
//!
//! (`--as-dcf`, not `--dcf`: that is the global option attaching a DCF.)
//!
//! CANopen has no service that lists a node's objects, so what is read is chosen here:
//!
//! - **with a description attached** to the node (`--eds`, `--dcf`; on `--bus sim` the
//!   simulated nodes' own): every entry it lists, read over SDO. Names, types, access and
//!   limits come from the description; an entry the node does not have (it aborts with "object
//!   does not exist" or "sub-index does not exist") is left out; write-only entries and DOMAINs
//!   are not read (a domain may be an image of megabytes) and keep the description's default.
//! - **without one, or with `--scan`**: each index of the standard communication range
//!   0x1000–0x1FFF and of every `--range` is asked for sub-index 0; an object that answers is
//!   read sub by sub (sub 0 as the highest sub-index, when sub 1 exists). Names, types and
//!   access come from CiA 301 for the objects the library's standard dictionary knows; any
//!   other entry is named after its address, its type guessed from its size (1, 2, 4, 8 bytes:
//!   UNSIGNED8…64; printable text: VISIBLE_STRING; else DOMAIN) and marked read-only, since SDO
//!   cannot tell access. 0x1000–0x1FFF is 4096 requests: about a second on `--bus sim`, a few
//!   seconds on a 500 kbit/s bus.
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
        "node {id:#04x}: {} entries read ({source}), {} not on the node, {} not read (write-only or DOMAIN)",
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

/// The standard objects CiA 301 names, as the library's standard dictionary defines them.
fn catalog(id: u8) -> DynamicDictionary {
    comm::standard_dictionary(id, comm::Identity::default())
}

/// A dictionary of what answers in `ranges`.
async fn scan(
    sdo: &RemoteSdo,
    id: u8,
    ranges: &[(u16, u16)],
    tally: &mut Tally,
) -> Result<DynamicDictionary, Fail> {
    let known = catalog(id);
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
        let catalog_type = known.get(index, 0).ok().map(|e| e.def.object_type);
        let structured = match catalog_type {
            Some(t) => t != ObjectType::Var,
            None => sub0.len() == 1 && probe(sdo, index, 1).await?,
        };
        if !structured {
            add(&mut od, &known, index, 0, ObjectType::Var, &sub0);
            tally.read += 1;
            continue;
        }
        let ot = catalog_type.unwrap_or(ObjectType::Record);
        add(&mut od, &known, index, 0, ot, &sub0);
        tally.read += 1;
        for sub in 1..=sub0.first().copied().unwrap_or(0) {
            match sdo.read_bytes(index, sub).await {
                Ok(d) => {
                    add(&mut od, &known, index, sub, ot, &d);
                    tally.read += 1;
                }
                Err(e) if absent(&e) => tally.absent += 1,
                Err(e) if answered(&e) => tally.not_read += 1,
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

/// Adds an entry read by a scan: the catalog's definition if it has one, else one guessed from
/// the bytes.
fn add(
    od: &mut DynamicDictionary,
    known: &DynamicDictionary,
    index: u16,
    sub: u8,
    ot: ObjectType,
    data: &[u8],
) {
    let (mut def, name) = match known.get(index, sub) {
        Ok(e) => (*e.def, e.name.to_string()),
        Err(_) => {
            let ty = guess(data);
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
    if def.data_type.fixed_size().is_none() {
        def.capacity = def.capacity.max(data.len() as u32);
    }
    let _ = od.insert_owned(def, &name, None);
    let _ = od.store(index, sub, data);
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
