//! What the demo leaves behind: a candump log of every bus, a pcap per bus of the CANopen
//! racks (what Wireshark decodes as CANopen), and the SVG timeline chart.

use super::analysis::Analysis;
use super::board::BoardEvent;
use super::interlocking::IlEvent;
use super::report::svg::seconds;
use super::report::{render, Fault, Lane, LaneKind, Network, Span, State, Timeline};
use super::station::{master_node, MASTER_NAMES, STRONG, WEAK};
use super::{Act, Station};
use duocan::capture::candump::CandumpWriter;
use duocan::capture::pcap::PcapWriter;
use duocan::profile::Predefined;
use duocan::sim::{TraceRecord, TxOutcome};
use duocan::Instant;
use duocan_redundancy::supervisor::flying_master::MasterRole;
use duocan_redundancy::{Member, NetworkEventKind as K};
use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use super::scheme::Scheme;

/// Wall-clock time of simulated zero in the captures: 2026-01-01 06:00:00 UTC.
pub const EPOCH_US: u64 = 1_767_247_200_000_000;

/// Where the files went.
#[derive(Clone, Debug)]
pub struct Paths {
    /// The candump log (every bus).
    pub candump: PathBuf,
    /// One pcap per bus of the CANopen racks.
    pub pcaps: Vec<PathBuf>,
    /// The SVG chart.
    pub svg: PathBuf,
}

/// Writes the candump log, the pcap files and the chart into `dir` (created if missing).
pub fn write_all(st: &Station, chart: &Timeline, dir: &Path) -> io::Result<Paths> {
    std::fs::create_dir_all(dir)?;
    let candump = dir.join("demo.log");
    let mut log = CandumpWriter::new(BufWriter::new(File::create(&candump)?));
    let mut pcaps = Vec::new();
    let mut pcap_of = std::collections::HashMap::new();
    for r in &st.racks {
        if r.scheme_name() != Predefined::NAME {
            continue;
        }
        for b in r.buses() {
            let path = dir.join(format!("{}.pcap", st.sim.bus_name(b)));
            let w = PcapWriter::new(BufWriter::new(File::create(&path)?))?;
            pcap_of.insert(b, w);
            pcaps.push(path);
        }
    }
    for rec in st.sim.trace() {
        let TraceRecord::Tx(x) = rec else { continue };
        if !matches!(x.outcome, TxOutcome::Delivered { .. }) {
            continue;
        }
        let ts = EPOCH_US + x.end.as_micros();
        log.write(ts, st.sim.bus_name(x.bus), &x.frame)?;
        if let Some(w) = pcap_of.get_mut(&x.bus) {
            w.write(ts, &x.frame)?;
        }
    }
    log.flush()?;
    for (_, mut w) in pcap_of {
        w.flush()?;
    }
    let svg = dir.join("timeline.svg");
    let text =
        render(chart).map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e.to_string()))?;
    let mut f = BufWriter::new(File::create(&svg)?);
    f.write_all(text.as_bytes())?;
    f.flush()?;
    Ok(Paths {
        candump,
        pcaps,
        svg,
    })
}

/// A lane from `(time, state, label)` changes; equal neighbours merge.
fn lane(label: String, kind: LaneKind, changes: &[(Instant, State, String)], end: f64) -> Lane {
    let mut merged: Vec<&(Instant, State, String)> = Vec::new();
    for c in changes {
        match merged.last() {
            Some(l) if l.1 == c.1 && l.2 == c.2 => {}
            Some(l) if l.0 == c.0 => {
                merged.pop();
                merged.push(c);
            }
            _ => merged.push(c),
        }
    }
    let spans = merged
        .iter()
        .enumerate()
        .map(|(i, (t, s, l))| {
            let to = merged.get(i + 1).map_or(end, |n| seconds(n.0));
            Span::new(seconds(*t), to, *s).labelled(l.clone())
        })
        .collect();
    Lane { label, kind, spans }
}

