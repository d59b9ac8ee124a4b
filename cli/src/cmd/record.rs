//! `duocan record --candump FILE --pcap FILE [--duration S | --count N]`: what the bus carries,
//! written as the library's recorder writes it, and a summary of frames per bus.
//!
//! The network is listen-only and tapped (`NetOptions::with_tap`): every frame each port
//! receives goes to the candump log with the port's interface name, and to the pcap. A pcap
//! has no interface column, so on two ports bus 1 goes to FILE and bus 2 to FILE with `-bus2`
//! before its extension. The run ends at `--count N` frames (exactly N are written),
//! `--duration S` or Ctrl-C.

use super::live::{self, End};
use crate::args::parse_unsigned;
use crate::fail::Fail;
use crate::out::{self, Cell, Table};
use crate::{bus, Global};
use duocan::capture::recorder::{Filter, Recorder, Tap, TapDirection, TapPoint};
use duocan::{Frame, Instant};
use serde_json::json;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::Notify;

/// The arguments of `duocan record`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Write a candump log (`candump -l` format) here
    #[arg(long, value_name = "FILE")]
    candump: Option<PathBuf>,
    /// Write a pcap (Wireshark, tshark) here; on two ports bus 2 goes to FILE-bus2
    #[arg(long, value_name = "FILE")]
    pcap: Option<PathBuf>,
    /// Stop after S seconds (decimals allowed: 0.5)
    #[arg(long, value_name = "S", value_parser = live::parse_seconds)]
    duration: Option<Duration>,
    /// Stop after N frames
    #[arg(long, value_name = "N", value_parser = parse_count)]
    count: Option<u64>,
}

fn parse_count(s: &str) -> Result<u64, String> {
    match parse_unsigned::<u64>(s, "a count of frames")? {
        0 => Err(format!("count {s}: give at least 1")),
        n => Ok(n),
    }
}

/// The interface name of each port, as the log names them: what `--bus` names, and for the
/// simulated station its two buses (the names its ports carry; the record test holds them to
/// that).
fn port_names(bus: &[String]) -> Vec<String> {
    if bus::is_sim_station(bus) {
        return vec!["sim-bus1".into(), "sim-bus2".into()];
    }
    bus.to_vec()
}

/// The pcap of port `port` (0: bus 1) when the run records `ports` ports.
fn pcap_path(path: &Path, port: usize, ports: usize) -> PathBuf {
    if ports < 2 || port == 0 {
        return path.to_path_buf();
    }
    let stem = path
        .file_stem()
        .map_or_else(Default::default, |s| s.to_string_lossy());
    let name = match path.extension() {
        Some(ext) => format!("{stem}-bus{}.{}", port + 1, ext.to_string_lossy()),
        None => format!("{stem}-bus{}", port + 1),
    };
    path.with_file_name(name)
}

/// The recorder behind a count: frames per port, and at most `limit` frames written.
struct Counted {
    recorder: Recorder,
    counts: Mutex<Vec<u64>>,
    limit: Option<u64>,
    reached: Notify,
}

impl Tap for Counted {
    fn frame(&self, at: Instant, point: TapPoint, dir: TapDirection, frame: &Frame) {
        let TapPoint::Port(port) = point else {
            return;
        };
        let Ok(mut counts) = self.counts.lock() else {
            return;
        };
        let total: u64 = counts.iter().sum();
        if self.limit.is_some_and(|n| total >= n) {
            return;
        }
        if counts.len() <= port {
            counts.resize(port + 1, 0);
        }
        counts[port] += 1;
        self.recorder.frame(at, point, dir, frame);
        if self.limit == Some(total + 1) {
            self.reached.notify_one();
        }
    }
}

fn create(path: &Path) -> Result<BufWriter<File>, Fail> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|e| Fail::usage(format!("{}: {e}", path.display())))
}

/// Runs `duocan record`.
pub async fn run(g: &Global, a: Args) -> Result<(), Fail> {
    if a.candump.is_none() && a.pcap.is_none() {
        return Err(Fail::usage(
            "record: give --candump FILE and/or --pcap FILE to write to",
        ));
    }
    let names = port_names(g.bus.as_ref().map_or(&[][..], |b| &b.0[..]));
    let mut recorder = Recorder::new().port_names(names.clone());
    if let Some(p) = &a.candump {
        recorder = recorder.candump(Filter::All, create(p)?);
    }
    if let Some(p) = &a.pcap {
        for port in 0..names.len().max(1) {
            let path = pcap_path(p, port, names.len());
            recorder = recorder
                .pcap(Filter::Point(TapPoint::Port(port)), create(&path)?)
                .map_err(|e| Fail::usage(format!("{}: {e}", path.display())))?;
        }
    }
    let tap = Arc::new(Counted {
        recorder,
        counts: Mutex::new(vec![0; names.len().max(1)]),
        limit: a.count,
        reached: Notify::new(),
    });
    let bus = bus::open_with(g, bus::options(g, true).with_tap(tap.clone()))?;
    let started = std::time::Instant::now();
    let deadline = a.duration.map(|d| tokio::time::Instant::now() + d);
    let end = live::until(deadline, async {
        match a.count {
            Some(_) => tap.reached.notified().await,
            None => std::future::pending().await,
        }
        Some(())
    })
    .await;
    bus.close().await;
    let seconds = started.elapsed().as_secs_f64();
    tap.recorder
        .flush()
        .map_err(|e| Fail::usage(format!("writing the capture: {e}")))?;
    if tap.recorder.errors() > 0 {
        return Err(Fail::usage(format!(
            "{} frames could not be written (disk full?)",
            tap.recorder.errors()
        )));
    }
    let counts = tap.counts.lock().map(|c| c.clone()).unwrap_or_default();
    summary(g, &names, &counts, &a, seconds, end.err());
    Ok(())
}

fn summary(g: &Global, names: &[String], counts: &[u64], a: &Args, seconds: f64, end: Option<End>) {
    let total: u64 = counts.iter().sum();
    let why = match end {
        None => "count reached",
        Some(End::Duration) => "duration passed",
        Some(End::Interrupted) => "interrupted",
        Some(End::Closed) => "network closed",
    };
    let mut t = Table::new(&["bus", "interface", "frames"]);
    for (i, n) in counts.iter().enumerate() {
        let name = names.get(i).cloned().unwrap_or_else(|| format!("port {i}"));
        t.row(vec![
            Cell::new(format!("{}", i + 1), i + 1),
            name.into(),
            (*n).into(),
        ]);
    }
    let path = |p: &Option<PathBuf>| p.as_ref().map(|p| p.display().to_string());
    if g.json {
        out::emit_json(&json!({
            "frames": total,
            "buses": t.to_json(),
            "candump": path(&a.candump),
            "pcap": path(&a.pcap),
            "seconds": (seconds * 1000.0).round() / 1000.0,
            "end": why,
        }));
    } else {
        out::print_text(&t.to_text());
        out::print_text(&format!("{total} frames in {seconds:.1} s ({why})\n"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_second_bus_gets_its_own_pcap() {
        let p = Path::new("/tmp/run.pcap");
        assert_eq!(pcap_path(p, 0, 1), p);
        assert_eq!(pcap_path(p, 0, 2), p);
        assert_eq!(pcap_path(p, 1, 2), Path::new("/tmp/run-bus2.pcap"));
        assert_eq!(pcap_path(Path::new("cap"), 1, 2), Path::new("cap-bus2"));
    }
}
