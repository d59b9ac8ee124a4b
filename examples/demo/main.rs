//! The demo: one railway station's day on four simulated dual-bus racks, no hardware.
//!
//! `cargo run --release --example demo [-- --out DIR]`
//!
//! A strong and a weak interlocking computer run every rack (turnout and misc racks on the
//! CANopen predefined connection set, signal and track-circuit racks on the railway 29-bit
//! profile) with A/B board pairs driving point machines, signals, track circuits and level
//! crossings; the boards' dictionaries come from their EDS and the masters configure them from
//! each rack's DCF (`examples/demo/devices/`). Routes are set all day while a script hands a
//! rack over from one bus to the other, cuts a bus, kills an active board, kills the strong
//! master, makes an active board stop by itself, repairs all of it and splits a rack between
//! the computers; the dead board is replaced by a spare without node-ID, which the
//! active master finds and addresses by LSS (CiA 305) before it joins as standby. The demo
//! prints the timeline with the reaction times measured in the run, the application messages
//! counted end to end, and each rack's final status; it writes a candump log, pcap files and
//! an SVG timeline into `target/demo/` (or `--out DIR`). It exits with status 1 if a message
//! was lost, a failover missed its bound, the spare did not join with its slot's node-ID, or
//! the hand-over or the stopped board broke one of their invariants.

mod scenario;

use scenario::analysis::{Analysis, Outcome};
use scenario::station::MASTER_NAMES;
use scenario::{BITRATE, BOARD_HB, CONSUMER, MASTER_HB, MASTER_TIMEOUT, SYNC};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant as Wall;

fn main() -> ExitCode {
    let mut out = PathBuf::from("target/demo");
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match (a.as_str(), args.next()) {
            ("--out", Some(dir)) => out = PathBuf::from(dir),
            _ => {
                eprintln!("usage: demo [--out DIR]   (default: target/demo)");
                return ExitCode::from(2);
            }
        }
    }
    // The stations' devices are large bounded tables: give the simulation room on its stack.
    let run = std::thread::Builder::new()
        .stack_size(256 << 20)
        .spawn(move || demo(out))
        .and_then(|h| {
            h.join()
                .map_err(|_| std::io::Error::other("the demo panicked"))
        });
    match run {
        Ok(code) => code,
        Err(e) => {
            eprintln!("demo: {e}");
            ExitCode::FAILURE
        }
    }
}

fn demo(out: PathBuf) -> ExitCode {
    let wall = Wall::now();
    println!("duocan demo: one station, four dual-bus racks, simulated (no hardware)\n");
    let st = match scenario::run() {
        Ok(st) => st,
        Err(e) => {
            eprintln!("demo: {e}");
            return ExitCode::from(2);
        }
    };
    let analysis = Analysis::new(&st);
    let outcome = analysis.outcome();
    let chart = analysis.chart();

    println!(
        "station: a strong and a weak interlocking computer on every rack, {} kbit/s buses",
        BITRATE / 1000
    );
    for r in &st.racks {
        let [b1, b2] = r.buses().map(|b| st.sim.bus_name(b).to_owned());
        println!(
            "  {:<19} {:<34} {} A/B pairs ({}…)  buses {b1}, {b2}",
            r.name(),
            r.scheme_name(),
            r.pairs(),
            r.kind().label(0)
        );
    }
    println!(
        "  heartbeat: boards {} (failed after {}), masters {} (takeover after {}); SYNC every {}\n",
        ms(BOARD_HB),
        ms(CONSUMER),
        ms(MASTER_HB),
        ms(MASTER_TIMEOUT),
        ms(SYNC)
    );

    println!("timeline (simulated time)");
    for l in &outcome.lines {
        let indent = if l.depth == 0 { "" } else { "  -> " };
        println!(
            "{:>9}  {indent}{}",
            format!("{:.3} s", l.at.as_micros() as f64 / 1e6),
            l.text
        );
    }

    let ok = report(&outcome);
    for r in &outcome.replacements {
        let held = r.held();
        println!(
            "board replacement by LSS: {} {}'s slot {}: spare found by the {} and given {}, booted, identity checked, configured, joined as standby: {}",
            r.rack,
            r.label,
            r.member,
            MASTER_NAMES[r.master],
            r.node(),
            if held { "yes" } else { "NO" }
        );
    }
    let replaced = st
        .happened
        .iter()
        .filter(|h| matches!(h.act, scenario::Act::BoardReplaced { .. }))
        .count();
    let mut ok = ok
        && outcome.replacements.len() == replaced
        && outcome.replacements.iter().all(|r| r.held());
    for (text, held) in outcome.verdicts(&st) {
        println!("{text}: {}", if held { "yes" } else { "NO" });
        ok &= held;
    }
    let (boards, holding) = scenario::devices::configured(&st);
    println!(
        "configuration: {holding} of {boards} boards hold their rack's DCF values (dictionaries from {})",
        scenario::devices::BOARD_EDS.0
    );
    let ok = ok && holding == boards;

    println!("\nfinal status (the active computer's table, per rack)");
    for e in &outcome.ends {
        let who: Vec<&str> = e.active.iter().map(|w| MASTER_NAMES[*w]).collect();
        println!(
            "--- {}: active: {}; commands awaiting an answer: {} ---",
            e.name,
            who.join(", "),
            e.unanswered
        );
        print!("{}", e.status);
    }

    match scenario::outputs::write_all(&st, &chart, &out) {
        Ok(p) => {
            println!("\nfiles");
            println!("  candump log (every bus):     {}", p.candump.display());
            for f in &p.pcaps {
                println!("  pcap (CANopen, Wireshark):   {}", f.display());
            }
            println!("  timeline chart (browser):    {}", p.svg.display());
        }
        Err(e) => {
            eprintln!("cannot write the outputs into {}: {e}", out.display());
            return ExitCode::FAILURE;
        }
    }
    println!(
        "\n{} of simulated time, {} frames on 8 buses (busiest bus {:.1} % loaded), in {:.1} s of wall time",
        st.sim.now(),
        outcome.frames,
        100.0 * outcome.max_load,
        wall.elapsed().as_secs_f64()
    );
    if ok {
        ExitCode::SUCCESS
    } else {
        println!("FAILED: see above");
        ExitCode::FAILURE
    }
}

