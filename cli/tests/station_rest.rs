//! The station's REST access (`duocan station run` with `http`), on simulated networks
//! (`sim-pairs:quiet`, whose boards are `duocan::net`'s simulated node): SDO reads give what
//! the boards hold, a write reads back, NMT stops a node and the status shows it, a forced
//! switch-over moves a pair to its other board; the read token cannot control, the control
//! token can, and every control action is in the audit trail; each error has its status and
//! says what was wrong, and a malformed request changes nothing; bodies and the control rate
//! are bounded.

#[path = "station_rest/client.rs"]
mod client;
mod common;
#[path = "station_mqtt/station.rs"]
#[allow(dead_code)]
mod station;
use client::{why, Client};
use serde_json::{json, Value};
use station::{log_until, station};
use std::path::PathBuf;

const READ: &str = "read-token-0123456789";
const CONTROL: &str = "control-token-0123456789";

/// A folder of the test's own, emptied.
fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("duocan-rest-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The two networks of `two.toml` ("east", and "west yard" to be named URL-encoded) under
/// the `[station]` table `head`, written to `dir`.
fn station_file(dir: &std::path::Path, head: &str) -> PathBuf {
    let two = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/station_files/two.toml"),
    )
    .unwrap();
    let two = two.replace("name = \"west\"", "name = \"west yard\"");
    let file = dir.join("rest.toml");
    std::fs::write(&file, format!("[station]\n{head}\n{two}")).unwrap();
    file
}

/// The station's address, once both networks run their pairs' A boards.
fn started(rx: &std::sync::mpsc::Receiver<String>, log: &mut Vec<String>) -> String {
    let line = log_until(rx, log, 120, "http listening on ");
    let addr = line.split("http listening on ").nth(1).unwrap().trim();
    for net in ["east", "west yard"] {
        log_until(
            rx,
            log,
            120,
            &format!("pair 0x10/0x50: A active network={net}"),
        );
    }
    addr.to_string()
}

const SDO: &str = "/api/networks/east/nodes/0x10/sdo";

