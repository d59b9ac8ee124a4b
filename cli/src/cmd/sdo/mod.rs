//! `duocan sdo read|write NODE OBJECT [SUB] [TYPE] [VALUE]`: one entry of a node's object
//! dictionary, by index or by name, as a typed value or to/from a file.
//!
//! OBJECT is an index (`0x1018`, with the sub-index next or as `0x1018:1`) or, with a
//! description attached (`--eds`, `--dcf`; automatic on `--bus sim-station`), a name as the library
//! resolves it (`"Producer heartbeat time"`, `"Identity object.Vendor-ID"`). The type comes from
//! the command line, else from the description, else a read shows the bytes (and the number
//! they make) and a write asks for it. `--file` streams a value of any size to or from a file,
//! with progress on long transfers; `--block`, `--segmented`, `--expedited` and `--crc` choose
//! how it travels.

use crate::args::{encode, parse_index, parse_node, parse_sub, parse_type, show, type_of, Type};
use crate::bus::{self, Bus};
use crate::fail::Fail;
use crate::out;
use crate::progress::Progress;
use crate::Global;
use duocan::net::RemoteSdo;
use duocan::sdo::{SdoOptions, TransferMode};
use duocan::{Duration, NodeId};
use serde_json::{json, Value};
use std::path::PathBuf;

pub(crate) mod verify;

/// How a transfer travels.
#[derive(clap::Args, Debug, Clone, Copy)]
pub struct Mode {
    /// Block transfer (falls back if the node has none)
    #[arg(long, conflicts_with_all = ["segmented", "expedited"])]
    block: bool,
    /// Segmented transfer
    #[arg(long, conflicts_with = "expedited")]
    segmented: bool,
    /// Expedited transfer (1 to 4 bytes)
    #[arg(long)]
    expedited: bool,
    /// Ask for a CRC over a block transfer
    #[arg(long, requires = "block")]
    crc: bool,
}

/// `duocan sdo` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum Sdo {
    /// Read an entry: `read 5 0x1018 1 u32`, `read 5 "Device type"`, `read 5 0x2002 --file out.bin`
    Read {
        /// The node-ID (1-127)
        #[arg(value_parser = parse_node)]
        node: NodeId,
        /// Index (0x1018, 0x1018:1) or a name from the node's description
        object: String,
        /// SUB and TYPE, both optional: the sub-index (default 0), and u8…u64, i8…i64, f32, f64,
        /// bool, str, hex or auto
        rest: Vec<String>,
        /// Write the value to this file instead of printing it (any size)
        #[arg(long)]
        file: Option<PathBuf>,
        #[command(flatten)]
        mode: Mode,
    },
    /// Write an entry: `write 5 0x1017 0 u16 100`, `write 5 "Producer heartbeat time" 100`
    Write {
        /// The node-ID (1-127)
        #[arg(value_parser = parse_node)]
        node: NodeId,
        /// Index (0x1017, 0x1017:0) or a name from the node's description
        object: String,
        /// SUB and TYPE (both optional), then VALUE (none with --file)
        #[arg(allow_negative_numbers = true)]
        rest: Vec<String>,
        /// Write the value from this file (any size)
        #[arg(long)]
        file: Option<PathBuf>,
        /// Read the value back and compare (exit 1 on the first byte that differs)
        #[arg(long)]
        verify: bool,
        #[command(flatten)]
        mode: Mode,
    },
}

/// The entry a command names, and how its value reads.
#[derive(Debug, PartialEq)]
pub struct Entry {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The type, if known.
    pub ty: Option<Type>,
    /// Its name in the description, if there is one.
    pub name: Option<String>,
}

