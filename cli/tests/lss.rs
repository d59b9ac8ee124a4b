//! `duocan lss` against the simulated station of `--bus sim-station`: its two boards without a node-ID
//! (vendor 0x00D0CA00, product 0x305, revision 1, serials 1 and 2) found, configured and
//! booted by fastscan; the single services with `--select`; refusals, timeouts and usage
//! errors with their exit codes.

mod common;
use common::{duocan, one_station, sim, sim_ok};
use serde_json::Value;

fn json(text: &str) -> Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
}

const VENDOR: u64 = 0x00D0_CA00;
const BOARD1: &str = "0xD0CA00:0x305:1:1";
const BOARD2: &str = "0xD0CA00:0x305:1:2";
/// The settle time of the fastscans here: two simulated boards' answers to one step are two
/// tasks apart on a loaded machine, not microseconds as on a wire. 10 ms was too short with
/// the machine's two cores busy (a board's confirmation came after the step had ended: 1 run
/// in 3 failed beside four busy loops); 30 ms held in every run.
const SETTLE: &str = "--settle-ms=30";

/// (serial, node, booted) of each row of a fastscan's JSON.
fn assigned(v: &Value) -> Vec<(u64, u64, bool)> {
    v["assigned"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            assert_eq!(r["vendor"], VENDOR);
            assert_eq!(r["product"], 0x305);
            assert_eq!(r["revision"], 1);
            let n = |k: &str| r[k].as_u64().unwrap();
            (n("serial"), n("node"), r["booted"].as_bool().unwrap())
        })
        .collect()
}

#[test]
fn fastscan_gives_each_board_the_next_free_node_id_and_they_boot() {
    let _one = one_station();
    let v = json(&sim_ok(&[
        "--json", "lss", "fastscan", "--assign", "0x20", SETTLE,
    ]));
    // Lowest identity first; each boots by itself with its new node-ID.
    assert_eq!(assigned(&v), [(1, 0x20, true), (2, 0x21, true)]);
    assert_eq!(v["stopped"], Value::Null);
    // Exactly the frames the protocol needs for these two identities: one reset, 128 bit
    // steps and 4 confirmations a board, configure node-ID and switch back, the last reset.
    assert_eq!(v["requests"], v["protocol"]["requests"]);
    assert_eq!(v["requests"], 2 * (1 + 128 + 4 + 2) + 1);
    assert_eq!(v["answers"], v["protocol"]["answers"]);
    let took = v["took_ms"].as_f64().unwrap();
    let waiting = v["protocol"]["waiting_ms"].as_f64().unwrap();
    assert!(
        took >= waiting,
        "took {took} ms, the waiting alone is {waiting} ms"
    );
    assert!(
        took < waiting + 5_000.0,
        "took {took} ms against {waiting} ms of waiting"
    );
}

#[test]
fn fastscan_prints_a_table_and_the_cost() {
    let _one = one_station();
    let out = sim_ok(&["lss", "fastscan", "--assign", "100", SETTLE]);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[0],
        "vendor      product     revision    serial      node  booted"
    );
    assert_eq!(
        lines[1],
        "0x00d0ca00  0x00000305  0x00000001  0x00000001  0x64  yes"
    );
    assert_eq!(
        lines[2],
        "0x00d0ca00  0x00000305  0x00000001  0x00000002  0x65  yes"
    );
    assert!(
        lines[3].starts_with("2 configured: 271 request frames, 360 answers, "),
        "{out}"
    );
    assert!(
        lines[3].contains("(the protocol: 271 requests, 360 answers, "),
        "{out}"
    );
}