impl Analysis<'_> {
    /// The timeline chart: per rack, bus 1 and bus 2, each pair's running board, both masters'
    /// roles, and the faults of the script.
    pub fn chart(&self) -> Timeline {
        let st = self.station();
        let end = seconds(st.sim.now());
        let mut networks = Vec::new();
        for (i, r) in st.racks.iter().enumerate() {
            let mut lanes = Vec::new();
            for bus in 0..2 {
                let mut ch = vec![(Instant::ZERO, State::Ok, String::new())];
                for h in &st.happened {
                    match h.act {
                        Act::BusCut { rack, bus: b } if rack == i && b == bus => {
                            ch.push((h.at, State::Failed, "cut".into()))
                        }
                        Act::BusRestored { rack, bus: b } if rack == i && b == bus => {
                            ch.push((h.at, State::Ok, String::new()))
                        }
                        Act::HandOver { rack, repaired } if rack == i && repaired == bus => {
                            ch.push((h.at, State::Ok, String::new()))
                        }
                        Act::HandOver { rack, .. } if rack == i => {
                            ch.push((h.at, State::Failed, "cut".into()))
                        }
                        Act::Partition { rack } if rack == i => {
                            ch.push((h.at, State::Suspect, "split".into()))
                        }
                        Act::Healed { rack } if rack == i => {
                            ch.push((h.at, State::Ok, String::new()))
                        }
                        _ => {}
                    }
                }
                lanes.push(lane(format!("bus {}", bus + 1), LaneKind::Bus, &ch, end));
            }
            for p in 0..r.pairs() {
                let mut times: Vec<Instant> = vec![Instant::ZERO];
                for m in [Member::A, Member::B] {
                    times.extend(
                        r.board_events(&st.sim, p, m)
                            .into_iter()
                            .filter_map(|(t, e)| matches!(e, BoardEvent::State(_)).then_some(t)),
                    );
                }
                times.extend(st.happened.iter().filter(|h| matches!(h.act, Act::BoardKilled { rack, pair } | Act::BoardReplaced { rack, pair } if rack == i && pair == p)).map(|h| h.at));
                times.sort();
                let ch: Vec<_> = times
                    .into_iter()
                    .map(|t| {
                        let run = [Member::A, Member::B].map(|m| self.board_running(i, p, m, t));
                        match run {
                            [true, false] => (t, State::Active, "A".into()),
                            [false, true] => (t, State::Active, "B".into()),
                            [true, true] => (t, State::Failed, "A+B".into()),
                            [false, false] => (t, State::Down, String::new()),
                        }
                    })
                    .collect();
                lanes.push(lane(
                    format!("{} (running board)", r.kind().label(p)),
                    LaneKind::Pair,
                    &ch,
                    end,
                ));
            }
            for w in [STRONG, WEAK] {
                let mut ch = vec![(Instant::ZERO, State::Unknown, String::new())];
                for (_, e) in r.master_events(&st.sim, w) {
                    if let IlEvent::Net(n) = e {
                        if let K::MasterRole(role) = &n.kind {
                            ch.push(match role.to {
                                MasterRole::Active => (n.at, State::Active, "active".into()),
                                MasterRole::Standby(_) => (n.at, State::Standby, "standby".into()),
                                _ => (n.at, State::Unknown, String::new()),
                            });
                        }
                    }
                }
                for h in &st.happened {
                    if h.act == Act::MasterKilled(w) {
                        ch.push((h.at, State::Down, "off".into()));
                    }
                }
                ch.sort_by_key(|c| c.0);
                lanes.push(lane(
                    format!("{} ({})", MASTER_NAMES[w], master_node(w)),
                    LaneKind::Master,
                    &ch,
                    end,
                ));
            }
            let faults = st
                .happened
                .iter()
                .filter_map(|h| {
                    let text = match h.act {
                        Act::BusCut { rack, bus } if rack == i => format!("bus {} cut", bus + 1),
                        Act::BusRestored { rack, bus } if rack == i => {
                            format!("bus {} restored", bus + 1)
                        }
                        Act::BoardKilled { rack, pair } if rack == i => format!(
                            "{}: active board {} loses power",
                            r.kind().label(pair),
                            h.member.map_or("?".into(), |m| m.to_string())
                        ),
                        Act::BoardReplaced { rack, pair } if rack == i => format!(
                            "{}: spare without node-ID for board {}",
                            r.kind().label(pair),
                            h.member.map_or("?".into(), |m| m.to_string())
                        ),
                        Act::HandOver { rack, repaired } if rack == i => format!(
                            "bus {} repaired, bus {} cut in the same instant",
                            repaired + 1,
                            2 - repaired
                        ),
                        Act::BoardStops { rack, pair, state } if rack == i => format!(
                            "{}: active board {} stops by itself ({state})",
                            r.kind().label(pair),
                            h.member.map_or("?".into(), |m| m.to_string())
                        ),
                        Act::MasterKilled(w) => format!("{} loses power", MASTER_NAMES[w]),
                        Act::MasterBack(w) => format!("{} back", MASTER_NAMES[w]),
                        Act::Partition { rack } if rack == i => {
                            "buses split between the masters".into()
                        }
                        Act::Healed { rack } if rack == i => "partition healed".into(),
                        _ => return None,
                    };
                    Some(Fault::new(seconds(h.at), text))
                })
                .collect();
            networks.push(Network {
                name: format!("{} ({})", r.name(), r.scheme_name()),
                lanes,
                faults,
            });
        }
        Timeline {
            title: "duocan demo: one station's day on four dual-bus racks".into(),
            start: 0.0,
            end,
            networks,
        }
    }
}