#[test]
fn sdo_nmt_and_switch_over_by_role_with_each_error() {
    let _one = common::one_station();
    let d = dir("roles");
    let file = station_file(
        &d,
        &format!(
            "http = \"127.0.0.1:0\"\nhttp_token = \"{READ}\"\nhttp_control_token = \
             \"{CONTROL}\"\naudit_dir = \"trail\"\n"
        ),
    );
    // `check` says who may do what.
    let r = common::duocan(&["station", "check", file.to_str().unwrap()]);
    assert!(
        r.out.contains(
            "  http: 127.0.0.1:0, reads with http_token, control with http_control_token\n"
        ),
        "{}",
        r.out
    );
    let (mut child, rx) = station(&file);
    let mut log = vec![];
    let addr = started(&rx, &mut log);
    let reader = Client {
        addr: &addr,
        token: Some(READ),
    };
    let operator = reader.with(Some(CONTROL));
    // What each token may do, as the dashboard asks it before it offers operator actions.
    assert_eq!(reader.get("/api/role"), (200, json!({"role": "read"})));
    assert_eq!(operator.get("/api/role"), (200, json!({"role": "control"})));
    assert_eq!(reader.with(None).get("/api/role").0, 401);

    // Reads: what the simulated boards hold (vendor-ID, product code = node-ID), by network
    // name, URL-encoded name or index; the control token reads too.
    let (code, v) = reader.get(&format!("{SDO}/0x1018/1?type=u32"));
    assert_eq!(code, 200, "{v}");
    assert_eq!(
        v,
        json!({"network": "east", "node": 16, "index": "0x1018", "sub": 1, "type": "u32",
               "value": 0x00D0_CA00u32})
    );
    let (code, v) = operator.get("/api/networks/west%20yard/nodes/80/sdo/0x1018/2?type=u32");
    assert_eq!((code, &v["value"]), (200, &json!(0x50)), "{v}");
    let (code, v) = reader.get("/api/networks/1/nodes/16/sdo/0x1018/1?type=x32");
    assert_eq!((code, &v["value"]), (200, &json!("0x00D0CA00")), "{v}");
    // A size that is not the type's: the bytes.
    let (code, v) = reader.get(&format!("{SDO}/0x1018/1?type=u16"));
    assert_eq!(
        (code, &v["type"], &v["value"]),
        (200, &json!("hex"), &json!("00 CA D0 00")),
        "{v}"
    );

    // No token, a wrong one: 401; the read token cannot write: 403, and nothing changed.
    let output = format!("{SDO}/0x6200/1");
    let write = |c: &Client, value: &str| c.send("PUT", &output, Some(value));
    let (code, v) = reader.with(None).get(&format!("{SDO}/0x1018/1?type=u32"));
    assert_eq!(code, 401, "{v}");
    let (code, _) = write(&reader.with(None), r#"{"type":"u16","value":1234}"#);
    assert_eq!(code, 401);
    let (code, _) = write(
        &reader.with(Some("control-token-0123456788")),
        r#"{"type":"u16","value":1234}"#,
    );
    assert_eq!(code, 401);
    let (code, v) = write(&reader, r#"{"type":"u16","value":1234}"#);
    assert_eq!(code, 403, "{v}");
    assert!(why(&v).contains("may only read"), "{v}");
    let before = reader.get(&format!("{output}?type=u16")).1["value"].clone();
    assert_ne!(before, json!(1234));
    // The control token writes; the value reads back.
    let (code, v) = write(&operator, r#"{"type":"u16","value":1234}"#);
    assert_eq!((code, &v["value"]), (200, &json!(1234)), "{v}");
    let (code, v) = reader.get(&format!("{output}?type=u16"));
    assert_eq!((code, &v["value"]), (200, &json!(1234)), "{v}");

    // Malformed requests: 400 naming what was wrong, and the value is still 1234.
    for (body, want) in [
        (r#"{"type":"u16","value":70000}"#, "value: 70000: not a u16"),
        (r#"{"type":"u17","value":1}"#, "type \"u17\""),
        (r#"{"type":"u16"}"#, "body: missing field `value`"),
        (
            r#"{"type":"u16","value":1,"x":2}"#,
            "body: unknown field `x`",
        ),
        ("{", "body: "),
    ] {
        let (code, v) = write(&operator, body);
        assert_eq!(code, 400, "{body}: {v}");
        assert!(why(&v).starts_with(want), "{body}: {v}");
    }
    let (code, v) = operator.send(
        "PUT",
        "/api/networks/east/nodes/0x10/sdo/0x62zz/1",
        Some(r#"{"type":"u16","value":1}"#),
    );
    assert_eq!(code, 400, "{v}");
    assert!(why(&v).starts_with("index: "), "{v}");
    let (code, v) = reader.get(&format!("{SDO}/0x6200/256?type=u16"));
    assert_eq!(code, 400, "{v}");
    assert!(why(&v).starts_with("sub-index: "), "{v}");
    let (code, v) = reader.get(&format!("{output}?type=u16"));
    assert_eq!((code, &v["value"]), (200, &json!(1234)), "{v}");

    // Unknown network or node: 404; an object the node has not: its abort; no answer: 504.
    let (code, v) = reader.get("/api/networks/north/nodes/16/sdo/0x1000/0");
    assert_eq!(code, 404, "{v}");
    assert!(why(&v).contains("no network \"north\""), "{v}");
    let (code, v) = reader.get("/api/networks/7/nodes/16/sdo/0x1000/0");
    assert_eq!(code, 404, "{v}");
    let (code, v) = reader.get("/api/networks/east/nodes/200/sdo/0x1000/0");
    assert_eq!(code, 404, "{v}");
    assert!(why(&v).contains("no node 200"), "{v}");
    let (code, v) = reader.get(&format!("{SDO}/0x2fff/0?type=u32"));
    assert_eq!(code, 409, "{v}");
    assert_eq!(v["abort_code"], "0x06020000", "{v}");
    assert!(
        v["abort"].as_str().unwrap_or("").contains("does not exist"),
        "{v}"
    );
    let (code, v) = reader.get("/api/networks/east/nodes/0x7e/sdo/0x1000/0?type=u32");
    assert_eq!(code, 504, "{v}");
    assert_eq!(v["abort_code"], "0x05040000", "{v}");

    // NMT: the read token may not; a bad command changes nothing; stop is seen in the status.
    let nmt = "/api/networks/east/nmt";
    let (code, _) = reader.send("POST", nmt, Some(r#"{"command":"stop","node":80}"#));
    assert_eq!(code, 403);
    let (code, v) = operator.send("POST", nmt, Some(r#"{"command":"halt","node":80}"#));
    assert_eq!(code, 400, "{v}");
    assert!(
        why(&v).starts_with("command: \"halt\" is not an NMT command"),
        "{v}"
    );
    let (code, v) = operator.send("POST", nmt, Some(r#"{"command":"stop","node":128}"#));
    assert_eq!(code, 404, "{v}");
    let state = |v: &Value, id: &str| {
        v[0]["nodes"]
            .as_array()
            .and_then(|n| n.iter().find(|x| x["node"] == id))
            .map(|n| n["state"].clone())
    };
    let now = reader.get("/api/networks").1;
    assert_ne!(state(&now, "0x50"), Some(json!("stopped")), "{now}");
    let (code, v) = operator.send("POST", nmt, Some(r#"{"command":"stop","node":80}"#));
    assert_eq!(code, 200, "{v}");
    reader.get_until("/api/networks", 60, |v| {
        state(v, "0x50") == Some(json!("stopped"))
    });

    // A forced switch-over: the pair of west yard runs its B board.
    let (code, v) = reader.send("POST", "/api/networks/west%20yard/pairs/16/switch", None);
    assert_eq!(code, 403, "{v}");
    let (code, v) = operator.send("POST", "/api/networks/west%20yard/pairs/0x21/switch", None);
    assert_eq!(code, 404, "{v}");
    let (code, v) = operator.send(
        "POST",
        "/api/networks/west%20yard/pairs/16/switch",
        Some(r#"{"to":"C"}"#),
    );
    assert_eq!(code, 400, "{v}");
    let (code, v) = operator.send(
        "POST",
        "/api/networks/west%20yard/pairs/16/switch",
        Some(r#"{"to":"B"}"#),
    );
    assert_eq!(code, 200, "{v}");
    assert_eq!(
        v,
        json!({"network": "west yard", "pair": "0x10/0x50", "active": "B"})
    );
    reader.get_until("/api/networks", 60, |v| v[1]["pairs"][0]["active"] == "B");

    // LSS: no device without a node-ID on the simulated buses; a selection nobody answers is
    // 504, and configures nothing.
    let lss = "/api/networks/east/lss";
    let (code, _) = reader.send(
        "POST",
        lss,
        Some(r#"{"command":"identify-non-configured"}"#),
    );
    assert_eq!(code, 403);
    let (code, v) = operator.send(
        "POST",
        lss,
        Some(r#"{"command":"identify-non-configured"}"#),
    );
    assert_eq!(code, 200, "{v}");
    assert_eq!(v, json!({"network": "east", "non_configured": false}));
    let (code, v) = operator.send("POST", lss, Some(r#"{"command":"scan"}"#));
    assert_eq!(code, 400, "{v}");
    assert!(
        why(&v).starts_with("command: \"scan\" is not an LSS command"),
        "{v}"
    );
    // Fastscan: which node-IDs to give is asked for and checked; with no device without a
    // node-ID it finds none, having asked the bus (every first request unanswered).
    let (code, v) = operator.send("POST", lss, Some(r#"{"command":"fastscan"}"#));
    assert_eq!(code, 400, "{v}");
    assert!(why(&v).starts_with("assign: fastscan needs"), "{v}");
    let (code, v) = operator.send(
        "POST",
        lss,
        Some(r#"{"command":"fastscan","assign":[47,"0x20"]}"#),
    );
    assert_eq!(code, 400, "{v}");
    assert!(why(&v).starts_with("assign: [47, 32] is empty"), "{v}");
    let (code, v) = operator.send(
        "POST",
        lss,
        Some(r#"{"command":"fastscan","assign":[32,200]}"#),
    );
    assert_eq!(code, 400, "{v}");
    assert!(why(&v).starts_with("assign: 200 is not a node-ID"), "{v}");
    let (code, v) = operator.send(
        "POST",
        lss,
        Some(r#"{"command":"fastscan","assign":["0x20",47]}"#),
    );
    assert_eq!(code, 200, "{v}");
    assert_eq!(v["network"], "east", "{v}");
    assert_eq!(v["assigned"], json!([]), "{v}");
    assert_eq!(v["stopped"], Value::Null, "{v}");
    assert!(v["requests"].as_u64().is_some_and(|n| n >= 1), "{v}");
    assert_eq!(v["answers"], 0, "{v}");
    let (code, v) = operator.send("POST", lss, Some(r#"{"command":"configure","node":48}"#));
    assert_eq!(code, 400, "{v}");
    assert!(why(&v).starts_with("address: "), "{v}");
    let nobody = r#"{"command":"configure","node":48,
        "address":{"vendor":1,"product":2,"revision":3,"serial":4}}"#;
    let (code, v) = operator.send("POST", lss, Some(nobody));
    assert_eq!(code, 504, "{v}");

    let _ = child.kill();
    let _ = child.wait();
    log.extend(rx.try_iter());
    // Every control action taken: in the log and in its network's audit file, with who.
    let all = log.join("\n");
    assert!(
        all.contains("duocan::station::control: sdo write node 0x10 0x6200:1 u16 1234: done"),
        "{all}"
    );
    assert!(
        all.lines().any(
            |l| l.contains("duocan::station::control: nmt stop node 0x50: done")
                && l.contains(" role=control-token client=127.0.0.1:")
        ),
        "{all}"
    );
    let east = std::fs::read_to_string(d.join("trail/east.audit")).unwrap();
    for what in [
        "sdo write node 0x10 0x6200:1 u16 1234: done",
        "nmt stop node 0x50: done",
        "lss identify-non-configured: done",
        "lss fastscan 0x20-0x2f: 0 assigned",
    ] {
        let line = east
            .lines()
            .find(|l| l.ends_with(what))
            .unwrap_or_else(|| panic!("{what:?} not in:\n{east}"));
        assert!(
            line.contains(" operator role=control-token client=127.0.0.1:"),
            "{line}"
        );
    }
    // A failed one too, with why.
    assert!(
        east.contains(
            "lss configure 0x00000001:0x00000002:0x00000003:0x00000004 node 0x30: failed: "
        ),
        "{east}"
    );
    // Refused requests are not actions: no write of 70000, no halt.
    assert!(!east.contains("70000") && !east.contains("halt"), "{east}");
    let west = std::fs::read_to_string(d.join("trail/west_yard.audit")).unwrap_or_default();
    assert!(west.contains("switch pair 0x10/0x50 to B: done"), "{west}");
    let _ = std::fs::remove_dir_all(&d);
}

/// Control opened to loopback clients (no token): a body over 4 KiB is 413, and control
/// requests beyond the burst are 429 while reads go on.
#[test]
fn bodies_and_the_control_rate_are_bounded() {
    let _one = common::one_station();
    let d = dir("bounds");
    let file = station_file(&d, "http = \"127.0.0.1:0\"\nhttp_control = \"loopback\"\n");
    let r = common::duocan(&["station", "check", file.to_str().unwrap()]);
    assert!(
        r.out
            .contains("  http: 127.0.0.1:0, reads open, control open to loopback clients\n"),
        "{}",
        r.out
    );
    let (mut child, rx) = station(&file);
    let mut log = vec![];
    let addr = started(&rx, &mut log);
    let c = Client {
        addr: &addr,
        token: None,
    };
    // Loopback control: any client of the address controls, the dashboard too.
    assert_eq!(c.get("/api/role"), (200, json!({"role": "control"})));
    let big = format!(r#"{{"type":"vs","value":"{}"}}"#, "x".repeat(5000));
    let (code, v) = c.send("PUT", &format!("{SDO}/0x6200/1"), Some(&big));
    assert_eq!(code, 413, "{v}");
    // Malformed, so that none changes anything: 400 until the bucket is empty (less the one
    // the 413 took: a control request counts once its role is checked), then 429. Sent from
    // eight clients at once, so that the bucket empties faster than it refills however slow
    // the machine.
    let codes: Vec<u16> = std::thread::scope(|s| {
        let clients: Vec<_> = (0..8)
            .map(|_| {
                s.spawn(|| {
                    (0..15)
                        .map(|_| {
                            let bad = r#"{"command":"halt","node":0}"#;
                            c.send("POST", "/api/networks/east/nmt", Some(bad)).0
                        })
                        .collect::<Vec<u16>>()
                })
            })
            .collect();
        clients
            .into_iter()
            .flat_map(|t| t.join().unwrap())
            .collect()
    });
    let count = |want: u16| codes.iter().filter(|&&c| c == want).count();
    assert!(count(429) > 0, "{codes:?}");
    assert!(count(400) >= 19, "{codes:?}");
    assert_eq!(count(400) + count(429), codes.len(), "{codes:?}");
    let (code, v) = c.get(&format!("{SDO}/0x1018/1?type=u32"));
    assert_eq!((code, &v["value"]), (200, &json!(0x00D0_CA00u32)), "{v}");
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&d);
}

/// A board whose DCF the station file names, on a network whose file names the CiA 302-6
/// policy: `check` shows both, the status the policy run; at boot the
/// master writes the DCF's value (Output 1 = 0x1234); REST reads and writes the board's entries
/// by name and types them by the description; a board without one asks for INDEX/SUB and a
/// type.
#[test]
fn a_boards_dcf_configures_it_at_boot_and_names_its_entries() {
    let _one = common::one_station();
    let d = dir("boards");
    let file = station_file(&d, "http = \"127.0.0.1:0\"\nhttp_control = \"loopback\"\n");
    let dcf = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/station_files/board.dcf");
    let text = std::fs::read_to_string(&file).unwrap().replacen(
        "pairs = [[0x10, 0x50]]",
        &format!(
            "pairs = [[0x10, 0x50]]\nboards = [{{ node = 0x10, dcf = {:?} }}]\n\
             link = \"cia302-6\"",
            dcf.display().to_string()
        ),
        1,
    );
    std::fs::write(&file, text).unwrap();
    let r = common::duocan(&["station", "check", file.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.err);
    let want = format!(
        "    link cia302-6, default bus 1, profile predefined\n    board 0x10: dcf {} (1 \
         writes at boot)\n",
        dcf.display()
    );
    assert!(r.out.contains(&want), "{}", r.out);
    let (mut child, rx) = station(&file);
    let mut log = vec![];
    let addr = started(&rx, &mut log);
    let c = Client {
        addr: &addr,
        token: None,
    };
    // The network runs the policy its file names; the other one the default.
    let (code, v) = c.get("/api/networks");
    assert_eq!(code, 200, "{v}");
    assert_eq!(v[0]["link"], json!("CiA 302-6 active-standby"), "{v}");
    assert_eq!(v[1]["link"], json!("active-active"), "{v}");
    // Written at boot, read by its name and typed by the description.
    let v = c.get_until(&format!("{SDO}/Output%201"), 60, |v| {
        v["value"] == json!(0x1234)
    });
    assert_eq!(
        v,
        json!({"network": "east", "node": 16, "index": "0x6200", "sub": 1, "type": "u16",
               "value": 0x1234, "name": "Output 1"})
    );
    // By INDEX/SUB without a type: the described one.
    let (code, v) = c.get(&format!("{SDO}/0x6200/1"));
    assert_eq!(
        (code, &v["type"], &v["value"]),
        (200, &json!("u16"), &json!(0x1234)),
        "{v}"
    );
    // A type asked for still wins.
    let (code, v) = c.get(&format!("{SDO}/identity%20object.vendor-id?type=x32"));
    assert_eq!((code, &v["value"]), (200, &json!("0x00D0CA00")), "{v}");
    // Written by name, the type from the description.
    let (code, v) = c.send("PUT", &format!("{SDO}/Output%201"), Some(r#"{"value":77}"#));
    assert_eq!(
        (code, &v["value"], &v["type"]),
        (200, &json!(77), &json!("u16")),
        "{v}"
    );
    let (code, v) = c.get(&format!("{SDO}/0x6200/1"));
    assert_eq!((code, &v["value"]), (200, &json!(77)), "{v}");
    // Names the description does not have, a node without one, a write without a type.
    let (code, v) = c.get(&format!("{SDO}/no%20such%20entry"));
    assert_eq!(code, 404, "{v}");
    assert!(why(&v).starts_with("node 0x10: "), "{v}");
    let (code, v) = c.get("/api/networks/east/nodes/0x50/sdo/Output%201");
    assert_eq!(code, 404, "{v}");
    assert!(why(&v).contains("has no description"), "{v}");
    let (code, v) = c.send(
        "PUT",
        "/api/networks/east/nodes/0x50/sdo/0x6200/1",
        Some(r#"{"value":1}"#),
    );
    assert_eq!(code, 400, "{v}");
    assert!(why(&v).starts_with("type: missing"), "{v}");
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&d);
}
