//! `duocan kit`: the failover test kit. A scenario file (`scenario`) gives the buses, the
//! devices, a timeline of faults and the expectations; `kit check` measures the expectations
//! on the candump logs of a run, one log per wire (`<member>.log`, `<bus>.log`), and prints
//! each with its figure and verdict: exit 0 if all pass, 1 if any fails. The expectations' times
//! are read on the timeline as the run applied it ([`timeline`]).
//!
//! ```text
//! duocan kit validate failover.toml
//! duocan kit check failover.toml --logs run/
//! ```

mod bench;
mod expect;
mod run;
mod scenario;
mod sim;
mod timeline;

use crate::fail::Fail;
use crate::out::{Cell, Table};
use crate::Global;
use duocan::capture::candump::CandumpReader;
use duocan::capture::Record;
use expect::{measure, Wires};
use scenario::Scenario;
use serde_json::json;
use std::path::{Path, PathBuf};
use timeline::Timeline;

/// `duocan kit` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum Kit {
    /// Check a scenario file: every name, fault and expectation
    Validate {
        /// The scenario (TOML)
        file: PathBuf,
    },
    /// Run a scenario on real interfaces: the fault bridge between its members, its devices,
    /// its timeline; then measure its expectations on the logs
    Run {
        /// The scenario (TOML)
        file: PathBuf,
        /// Where the logs, pcaps and device outputs go
        #[arg(long, default_value = "kit-run")]
        out: PathBuf,
    },
    /// Run a scenario in duocan's simulator (simulated time, the same faults by the same
    /// names), then measure its expectations as on a real run
    Sim {
        /// The scenario (TOML)
        file: PathBuf,
        /// The simulated buses' bit rate
        #[arg(long, default_value = "1000000")]
        bitrate: u32,
    },
    /// Measure the bridge itself: latency and throughput through it from one interface to
    /// another, against a bare path on one interface, side by side
    Bench {
        /// The interface of the bare path (two sockets on it)
        #[arg(long)]
        bare: String,
        /// The bridge's first interface (frames are sent here)
        #[arg(long)]
        a: String,
        /// The bridge's second interface (frames are received here)
        #[arg(long)]
        b: String,
        /// Frames per measurement
        #[arg(long, default_value = "5000")]
        frames: u32,
    },
    /// Measure a scenario's expectations on the candump logs of a run
    Check {
        /// The scenario (TOML)
        file: PathBuf,
        /// The directory of logs: one `<wire>.log` per member and bus
        #[arg(long)]
        logs: PathBuf,
        /// When the run started (µs since the Unix epoch, as the logs count); default: the
        /// directory's `start_us` file, else the earliest frame
        #[arg(long)]
        start_us: Option<u64>,
    },
}

/// Reads and checks a scenario file.
pub fn load(file: &Path) -> Result<Scenario, Fail> {
    let text = std::fs::read_to_string(file)
        .map_err(|e| Fail::usage(format!("{}: {e}", file.display())))?;
    Scenario::parse(&text, &file.display().to_string()).map_err(Fail::usage)
}

