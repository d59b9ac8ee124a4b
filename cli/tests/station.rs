//! `duocan station`: the shipped demo file checks; a bad file is exit 2 naming file, line and
//! key; a small station runs its networks, logs their events and stops cleanly on SIGTERM; a
//! network whose buses cannot be opened stops the start (exit 3) naming it; no acknowledged
//! audit record is lost to SIGKILL. Its HTTP access: `station_http.rs`, `station_rest.rs`.

mod common;
#[path = "station_http/log.rs"]
mod log;
use common::duocan;
use log::{file, next_before, stderr_lines};
use std::io::{BufRead, BufReader};
use std::process::Command;
use std::time::{Duration, Instant};

#[test]
fn the_shipped_demo_station_checks_with_its_four_racks() {
    let demo = file("../examples/station/demo.toml");
    let r = duocan(&["station", "check", &demo]);
    assert_eq!(r.code, 0, "{}", r.err);
    assert!(r.out.starts_with("station demo: 4 networks\n"), "{}", r.out);
    // The turnout rack's plant fails (and runs on), the others' run without faults.
    for (rack, plant) in [
        ("turnout rack", "failover"),
        ("signal rack", "quiet"),
        ("track-circuit rack", "quiet"),
        ("misc rack", "quiet"),
    ] {
        assert!(
            r.out
                .contains(&format!("  {rack} on sim-pairs:{plant}: master 0x01")),
            "{}",
            r.out
        );
    }
    // 10 + 10 + 12 + 4 pairs, as the demo's racks.
    assert_eq!(r.out.matches("/0x2").count(), 36, "{}", r.out);
    // Its 309-3 gateway on loopback, the racks numbered by their place in the file.
    assert!(
        r.out.contains(
            "  309-3 gateway: tcp 127.0.0.1:5555, at most 16 clients, nets: 1 turnout rack, \
             2 signal rack, 3 track-circuit rack, 4 misc rack\n"
        ),
        "{}",
        r.out
    );
}

/// The SocketCAN station file (run in the vcan tier's VM by .ci/station-vm.sh) checks on any
/// machine: checking opens no interface.
#[test]
fn the_shipped_vcan_station_checks_with_two_racks_on_socketcan() {
    let vcan = file("../examples/station/vcan.toml");
    let r = duocan(&["station", "check", &vcan]);
    assert_eq!(r.code, 0, "{}", r.err);
    assert!(r.out.starts_with("station vcan: 2 networks\n"), "{}", r.out);
    for rack in ["turnout rack on vcan0,vcan1", "signal rack on vcan2,vcan3"] {
        assert!(
            r.out.contains(&format!("  {rack}: master 0x01")),
            "{}",
            r.out
        );
    }
    // A pair each.
    assert_eq!(r.out.matches("/0x2").count(), 2, "{}", r.out);
}

#[test]
fn a_bad_station_file_is_a_usage_error_naming_file_line_and_key() {
    let bad = file("tests/station_files/bad_timeout.toml");
    let r = duocan(&["station", "check", &bad]);
    assert_eq!(r.code, 2, "{}", r.err);
    let want = format!("duocan: {bad}:10:21: master_timeout_ms: ");
    assert!(r.err.starts_with(&want), "{}", r.err);
    // `run` checks the same way before it opens anything.
    let r = duocan(&["station", "run", &bad]);
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(r.err.starts_with(&want), "{}", r.err);
    let r = duocan(&["station", "check", "/nonexistent/station.toml"]);
    assert_eq!(r.code, 2);
    assert!(
        r.err.contains("/nonexistent/station.toml: cannot read"),
        "{}",
        r.err
    );
}

#[test]
fn a_station_whose_buses_cannot_open_does_not_start() {
    let r = duocan(&[
        "station",
        "run",
        &file("tests/station_files/no_such_bus.toml"),
    ]);
    assert_eq!(r.code, 3, "{}", r.err);
    assert!(r.err.contains("network lab"), "{}", r.err);
    assert!(r.err.contains("duocan-none0"), "{}", r.err);
}

/// Two simulated networks: both start, their pairs' A members become active, and SIGTERM
/// stops the station cleanly (exit 0, "stopped" last), the NMT command of `on_stop` sent on
/// the network that has one.
#[test]
fn a_station_runs_its_networks_until_sigterm() {
    runs_until("TERM");
}

/// SIGINT (Ctrl-C) stops it the same way.
#[test]
fn a_station_runs_its_networks_until_sigint() {
    runs_until("INT");
}

