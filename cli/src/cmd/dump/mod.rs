//! `duocan dump [FILE]`: a candump log, a pcap or the live bus as CANopen-aware lines, one per
//! frame: time, interface, identifier and what the frame is ("node 5 SDO upload 0x1018:01 =
//! 0x00000123"), by the library's decoder (`duocan::capture::decode`).
//!
//! A file is a pcap when it starts with a pcap magic number, a candump log otherwise (the
//! extension says nothing). Without a file the live bus of `--bus` is watched, listen-only,
//! until Ctrl-C, `--count N` lines or `--duration S`. `--eds`/`--dcf` name the PDO values of
//! their nodes (the mappings the description configures); `--node` and `--kind` keep only the
//! frames a commissioning engineer is after. Each interface (bus) has its own decoder, so an
//! SDO transfer seen on both buses of a dual bus is followed once per bus. A file that turns out bad ends the dump with
//! exit 1 and an error naming the file and the line (candump) or byte offset (pcap), after the
//! lines before it.

mod json;

use super::live::{self, Feed};
use crate::args::{parse_node, parse_unsigned};
use crate::fail::Fail;
use crate::{bus, Global};
use duocan::capture::candump::read_log;
use duocan::capture::decode::{DecodedFrame, Decoder, Kind};
use duocan::capture::pcap::PcapReader;
use duocan::capture::Record;
use duocan::eds::Description;
use duocan::{Frame, NodeId};
use serde_json::json;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

/// The arguments of `duocan dump`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A candump log or a pcap (told apart by the file's first bytes); without one, the live
    /// bus of --bus
    file: Option<PathBuf>,
    /// Stop after N lines
    #[arg(long, value_name = "N", value_parser = parse_count)]
    count: Option<u64>,
    /// Stop after S seconds (the live bus; decimals allowed: 0.5)
    #[arg(long, value_name = "S", value_parser = live::parse_seconds)]
    duration: Option<Duration>,
    /// Only frames of or to these nodes (NMT to all included); comma-separated or repeated
    #[arg(long, value_name = "NODE", value_delimiter = ',', value_parser = parse_node)]
    node: Vec<NodeId>,
    /// Only these kinds: nmt, sync, time, emcy, heartbeat, sdo, pdo, lss, flying-master,
    /// railway, unknown; comma-separated or repeated
    #[arg(long, value_name = "KIND", value_delimiter = ',', value_parser = parse_kind)]
    kind: Vec<Kind>,
}

/// A count of lines, at least 1.
fn parse_count(s: &str) -> Result<u64, String> {
    match parse_unsigned::<u64>(s, "a count")? {
        0 => Err(format!("count {s}: give at least 1")),
        n => Ok(n),
    }
}

/// A kind of frame by its name.
fn parse_kind(s: &str) -> Result<Kind, String> {
    Kind::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Kind::ALL.iter().map(|k| k.name()).collect();
        format!("kind {s:?}: give one of {}", names.join(", "))
    })
}

/// Which lines `--node` and `--kind` keep.
struct Filter {
    nodes: Vec<NodeId>,
    kinds: Vec<Kind>,
}

impl Filter {
    fn is_open(&self) -> bool {
        self.nodes.is_empty() && self.kinds.is_empty()
    }
    /// A railway heartbeat is kept by `heartbeat` and by `railway`.
    fn keeps(&self, d: &DecodedFrame) -> bool {
        (self.nodes.is_empty() || self.nodes.iter().any(|n| d.concerns(*n)))
            && (self.kinds.is_empty()
                || self.kinds.contains(&d.kind())
                || self.kinds.contains(&d.service()))
    }
}

/// Where the lines go: buffered from a file, flushed line by line from the live bus; a closed
/// pipe (`| head`) ends the dump quietly.
struct Out {
    w: BufWriter<std::io::Stdout>,
    json: bool,
    live: bool,
    lines: u64,
}

