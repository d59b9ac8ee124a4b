//! In plain mode (standard output is a pipe here): lines with the time of day, status lines,
//! JSON, and strict arguments.

use super::common::{duocan, sim};
use super::STATION;

/// True for `HH:MM:SS.mmm`.
fn is_clock(s: &str) -> bool {
    let b = s.as_bytes();
    b.len() == 12
        && b.iter().enumerate().all(|(i, c)| match i {
            2 | 5 => *c == b':',
            8 => *c == b'.',
            _ => c.is_ascii_digit(),
        })
}

#[test]
fn plain_lines_name_the_station_s_nodes_and_a_status_line_sums_up() {
    // One status line, at 2 s: the B members are powered at 1 s.
    let r = sim(&["monitor", "--duration", "3", "--every", "2"]);
    assert_eq!(r.code, 0, "{}", r.err);
    let lines: Vec<&str> = r.out.lines().collect();
    for line in &lines {
        let (clock, _) = line.split_at(12);
        assert!(is_clock(clock), "no time of day in {line:?}");
    }
    // The slaves' and pair members' states come as the network's events.
    for (id, state) in &STATION[2..] {
        let want = format!("  node {id:#04x}: {state}");
        assert!(
            lines.iter().any(|l| l.ends_with(&want)),
            "no {want:?} in\n{}",
            r.out
        );
    }
    // The monitor's own observations: the master from its 0x71, the pairs' active members.
    for want in [
        "  monitor: active master 0x01, priority 0",
        "  monitor: pair 0x10/0x50: 0x10 active",
        "  monitor: pair 0x11/0x51: 0x11 active",
    ] {
        assert!(
            lines.iter().any(|l| l.ends_with(want)),
            "no {want:?} in\n{}",
            r.out
        );
    }
    let status: Vec<&&str> = lines.iter().filter(|l| l.contains("  status: ")).collect();
    assert_eq!(
        status.len(),
        1,
        "one status line in 3 s every 2 s:\n{}",
        r.out
    );
    let last = status[0];
    assert!(
        last.contains("status: 9 nodes (4 operational, 5 pre-operational); "),
        "{last}"
    );
    // Both ports, ok; listen-only: the monitor sent nothing.
    for port in ["sim-bus1", "sim-bus2"] {
        let p = format!("port {port} ok rx ");
        let at = last
            .find(&p)
            .unwrap_or_else(|| panic!("no {p:?} in {last}"));
        let rest = &last[at + p.len()..];
        let rx: u64 = rest.split(' ').next().unwrap().parse().unwrap();
        assert!(rx > 0, "{last}");
        assert!(rest.contains(" tx 0 errors 0;"), "{last}");
    }
    assert!(
        last.contains(
            "; pair 0x10/0x50 active 0x10 standby 0x50; pair 0x11/0x51 active 0x11 standby 0x51; \
             master 0x01 (priority 0), heartbeat "
        ),
        "{last}"
    );
}

#[test]
fn json_lines_are_objects_with_a_kind_and_status_has_the_tables() {
    let r = sim(&[
        "--json",
        "monitor",
        "--duration",
        "2.5",
        "--every",
        "1.5",
        "--pair",
        "5,6",
    ]);
    assert_eq!(r.code, 0, "{}", r.err);
    let values: Vec<serde_json::Value> = r
        .out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l:?}: {e}")))
        .collect();
    let state = values
        .iter()
        .find(|v| v["kind"] == "state" && v["node"] == 5)
        .expect("a state line for node 5");
    assert_eq!(state["text"], "node 0x05: pre-operational");
    assert!(is_clock(state["time"].as_str().unwrap()));
    let status = values
        .iter()
        .find(|v| v["kind"] == "status")
        .expect("a status line");
    let nodes = status["nodes"].as_array().unwrap();
    let ids: Vec<u64> = nodes.iter().map(|n| n["node"].as_u64().unwrap()).collect();
    assert_eq!(ids, STATION.map(|(id, _)| u64::from(id)));
    let five = &nodes[2];
    assert_eq!(five["state"], "pre-operational");
    assert_eq!(five["name"], "duocan simulated node");
    assert_eq!(five["emcy"], serde_json::Value::Null);
    let age = five["heartbeat_age_ms"].as_u64().unwrap();
    assert!(age < 500, "heartbeat age {age} ms");
    let ports = status["ports"].as_array().unwrap();
    assert_eq!(ports.len(), 2);
    assert_eq!(ports[1]["name"], "sim-bus2");
    assert_eq!(ports[1]["state"], "ok");
    assert_eq!(ports[1]["tx"], 0);
    // --pair replaces the default pairs: both members pre-operational, none active.
    assert_eq!(
        status["pairs"],
        serde_json::json!([{"members": [5, 6], "active": "none", "standby": null}])
    );
    assert_eq!(
        status["master"],
        serde_json::json!({"node": 1, "priority": 0})
    );
}

#[test]
fn bad_arguments_exit_2_naming_what_was_wrong() {
    for (args, says) in [
        (vec!["--pair", "5,5"], "different"),
        (vec!["--pair", "5"], "A,B"),
        (vec!["--pair", "5,200"], "1-127"),
        (vec!["--duration", "0"], "more than 0"),
        (vec!["--duration", "abc"], "a number"),
        (vec!["--every=-1"], "a number"),
        (vec!["--every", "1e3"], "a number"),
        (vec!["--duration", "100000"], "a day"),
    ] {
        let mut all = vec!["--bus", "sim-station", "monitor"];
        all.extend(args.iter());
        let r = duocan(&all);
        assert_eq!(r.code, 2, "{all:?}: {}", r.err);
        assert!(r.err.contains(says), "{all:?}: {}", r.err);
    }
}
