//! `duocan monitor` in plain mode (its standard output is a pipe here) against the simulated
//! nodes of `--bus sim`: lines with the time of day, status lines, JSON, and strict arguments.

mod common;
use common::{duocan, sim};

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
fn plain_lines_name_each_simulated_node_and_a_status_line_follows() {
    let r = sim(&["monitor", "--duration", "1.5", "--every", "0.6"]);
    assert_eq!(r.code, 0, "{}", r.err);
    let lines: Vec<&str> = r.out.lines().collect();
    for line in &lines {
        let (clock, _) = line.split_at(12);
        assert!(is_clock(clock), "no time of day in {line:?}");
    }
    // Each simulated node (1-10) is heard in its state, from its heartbeat.
    for id in 1..=10 {
        let want = format!("  node {id:#04x}: pre-operational");
        assert!(
            lines.iter().any(|l| l.ends_with(&want)),
            "no {want:?} in\n{}",
            r.out
        );
    }
    let status: Vec<&&str> = lines.iter().filter(|l| l.contains("  status: ")).collect();
    assert_eq!(
        status.len(),
        2,
        "two status lines in 1.5 s every 0.6 s:\n{}",
        r.out
    );
    let last = status[1];
    assert!(
        last.contains("status: 10 nodes (10 pre-operational); port sim ok rx "),
        "{last}"
    );
    // The sim bus's default pairs are shown; the simulated nodes 1-10 are not in them.
    assert!(
        last.contains("; pair 0x10/0x50 not heard; pair 0x11/0x51 not heard; master -"),
        "{last}"
    );
    // Listen-only: the monitor sent nothing.
    assert!(last.contains(" tx 0 errors 0"), "{last}");
}

#[test]
fn json_lines_are_objects_with_a_kind_and_status_has_the_tables() {
    let r = sim(&[
        "--json",
        "monitor",
        "--duration",
        "1.2",
        "--every",
        "1",
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
    assert_eq!(nodes.len(), 10);
    assert_eq!(nodes[4]["node"], 5);
    assert_eq!(nodes[4]["state"], "pre-operational");
    assert_eq!(nodes[4]["name"], "duocan simulated node");
    // The simulated nodes beat every 100 ms.
    let age = nodes[4]["heartbeat_age_ms"].as_u64().unwrap();
    assert!(age < 500, "heartbeat age {age} ms");
    assert_eq!(status["ports"][0]["name"], "sim");
    assert_eq!(status["ports"][0]["tx"], 0);
    // --pair replaces the default pairs: both members pre-operational, none active.
    assert_eq!(
        status["pairs"],
        serde_json::json!([{"members": [5, 6], "active": "none", "standby": null}])
    );
    assert_eq!(status["master"], serde_json::Value::Null);
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
        let mut all = vec!["--bus", "sim", "monitor"];
        all.extend(args.iter());
        let r = duocan(&all);
        assert_eq!(r.code, 2, "{all:?}: {}", r.err);
        assert!(r.err.contains(says), "{all:?}: {}", r.err);
    }
}