impl Out {
    fn write(&mut self, text: &str) {
        let ok =
            writeln!(self.w, "{text}").and_then(
                |()| {
                    if self.live {
                        self.w.flush()
                    } else {
                        Ok(())
                    }
                },
            );
        if ok.is_err() {
            std::process::exit(0);
        }
        self.lines += 1;
    }
    fn flush(&mut self) {
        if self.w.flush().is_err() {
            std::process::exit(0);
        }
    }
}

/// Interfaces with a decoder of their own; the frames of any further one share the last.
const MAX_DECODERS: usize = 8;

/// Decodes, filters and prints each frame.
struct Dump {
    /// The decoder every interface's starts as (the descriptions' PDOs learned).
    template: Decoder,
    /// One decoder per interface: each bus's SDO transfers are followed on their own, so the
    /// two copies of a frame on a dual bus are not counted as two segments.
    decoders: Vec<(String, Decoder)>,
    filter: Filter,
    out: Out,
    count: Option<u64>,
}

impl Dump {
    fn new(g: &Global, a: &Args, descs: &BTreeMap<u8, Arc<Description>>, live: bool) -> Dump {
        let mut decoder = Decoder::new();
        for (id, d) in descs {
            if let Some(n) = NodeId::new(*id) {
                decoder.describe(n, d);
            }
        }
        Dump {
            template: decoder,
            decoders: Vec::new(),
            filter: Filter {
                nodes: a.node.clone(),
                kinds: a.kind.clone(),
            },
            out: Out {
                w: BufWriter::new(std::io::stdout()),
                json: g.json,
                live,
                lines: 0,
            },
            count: a.count,
        }
    }

    /// The decoder of `interface`.
    fn decoder(&mut self, interface: &str) -> &mut Decoder {
        let i = match self.decoders.iter().position(|(n, _)| n == interface) {
            Some(i) => i,
            None if self.decoders.len() < MAX_DECODERS => {
                self.decoders
                    .push((interface.to_owned(), self.template.clone()));
                self.decoders.len() - 1
            }
            None => MAX_DECODERS - 1,
        };
        &mut self.decoders[i].1
    }

    fn done(&self) -> bool {
        self.count.is_some_and(|n| self.out.lines >= n)
    }

    /// Prints one record; error frames and CAN FD frames that are no PDO only without a filter.
    fn record(&mut self, timestamp_us: u64, interface: &str, record: &Record) {
        let time = json::time_text(timestamp_us);
        let frame = match record {
            Record::Frame(f) => f,
            Record::Error { bits, data } if self.filter.is_open() => {
                let text = format!("error frame, class bits {bits:#010x}");
                let line = match self.out.json {
                    true => {
                        json!({"time": time, "timestamp_us": timestamp_us, "interface": interface,
                        "kind": "error_frame", "bits": bits, "data": json::hex(data), "text": text})
                        .to_string()
                    }
                    false => format!("{time}  {interface:<5}  {:<8}  {text}", "error"),
                };
                return self.out.write(&line);
            }
            Record::Fd(f) => {
                // A PDO of up to 64 bytes is decoded; another CAN FD frame only without a filter.
                if let Some(d) = self.decoder(interface).decode_fd(f) {
                    if !self.filter.keeps(&d) {
                        return;
                    }
                    let line = match self.out.json {
                        true => json::line_fd(timestamp_us, interface, f, &d).to_string(),
                        false => {
                            format!("{time}  {interface:<5}  {:<8}  {d}", json::id_text(f.id()))
                        }
                    };
                    return self.out.write(&line);
                }
                if !self.filter.is_open() {
                    return;
                }
                let (id, data) = (f.id(), f.data());
                let text = format!("CAN FD frame of {} bytes (not decoded)", data.len());
                let line = match self.out.json {
                    true => {
                        json!({"time": time, "timestamp_us": timestamp_us, "interface": interface,
                        "kind": "fd_frame", "id": id.raw(), "data": json::hex(data), "text": text})
                        .to_string()
                    }
                    false => format!("{time}  {interface:<5}  {:<8}  {text}", json::id_text(id)),
                };
                return self.out.write(&line);
            }
            _ => return,
        };
        self.frame(timestamp_us, &time, interface, frame);
    }