/// Resolves OBJECT and the words after it. `value` is true when the last word is the value to
/// write (taken off `rest` first).
pub fn resolve(
    desc: Option<&duocan::eds::Description>,
    object: &str,
    rest: &[String],
) -> Result<Entry, Fail> {
    let mut words = rest.iter().map(String::as_str);
    let numeric = object.starts_with(|c: char| c.is_ascii_digit());
    let (index, mut sub, by_name) = if numeric {
        match object.split_once(':') {
            Some((i, s)) => (
                parse_index(i).map_err(Fail::usage)?,
                Some(parse_sub(s).map_err(Fail::usage)?),
                None,
            ),
            None => (parse_index(object).map_err(Fail::usage)?, None, None),
        }
    } else {
        let d = desc.ok_or_else(|| {
            Fail::usage(format!(
                "{object:?} is a name, and this node has no description: attach one with \
                 --eds NODE=FILE, or give the index (0x1017)"
            ))
        })?;
        let e = d.entry(object).map_err(|e| Fail::usage(e.to_string()))?;
        (e.index, Some(e.sub), Some(e.name.clone()))
    };
    let mut next = words.next();
    if sub.is_none() {
        match next {
            Some(w) if w.starts_with(|c: char| c.is_ascii_digit()) => {
                sub = Some(parse_sub(w).map_err(Fail::usage)?);
                next = words.next();
            }
            _ => sub = Some(0),
        }
    }
    let sub = sub.unwrap_or(0);
    let ty = match next {
        Some(w) => Some(parse_type(w).ok_or_else(|| {
            Fail::usage(format!(
                "{w:?} is not a type: give u8, u16, u32, u64, i8, i16, i32, i64, f32, f64, \
                 bool, str, hex or auto"
            ))
        })?),
        None => None,
    };
    if let Some(extra) = words.next() {
        return Err(Fail::usage(format!("{extra:?}: one word too many")));
    }
    let known = desc.and_then(|d| d.entry_at(index, sub));
    Ok(Entry {
        index,
        sub,
        ty: ty.or_else(|| known.map(|e| type_of(e.data_type))),
        name: by_name.or_else(|| known.map(|e| e.name.clone())),
    })
}

/// Runs `duocan sdo`.
pub async fn run(g: &Global, c: Sdo) -> Result<(), Fail> {
    let bus = bus::open(g, false)?;
    let r = match c {
        Sdo::Read {
            node,
            object,
            rest,
            file,
            mode,
        } => read(g, &bus, node, &object, &rest, file, mode).await,
        Sdo::Write {
            node,
            object,
            mut rest,
            file,
            verify,
            mode,
        } => {
            let value =
                match file {
                    Some(_) => None,
                    None => Some(rest.pop().ok_or_else(|| {
                        Fail::usage("give the value to write last (or --file FILE)")
                    })?),
                };
            let w = WriteArgs {
                node,
                object,
                rest,
                value,
                file,
                verify,
                mode,
            };
            write(g, &bus, w).await
        }
    };
    bus.close().await;
    r
}

fn client(g: &Global, bus: &Bus, node: NodeId, m: Mode) -> RemoteSdo {
    let mode = if m.block {
        TransferMode::Block
    } else if m.segmented {
        TransferMode::Segmented
    } else if m.expedited {
        TransferMode::Expedited
    } else {
        TransferMode::Auto
    };
    let opts = SdoOptions::default()
        .with_timeout(Duration::from_millis(g.timeout))
        .with_mode(mode)
        .with_crc(m.crc);
    bus.net.node(node.raw()).sdo().with_options(opts)
}

fn label(node: NodeId, e: &Entry) -> String {
    format!("node {:#04x} {:#06x}:{:02x}", node.raw(), e.index, e.sub)
}

async fn read(
    g: &Global,
    bus: &Bus,
    node: NodeId,
    object: &str,
    rest: &[String],
    file: Option<PathBuf>,
    m: Mode,
) -> Result<(), Fail> {
    let e = resolve(bus.desc(node.raw()).map(|d| &**d), object, rest)?;
    let sdo = client(g, bus, node, m);
    let mut progress = Progress::new(format!("read {}", label(node, &e)), g.quiet);
    if let Some(path) = file {
        let f = tokio::fs::File::create(&path)
            .await
            .map_err(|err| Fail::usage(format!("{}: {err}", path.display())))?;
        let mut w = tokio::io::BufWriter::new(f);
        let n = sdo
            .read_to(e.index, e.sub, &mut w, |p| progress.update(p))
            .await?;
        tokio::io::AsyncWriteExt::flush(&mut w)
            .await
            .map_err(|err| Fail::usage(format!("{}: {err}", path.display())))?;
        let summary = progress.finish();
        out::result(
            g.json,
            &format!("{}: {summary} into {}", label(node, &e), path.display()),
            json!({"node": node.raw(), "index": e.index, "sub": e.sub, "bytes": n, "file": path.display().to_string()}),
        );
        return Ok(());
    }
    let mut data = Vec::new();
    sdo.read_to(e.index, e.sub, &mut data, |p| progress.update(p))
        .await?;
    let _ = progress.finish();
    let ty = e.ty.unwrap_or(Type::Auto);
    let mut v = json!({
        "node": node.raw(),
        "index": e.index,
        "sub": e.sub,
        "name": e.name,
        "type": format!("{ty:?}").to_lowercase(),
        "value": json_value(ty, &data),
        "hex": hex(&data),
    });
    if e.name.is_none() {
        v.as_object_mut().map(|o| o.remove("name"));
    }
    out::result(g.json, &show(ty, &data), v);
    Ok(())
}