/// Runs `duocan kit`.
pub async fn run(g: &Global, k: Kit) -> Result<(), Fail> {
    match k {
        Kit::Validate { file } => {
            let s = load(&file)?;
            crate::out::result(
                g.json,
                &format!(
                    "{}: {:?}, {} buses, {} members, {} devices, {} faults, {} expectations, {} ms",
                    file.display(),
                    s.name,
                    s.buses.len(),
                    s.members().count(),
                    s.devices.len(),
                    s.timeline.len(),
                    s.expects.len(),
                    s.duration_ms
                ),
                json!({"name": s.name, "buses": s.buses.len(), "members": s.members().count(),
                       "devices": s.devices.len(), "faults": s.timeline.len(),
                       "expectations": s.expects.len(), "duration_ms": s.duration_ms}),
            );
            Ok(())
        }
        Kit::Run { file, out } => {
            let s = load(&file)?;
            println!(
                "scenario {:?}: {} ms, logs in {}",
                s.name,
                s.duration_ms,
                out.display()
            );
            let r = run::run(g, &s, &out).await?;
            let mut t = Table::new(&[
                "wire",
                "rx",
                "tx",
                "cut",
                "partitioned",
                "dropped",
                "corrupted",
                "flipped",
                "duplicated",
                "delayed",
                "babbled",
                "overflow",
                "tx failed",
            ]);
            for (name, c) in r.buses.iter().chain(&r.members) {
                t.row(vec![
                    name.clone().into(),
                    c.rx.into(),
                    c.tx.into(),
                    c.cut.into(),
                    c.partitioned.into(),
                    c.dropped.into(),
                    c.corrupted.into(),
                    c.flipped.into(),
                    c.duplicated.into(),
                    c.delayed.into(),
                    c.babbled.into(),
                    c.overflow.into(),
                    c.tx_failed.into(),
                ]);
            }
            t.print(g.json);
            let unasked: u64 = r
                .members
                .iter()
                .map(|(_, c)| c.overflow + c.tx_failed)
                .sum();
            let (wires, end) = read_wires(&s, &r.dir, None)?;
            let verdict = report(g, &s, &wires, end, &r.timeline);
            if unasked > 0 || r.log_errors > 0 {
                return Err(Fail::protocol(format!(
                    "the bridge lost {unasked} frame(s) it was not told to drop, and {} log write(s) failed",
                    r.log_errors
                )));
            }
            verdict
        }
        Kit::Sim { file, bitrate } => {
            let s = load(&file)?;
            if !g.json {
                println!(
                    "scenario {:?} in the simulator: {} ms",
                    s.name, s.duration_ms
                );
            }
            let (wires, end) = sim::run(&s, bitrate, g.json)?;
            report(g, &s, &wires, end, &Timeline::default())
        }
        Kit::Bench { bare, a, b, frames } => bench::run(g, &bare, &a, &b, frames.max(1)).await,
        Kit::Check {
            file,
            logs,
            start_us,
        } => {
            let s = load(&file)?;
            let (wires, end) = read_wires(&s, &logs, start_us)?;
            let applied = Timeline::read_from(&logs).map_err(Fail::usage)?;
            report(g, &s, &wires, end, &applied)
        }
    }
}

/// The wires of a run from its log directory, times relative to the start; and the end.
fn read_wires(s: &Scenario, dir: &Path, start_us: Option<u64>) -> Result<(Wires, u64), Fail> {
    let mut raw = Vec::new();
    let names = s.buses.iter().map(|(b, _)| b.as_str()).chain(s.members());
    for name in names {
        let path = dir.join(format!("{name}.log"));
        if !path.exists() {
            continue;
        }
        let mut frames = Vec::new();
        for e in CandumpReader::open(&path).map_err(|e| Fail::usage(e.to_string()))? {
            let e = e.map_err(|e| Fail::usage(e.to_string()))?;
            if let Record::Frame(f) = e.record {
                frames.push((e.timestamp_us, f));
            }
        }
        raw.push((name.to_string(), frames));
    }
    let start = match start_us {
        Some(t) => t,
        None => match std::fs::read_to_string(dir.join("start_us")) {
            Ok(t) => t.trim().parse().map_err(|_| {
                Fail::usage(format!(
                    "{}: not a number of µs",
                    dir.join("start_us").display()
                ))
            })?,
            Err(_) => raw
                .iter()
                .filter_map(|(_, w)| w.first().map(|(t, _)| *t))
                .min()
                .unwrap_or(0),
        },
    };
    let mut end = s.duration_ms.saturating_mul(1000);
    let mut wires = Wires::new();
    for (name, frames) in raw {
        let w: Vec<_> = frames
            .into_iter()
            .map(|(t, f)| (t.saturating_sub(start), f))
            .collect();
        end = end.max(w.last().map_or(0, |(t, _)| *t));
        wires.insert(name, w);
    }
    Ok((wires, end))
}

/// Prints every expectation, its times read on the timeline as `applied`, with its figure and
/// verdict; an error if any failed.
fn report(
    g: &Global,
    s: &Scenario,
    wires: &Wires,
    end: u64,
    applied: &Timeline,
) -> Result<(), Fail> {
    let mut t = Table::new(&["expectation", "result", "measured"]);
    let mut failed = 0;
    for (name, e) in &s.expects {
        let o = measure(&applied.read(e), wires, end).map_err(Fail::usage)?;
        failed += usize::from(!o.pass);
        t.row(vec![
            name.clone().into(),
            Cell::new(if o.pass { "pass" } else { "FAIL" }, o.pass),
            o.measured.into(),
        ]);
    }
    t.print(g.json);
    if failed > 0 {
        return Err(Fail::protocol(format!(
            "{failed} of {} expectations failed in {:?}",
            s.expects.len(),
            s.name
        )));
    }
    Ok(())
}