    fn frame(&mut self, timestamp_us: u64, time: &str, interface: &str, frame: &Frame) {
        let d = self.decoder(interface).decode(frame);
        if !self.filter.keeps(&d) {
            return;
        }
        let line = if self.out.json {
            json::line(timestamp_us, interface, frame, &d).to_string()
        } else {
            format!(
                "{time}  {interface:<5}  {:<8}  {d}",
                json::id_text(frame.id())
            )
        };
        self.out.write(&line);
    }
}

/// Runs `duocan dump`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    match &a.file {
        Some(path) => {
            if a.duration.is_some() {
                return Err(Fail::usage(
                    "--duration is for the live bus: a file is dumped whole (or --count N lines)",
                ));
            }
            let mut dump = Dump::new(g, &a, &bus::descriptions(g)?, false);
            let r = file(&mut dump, path);
            dump.out.flush();
            r
        }
        None => live_bus(g, &a).await,
    }
}

/// The pcap magic numbers (microseconds and nanoseconds, either byte order).
fn is_pcap(head: &[u8]) -> bool {
    matches!(
        head.get(..4),
        Some(
            [0xD4, 0xC3, 0xB2, 0xA1]
                | [0xA1, 0xB2, 0xC3, 0xD4]
                | [0x4D, 0x3C, 0xB2, 0xA1]
                | [0xA1, 0xB2, 0x3C, 0x4D]
        )
    )
}

fn file(dump: &mut Dump, path: &Path) -> Result<(), Fail> {
    let name = path.display().to_string();
    let f = File::open(path).map_err(|e| Fail::usage(format!("{name}: {e}")))?;
    let mut r = BufReader::new(f);
    let head = r
        .fill_buf()
        .map_err(|e| Fail::protocol(format!("{name}: {e}")))?;
    if is_pcap(head) {
        let packets = PcapReader::new(r).map_err(|e| Fail::protocol(format!("{name}: {e}")))?;
        for p in packets {
            let p = p.map_err(|e| Fail::protocol(format!("{name}: {e}")))?;
            dump.record(p.timestamp_us, "pcap", &p.record);
            if dump.done() {
                break;
            }
        }
    } else {
        for e in read_log(name, r) {
            let e = e.map_err(|e| Fail::protocol(e.to_string()))?;
            dump.record(e.timestamp_us, &e.interface, &e.record);
            if dump.done() {
                break;
            }
        }
    }
    Ok(())
}

async fn live_bus(g: &Global, a: &Args) -> Result<(), Fail> {
    let (feed, mut rx) = Feed::new();
    let bus = bus::open_with(g, bus::options(g, true).with_tap(feed.clone()))?;
    let mut dump = Dump::new(g, a, &bus.descs, true);
    // The ports' own names: `sim-station` is two buses, `sim-bus1` and `sim-bus2`.
    let names: Vec<String> = match bus.net.ports().await {
        Ok(ports) => ports.into_iter().map(|p| p.name).collect(),
        Err(_) => bus.names.clone(),
    };
    let deadline = a.duration.map(|d| tokio::time::Instant::now() + d);
    while !dump.done() {
        let Ok(seen) = live::until(deadline, rx.recv()).await else {
            break;
        };
        let interface = names.get(seen.port).map_or("?", String::as_str);
        dump.record(seen.timestamp_us, interface, &Record::Frame(seen.frame));
    }
    dump.out.flush();
    bus.close().await;
    if feed.dropped() > 0 {
        eprintln!(
            "duocan: {} frames not shown: the output fell behind the bus",
            feed.dropped()
        );
    }
    Ok(())
}