fn runs_until(signal: &str) {
    let _one = common::one_station();
    let mut child = common::station_run(file("tests/station_files/two.toml"))
        .spawn()
        .expect("run duocan");
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let mut lines = vec![];
    let want = |l: &Vec<String>, net: &str| {
        l.iter().any(|x| {
            x.contains("pair 0x10/0x50: A active") && x.ends_with(&format!("network={net}"))
        })
    };
    let end = Instant::now() + Duration::from_secs(120);
    while !(want(&lines, "east") && want(&lines, "west")) {
        let left = end.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(l) => lines.push(l),
            Err(_) => {
                let _ = child.kill();
                panic!(
                    "no pair active on both networks in 120 s:\n{}",
                    lines.join("\n")
                );
            }
        }
    }
    let pid = child.id().to_string();
    let killed = Command::new("kill")
        .args([&format!("-{signal}"), &pid])
        .status()
        .expect("kill");
    assert!(killed.success());
    let status = child.wait().expect("wait");
    reader.join().expect("reader");
    lines.extend(rx.try_iter());
    let all = lines.join("\n");
    assert_eq!(status.code(), Some(0), "{all}");
    for net in ["east", "west"] {
        assert!(
            all.contains(&format!("started network={net} buses=sim-pairs:quiet")),
            "{all}"
        );
        assert!(
            all.contains(&format!("this master: active network={net}")),
            "{all}"
        );
    }
    assert!(
        all.contains(&format!("stopping: SIG{signal} station=two")),
        "{all}"
    );
    // `on_stop = "preop"` on east only.
    let sent: Vec<_> = lines.iter().filter(|l| l.contains("on_stop:")).collect();
    assert_eq!(sent.len(), 1, "{all}");
    assert!(
        sent[0].contains("on_stop: EnterPreOperational sent to every node")
            && sent[0].ends_with("network=east"),
        "{all}"
    );
    assert!(
        lines
            .last()
            .is_some_and(|l| l.contains("stopped station=two")),
        "{all}"
    );
    // Every line is one record: a time, a level, the target.
    assert!(
        lines
            .iter()
            .all(|l| l.contains(" INFO ") || l.contains(" WARN ")),
        "{all}"
    );
}

/// A network on the railway 29-bit profile: `check` shows the profile, and `run` runs it on
/// the simulated plant, whose boards run in turn: A first, B once A stops (the plant's fault
/// script, 4 s in).
#[test]
fn a_station_runs_a_network_on_the_railway_29_bit_profile() {
    let rail = file("tests/station_files/railway.toml");
    let r = duocan(&["station", "check", &rail]);
    assert_eq!(r.code, 0, "{}", r.err);
    assert!(r.out.contains("profile railway29"), "{}", r.out);
    let _one = common::one_station();
    let mut child = common::station_run(&rail).spawn().expect("run duocan");
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().expect("stderr");
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let mut lines: Vec<String> = vec![];
    let has = |l: &Vec<String>, what: &str| l.iter().any(|x| x.contains(what));
    let end = Instant::now() + Duration::from_secs(120);
    while !has(&lines, "pair 0x10/0x50: B active") {
        let left = end.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(l) => lines.push(l),
            Err(_) => {
                let _ = child.kill();
                panic!("board B never ran in 120 s:\n{}", lines.join("\n"));
            }
        }
    }
    let _ = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    let _ = child.wait();
    reader.join().expect("reader");
    lines.extend(rx.try_iter());
    let all = lines.join("\n");
    assert!(
        all.contains("started network=rail buses=sim-pairs"),
        "{all}"
    );
    let at = |what: &str| lines.iter().position(|l| l.contains(what));
    let (a, b) = (
        at("pair 0x10/0x50: A active network=rail"),
        at("pair 0x10/0x50: B active network=rail"),
    );
    assert!(a.is_some() && a < b, "{all}");
}

/// The station's audit trail under SIGKILL: a station on two simulated networks whose plants
/// fail (buses, masters, boards: audit records) is killed with SIGKILL after its first, third
/// and fifth acknowledged record, and started again each time: every record acknowledged as
/// written is in its network's file, and every line there is a whole record.
#[test]
fn no_acknowledged_audit_record_is_lost_when_the_station_is_killed() {
    let net = |name: &str, id: u8| {
        format!(
            "[[network]]\nname = \"{name}\"\nbuses = \"sim-pairs\"\nnode_id = {id}\n\
             heartbeat_ms = 50\nmaster_timeout_ms = 200\npairs = [[0x10, 0x50], [0x11, 0x51]]\n\
             pair_heartbeat_ms = 50\npair_timeout_ms = 200\npeers = [{{ node = {} }}]\n\n",
            id + 1
        )
    };
    let networks = format!("{}{}", net("east", 1), net("west", 3));
    killed_three_times("kill", &networks, &["east", "west"], [1, 3, 5]);
}