#[test]
fn fastscan_follows_a_plan_by_identity_and_by_expected_identity() {
    let _one = one_station();
    let dir = std::env::temp_dir().join(format!("duocan-cli-lss-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plan = dir.join("plan.txt");
    std::fs::write(
        &plan,
        "# board 2 by its serial, any other of the product as 0x31\n\
         0x00D0CA00 0x305 1 2 0x30\n\
         0x00D0CA00 0x305 * * 0x31\n",
    )
    .unwrap();
    let p = plan.to_str().unwrap();
    let v = json(&sim_ok(&["--json", "lss", "fastscan", "--plan", p, SETTLE]));
    assert_eq!(assigned(&v), [(1, 0x31, true), (2, 0x30, true)]);

    // A plan that places board 1 only: board 2 is found, gets nothing, and the scan stops
    // there (exit 1) with board 1 configured and listed.
    std::fs::write(&plan, "0x00D0CA00 0x305 1 1 0x40\n").unwrap();
    let r = sim(&["--json", "lss", "fastscan", "--plan", p, SETTLE]);
    assert_eq!(r.code, 1, "{}", r.err);
    let v = json(&r.out);
    assert_eq!(assigned(&v), [(1, 0x40, true)]);
    assert_eq!(v["protocol"], Value::Null);
    assert!(
        v["stopped"]
            .as_str()
            .unwrap()
            .contains("the plan has no node-ID for vendor 0x00d0ca00 product 0x00000305 revision 0x00000001 serial 0x00000002"),
        "{v}"
    );
    assert!(
        r.err.contains("the slaves listed keep their node-IDs"),
        "{}",
        r.err
    );

    // A bad plan is a usage error naming the line, before anything is sent.
    std::fs::write(&plan, "0x00D0CA00 0x305 1 1\n").unwrap();
    let r = sim(&["lss", "fastscan", "--plan", p]);
    assert_eq!(r.code, 2);
    assert!(r.err.contains("plan.txt: line 1: "), "{}", r.err);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn select_then_inquire_configure_and_store() {
    let _one = one_station();
    let v = json(&sim_ok(&["--json", "lss", "--select", BOARD2, "inquire"]));
    assert_eq!(
        v.to_string(),
        r#"{"vendor":13683200,"product":773,"revision":1,"serial":2,"node_id":null}"#
    );
    let out = sim_ok(&["lss", "inquire", "serial", "--select", BOARD1]);
    assert_eq!(out, "part    value\nserial  0x00000001\n");
    let out = sim_ok(&["lss", "set-id", "0x30", "--select", BOARD1]);
    assert_eq!(
        out,
        "node-ID 0x30 configured (active at the slave's next reset-communication)\n"
    );
    let out = sim_ok(&[
        "--json",
        "lss",
        "set-bitrate",
        "250",
        "--activate",
        "20",
        "--select",
        BOARD1,
    ]);
    assert_eq!(json(&out).to_string(), r#"{"kbit":250,"activate_ms":20}"#);
    // The simulated boards have no medium: store is refused with code 1.
    let r = sim(&["lss", "store", "--select", BOARD1]);
    assert_eq!(r.code, 1);
    assert_eq!(
        r.err,
        "duocan: LSS, store configuration: the slave refused with code 1 (not supported, spec 0)\n"
    );
}

#[test]
fn no_answer_is_exit_1_with_what_to_do() {
    let _one = one_station();
    // Not in configuration mode: a slave ignores inquire.
    let r = sim(&["lss", "inquire", "node-id"]);
    assert_eq!(r.code, 1);
    assert!(
        r.err.contains("LSS, inquire node-ID: no slave answered in time: a slave serves it in configuration mode only"),
        "{}",
        r.err
    );
    let r = sim(&["lss", "--select", "0xD0CA00:0x305:1:3", "inquire"]);
    assert_eq!(r.code, 1);
    assert!(
        r.err
            .contains("switch state selective: no slave with this identity answered"),
        "{}",
        r.err
    );
}

#[test]
fn identify_by_range_and_non_configured() {
    let _one = one_station();
    let yes = |args: &[&str]| {
        let mut a = vec!["--json", "lss", "identify"];
        a.extend_from_slice(args);
        json(&sim_ok(&a))["answered"].as_bool().unwrap()
    };
    assert!(yes(&["--non-configured"]));
    assert!(yes(&["0xD0CA00", "0x305", "0-5", "2"]));
    assert!(yes(&["0xD0CA00", "0x305", "1", "0x2-0xFFFFFFFF"]));
    assert!(!yes(&["0xD0CA00", "0x305", "1", "3-9"]));
    assert!(!yes(&["0xD0CA00", "0x306", "1", "1-2"]));
    let out = sim_ok(&["lss", "identify", "0xD0CA00", "0x305", "2-3", "1-2"]);
    assert_eq!(out, "no slave in the ranges answered\n");
    let out = sim_ok(&["--json", "lss", "switch", "config"]);
    assert_eq!(json(&out).to_string(), r#"{"switched":"configuration"}"#);
}

#[test]
fn usage_errors_are_exit_2_before_anything_is_sent() {
    for (args, says) in [
        (
            &["lss", "fastscan"][..],
            "give --assign NEXT_FREE_FROM and/or --plan FILE",
        ),
        (
            &["lss", "fastscan", "--assign", "0"],
            "node-ID 0: a node-ID is 1-127",
        ),
        (
            &["lss", "switch", "config", "--select", BOARD1],
            "--select goes with inquire",
        ),
        (
            &["lss", "set-bitrate", "100"],
            "100 kbit/s is not in the CiA 301 table",
        ),
        (
            &["lss", "set-bitrate", "125", "--activate", "0"],
            "give a delay of 1 to 65535 ms",
        ),
        (&["lss", "set-id", "128"], "a node-ID is 1-127 (or `none`)"),
        (&["lss", "identify", "1", "2", "3"], "required"),
        (
            &["lss", "identify", "1", "2", "5-3", "1"],
            "the low end is above the high end",
        ),
        (
            &["lss", "identify", "--non-configured", "1"],
            "cannot be used with",
        ),
        (&["lss", "inquire", "everything"], "invalid value"),
        (
            &["lss", "select", "1", "2", "3", "-4"],
            "unexpected argument",
        ),
        (
            &["lss", "--select", "1:2:3", "store"],
            "give VENDOR:PRODUCT:REVISION:SERIAL",
        ),
        (
            &["lss", "fastscan", "--plan", "/nonexistent/plan.txt"],
            "/nonexistent/plan.txt",
        ),
    ] {
        let mut all = vec!["--bus", "sim-station"];
        all.extend_from_slice(args);
        let r = duocan(&all);
        assert_eq!(r.code, 2, "{args:?}: {}", r.err);
        assert!(r.err.contains(says), "{args:?}: {}", r.err);
    }
}