/// What `sdo write` was given.
struct WriteArgs {
    node: NodeId,
    object: String,
    rest: Vec<String>,
    value: Option<String>,
    file: Option<PathBuf>,
    verify: bool,
    mode: Mode,
}

async fn write(g: &Global, bus: &Bus, w: WriteArgs) -> Result<(), Fail> {
    let node = w.node;
    let e = resolve(bus.desc(node.raw()).map(|d| &**d), &w.object, &w.rest)?;
    let sdo = client(g, bus, node, w.mode);
    let (file, value) = (w.file, w.value);
    let mut progress = Progress::new(format!("write {}", label(node, &e)), g.quiet);
    let n = match (&file, &value) {
        (Some(path), _) => {
            let f = tokio::fs::File::open(&path)
                .await
                .map_err(|err| Fail::usage(format!("{}: {err}", path.display())))?;
            let size = f
                .metadata()
                .await
                .map_err(|err| Fail::usage(format!("{}: {err}", path.display())))?
                .len();
            let r = tokio::io::BufReader::new(f);
            sdo.write_from(e.index, e.sub, r, Some(size), |p| progress.update(p))
                .await?
        }
        (None, Some(value)) => {
            let ty = match e.ty {
                Some(Type::Auto) | None => {
                    return Err(Fail::usage(format!(
                        "{}: give the type to write (u8, u16, u32, str, hex…), as in \
                         `sdo write {} {:#06x} {} u16 {value}`, or attach a description",
                        label(node, &e),
                        node.raw(),
                        e.index,
                        e.sub
                    )))
                }
                Some(t) => t,
            };
            let bytes = encode(ty, value).map_err(Fail::usage)?;
            let n = bytes.len() as u64;
            sdo.write_from(e.index, e.sub, &bytes[..], Some(n), |p| progress.update(p))
                .await?
        }
        (None, None) => return Err(Fail::usage("give the value to write (or --file FILE)")),
    };
    let summary = progress.finish();
    let verified = if w.verify {
        // The same bytes again, from the file or the value, compared as they come back.
        let src: Box<dyn std::io::Read + Send> = match (&file, &value) {
            (Some(path), _) => Box::new(std::io::BufReader::new(
                std::fs::File::open(path)
                    .map_err(|err| Fail::usage(format!("{}: {err}", path.display())))?,
            )),
            (None, Some(v)) => Box::new(std::io::Cursor::new(
                encode(e.ty.unwrap_or(Type::Hex), v).map_err(Fail::usage)?,
            )),
            (None, None) => unreachable_args()?,
        };
        let mut cmp = verify::Compare::new(src);
        let mut progress = Progress::new(format!("verify {}", label(node, &e)), g.quiet);
        let back = sdo
            .read_to(e.index, e.sub, &mut cmp, |p| progress.update(p))
            .await?;
        let _ = progress.finish();
        cmp.check(back, n)
            .map_err(|why| Fail::protocol(format!("{}: verify failed: {why}", label(node, &e))))?;
        ", verified"
    } else {
        ""
    };
    out::result(
        g.json,
        &format!("{}: written, {summary}{verified}", label(node, &e)),
        json!({"node": node.raw(), "index": e.index, "sub": e.sub, "bytes": n, "verified": w.verify}),
    );
    Ok(())
}

/// The case clap's arguments rule out (a write without a value or a file), as an error.
fn unreachable_args() -> Result<Box<dyn std::io::Read + Send>, Fail> {
    Err(Fail::usage("give the value to write (or --file FILE)"))
}

/// Bytes as lower-case hex without spaces.
fn hex(data: &[u8]) -> String {
    data.iter().map(|b| format!("{b:02x}")).collect()
}

/// The value as JSON: numbers as numbers, text as a string, anything else as hex.
fn json_value(ty: Type, data: &[u8]) -> Value {
    let text = show(ty, data);
    match ty {
        Type::Str => Value::String(text),
        Type::Bool => match data {
            [0] => Value::Bool(false),
            [1] => Value::Bool(true),
            _ => Value::Null,
        },
        Type::Hex | Type::Auto => Value::String(hex(data)),
        _ => serde_json::from_str::<Value>(&text)
            .ok()
            .filter(Value::is_number)
            .unwrap_or(Value::Null),
    }
}