/// The same on the shipped demonstration file's four racks (its networks under a station
/// section of the test's own, with an audit trail), killed after its first, 30th and 60th
/// acknowledged record: in the thick of its racks' start-up and failovers, the records
/// coming by the hundred a second. (How many a run writes depends on its plants' timing: one
/// in CI wrote 93 while the second kill waited for the 100th.)
#[test]
fn the_shipped_demo_loses_no_acknowledged_audit_record_when_killed() {
    let examples = std::path::PathBuf::from(file("../examples"));
    let demo = std::fs::read_to_string(examples.join("station/demo.toml")).unwrap();
    let racks = &demo[demo.find("[[network]]").expect("the demo's networks")..];
    let racks = racks.replace(
        "\"../demo/devices/",
        &format!("\"{}/", examples.join("demo/devices").display()),
    );
    let names = [
        "turnout rack",
        "signal rack",
        "track-circuit rack",
        "misc rack",
    ];
    killed_three_times("kill-demo", &racks, &names, [1, 30, 60]);
}

/// Runs a station on `networks` (station file text) with an audit trail, kills it with
/// SIGKILL after each run's `kills`-th acknowledged record and starts it again each time;
/// then checks that every acknowledged record is in its network's file and that every
/// line of each of `names`' files is a whole record.
fn killed_three_times(tag: &str, networks: &str, names: &[&str], kills: [usize; 3]) {
    let _one = common::one_station();
    let dir = std::env::temp_dir().join(format!("duocan-station-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let station = dir.join("killed.toml");
    std::fs::write(
        &station,
        format!("[station]\naudit_dir = \"trail\"\n\n{networks}"),
    )
    .unwrap();
    // A network's file, named as the station names it.
    let audit_file = |network: &str| {
        let name: String = network
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        dir.join("trail").join(format!("{name}.audit"))
    };
    let mut acked: Vec<(String, String, String)> = vec![];
    for kill_after in kills {
        let mut child = common::station_run(station.to_str().unwrap())
            .env(
                "DUOCAN_LOG",
                "warn,duocan::station=info,duocan::station::audit=debug",
            )
            .spawn()
            .expect("run duocan");
        let rx = stderr_lines(&mut child);
        let end = Instant::now() + Duration::from_secs(120);
        let mut this_run = 0;
        let mut seen = vec![];
        while let Some(line) = next_before(&rx, end) {
            seen.push(line.clone());
            if !line.contains("duocan::station::audit: written") {
                continue;
            }
            // The network's name may hold spaces: it runs up to the next field.
            let network = line
                .split_once("network=")
                .and_then(|(_, r)| r.split_once(" run="))
                .unwrap_or_else(|| panic!("no network in {line}"))
                .0
                .to_string();
            let field = |k: &str| {
                line.split(' ')
                    .find_map(|w| w.strip_prefix(&format!("{k}=")))
                    .unwrap_or_else(|| panic!("no {k} in {line}"))
                    .to_string()
            };
            acked.push((network, field("run"), field("seq")));
            this_run += 1;
            if this_run == kill_after {
                break;
            }
        }
        // Killed at once after the acknowledgement it read (or after the plants' end).
        let _ = child.kill();
        let _ = child.wait();
        assert_eq!(
            this_run,
            kill_after,
            "fewer records than expected:\n{}",
            seen.join("\n")
        );
    }
    assert_eq!(acked.len(), kills.iter().sum::<usize>());
    for (network, run, seq) in &acked {
        let file = audit_file(network);
        let text = std::fs::read_to_string(&file).unwrap();
        let want = format!(" run={run} #{seq} ");
        assert!(
            text.contains(&want),
            "{want:?} not in {}:\n{text}",
            file.display()
        );
    }
    for network in names {
        let text = std::fs::read_to_string(audit_file(network)).unwrap_or_default();
        for line in text.lines() {
            let mut words = line.splitn(4, ' ');
            let (t, run, rec) = (words.next(), words.next(), words.next());
            assert!(
                t.is_some_and(|t| t
                    .split_once('.')
                    .is_some_and(|(s, ms)| { s.parse::<u64>().is_ok() && ms.len() == 3 })),
                "{line}"
            );
            assert!(run.is_some_and(|r| r.starts_with("run=")), "{line}");
            assert!(rec.is_some_and(|r| r.starts_with('#')), "{line}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