fn ms(d: duocan::Duration) -> String {
    let us = d.as_micros();
    if us.is_multiple_of(1000) {
        format!("{} ms", us / 1000)
    } else {
        format!("{:.1} ms", us as f64 / 1000.0)
    }
}

/// Prints the failovers and the message counts; true if everything held.
fn report(o: &Outcome) -> bool {
    let mut ok = true;
    println!("\nfailovers and reactions, measured in the run");
    for f in &o.failovers {
        let verdict = match f.bound {
            Some(b) if f.within() => format!("bound {:>10}  ok", ms(b)),
            Some(b) => {
                ok = false;
                format!("bound {:>10}  EXCEEDED", ms(b))
            }
            None => String::new(),
        };
        println!(
            "  {:<19} {:<58} {:>10}  {verdict}",
            f.rack,
            f.what,
            ms(f.took())
        );
    }
    println!(
        "\napplication messages, end to end (interlocking <-> the running board of each pair)"
    );
    println!(
        "  {:<19} {:>8} {:>7} {:>9} {:>9} {:>9}   {:>7} {:>9} {:>5} {:>5}",
        "rack",
        "commands",
        "resent",
        "exec once",
        "answered",
        "wrong",
        "states",
        "delivered",
        "lost",
        "dup"
    );
    let row = |name: &str, t: &scenario::analysis::Traffic| {
        println!(
            "  {:<19} {:>8} {:>7} {:>9} {:>9} {:>9}   {:>7} {:>9} {:>5} {:>5}",
            name,
            t.commands,
            t.resends,
            t.executed_once,
            t.answered,
            t.wrong,
            t.reports,
            t.delivered,
            t.lost_total(),
            t.duplicates_total()
        )
    };
    for (name, t) in &o.traffic {
        row(name, t);
    }
    let total = o.total();
    row("station", &total);
    let lost = total.lost_total();
    let dup = total.duplicates_total();
    println!(
        "frames lost = {lost}, duplicates = {dup}, wrong executions = {}, failed checks = {}",
        total.wrong, total.rejected
    );
    let masters_ok = o.ends.iter().all(|e| e.active.len() == 1);
    let pairs_ok = o.ends.iter().all(|e| {
        e.pairs
            .iter()
            .all(|p| p.running.len() == 1 && p.table == p.running.first().copied())
    });
    println!(
        "at the end: {} rack(s) of {} with exactly one active master; every pair with exactly one running board, the one the active master's table names: {}",
        o.ends.iter().filter(|e| e.active.len() == 1).count(),
        o.ends.len(),
        if pairs_ok { "yes" } else { "NO" }
    );
    for e in &o.ends {
        for p in e
            .pairs
            .iter()
            .filter(|p| p.running.len() != 1 || p.table != p.running.first().copied())
        {
            println!(
                "  {} {}: running {:?}, table says {:?}",
                e.name, p.label, p.running, p.table
            );
        }
    }
    ok && lost == 0 && dup == 0 && total.wrong == 0 && total.rejected == 0 && masters_ok && pairs_ok
}
