//! `duocan scan`, `pdo`, `eds` and `flash` against the simulated nodes of `--bus sim-station`.

mod common;
#[path = "common/eds_compare.rs"]
mod eds_compare;
use common::{duocan, one_station, sim, sim_ok};
use eds_compare::{differences, read_eds};
use serde_json::Value;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// The simulated redundant station: masters 0x01 and 0x02, the pairs 0x10/0x50 and 0x11/0x51,
/// the slaves 0x05-0x07.
const SIM_NODES: [u64; 9] = [0x01, 0x02, 0x05, 0x06, 0x07, 0x10, 0x11, 0x50, 0x51];

fn json(text: &str) -> Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
}

/// A fresh directory for one test's files.
fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("duocan-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn scan_finds_exactly_the_simulated_nodes_with_their_identity() {
    let _one = one_station();
    let t = Instant::now();
    let v = json(&sim_ok(&["--json", "scan"]));
    let took = t.elapsed();
    let rows = v.as_array().unwrap();
    let ids: Vec<u64> = rows.iter().map(|r| r["node"].as_u64().unwrap()).collect();
    assert_eq!(ids, SIM_NODES);
    for r in rows {
        let id = r["node"].as_u64().unwrap();
        assert!(r["state"].is_string(), "heard: {r}");
        // Two buses: every node is heard on both.
        assert_eq!(
            (&r["bus_1"], &r["bus_2"]),
            (&Value::Bool(true), &Value::Bool(true)),
            "{r}"
        );
        // The sim's own description is not an identity claim.
        assert_eq!(r["description"], Value::Null);
        if id <= 2 {
            continue; // the masters: a default identity
        }
        assert_eq!(r["vendor"], 0x00D0_CA00, "{r}");
        assert_eq!(r["product"], id, "{r}");
        if (5..=7).contains(&id) {
            assert_eq!(r["name"], "duocan simulated node");
        }
    }
    // 127 IDs probed at once with 100 ms each, and 1.5 s of listening: under 2 s on a quiet
    // machine; a generous bound for a loaded one.
    assert!(took < Duration::from_secs(8), "scan took {took:?}");
}

#[test]
fn scan_text_lines_up_and_listening_alone_finds_the_heartbeats() {
    let _one = one_station();
    // The B members are powered 1 s after the station starts: 1.5 s of listening hears them.
    let out = sim_ok(&["scan", "--no-probe"]);
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].starts_with("node  state "), "{out}");
    assert!(lines[0].ends_with("description  bus 1  bus 2"), "{out}");
    assert_eq!(lines.len(), 1 + SIM_NODES.len(), "{out}");
    let five = lines[3];
    assert!(five.starts_with("0x05  "), "{out}");
    assert!(
        five.contains("  0x00000000   0x00d0ca00  0x00000005  0x00000000  0x00000000  duocan simulated node  -            yes    yes"),
        "{out}"
    );
}

#[test]
fn scan_shows_the_bus_a_node_is_no_longer_heard_on() {
    let _one = one_station();
    // sim-station:faults cuts the tool's connection to bus 1 from 2 s to 4 s: a scan that ends in
    // between hears every node on bus 2 only.
    let r = duocan(&[
        "--bus",
        "sim-station:faults",
        "--json",
        "scan",
        "--listen",
        "3000",
    ]);
    assert_eq!(r.code, 0, "{}", r.err);
    let v = json(&r.out);
    let rows = v.as_array().unwrap();
    assert!(rows.len() >= 7, "{v}");
    for r in rows {
        assert_eq!(
            (&r["bus_1"], &r["bus_2"]),
            (&Value::Bool(false), &Value::Bool(true)),
            "{r}"
        );
    }
}

#[test]
fn scan_compares_attached_descriptions_with_the_identity() {
    let _one = one_station();
    let dir = temp_dir("scan-desc");
    // The sim nodes' EDS as node 6 reads it: product code 6.
    let eds = dir.join("node6.eds");
    let r = sim(&["eds", "export", "6", "-o", eds.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.err);
    let arg6 = format!("6={}", eds.display());
    let arg7 = format!("7={}", eds.display());
    let v = json(&sim_ok(&[
        "--eds", &arg6, "--eds", &arg7, "--json", "scan", "--listen", "200",
    ]));
    let row = |id: u64| {
        v.as_array()
            .unwrap()
            .iter()
            .find(|r| r["node"] == id)
            .cloned()
            .unwrap()
    };
    assert_eq!(row(6)["description"], "node6.eds");
    assert_eq!(
        row(7)["description"],
        "MISMATCH: product 0x7, file says 0x6"
    );
    assert_eq!(row(5)["description"], Value::Null);
}

#[test]
fn pdo_show_lists_the_pdos_with_names() {
    let _one = one_station();
    let out = sim_ok(&["pdo", "show", "5"]);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 9, "{out}");
    assert_eq!(
        lines[1],
        "0x05  TPDO 1  0x185   yes      254         0        0 ms         0x6000:01/16 Input 1, 0x6000:03/8 Status"
    );
    assert!(
        lines[5].contains("RPDO 1") && lines[5].contains("0x6200:02/8 Output 2"),
        "{out}"
    );
    let v = json(&sim_ok(&["--json", "pdo", "show", "6"]));
    let t1 = &v[0];
    assert_eq!(t1["pdo"], "TPDO 1");
    assert_eq!(t1["cob-id"], 0x186);
    assert_eq!(t1["enabled"], true);
    assert_eq!(t1["entries"][1]["name"], "Status");
    assert_eq!(t1["entries"][1]["bits"], 8);
}

#[test]
fn pdo_map_changes_a_mapping_and_reads_it_back() {
    let _one = one_station();
    let v = json(&sim_ok(&[
        "--json",
        "pdo",
        "map",
        "5",
        "tpdo",
        "2",
        "--clear",
        "--add",
        "Input 2",
        "--add",
        "0x6000:3:8",
        "--add",
        "0x6000:1",
        "--trans-type",
        "1",
        "--event-timer",
        "250",
        "--enable",
    ]));
    let m = &v[0];
    assert_eq!(m["pdo"], "TPDO 2");
    assert_eq!(m["enabled"], true);
    assert_eq!(m["trans_type"], 1);
    assert_eq!(m["event_timer"], 250);
    let entries: Vec<(u64, u64, u64, &str)> = m["entries"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["index"].as_u64().unwrap(),
                e["sub"].as_u64().unwrap(),
                e["bits"].as_u64().unwrap(),
                e["name"].as_str().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        entries,
        [
            (0x6000, 2, 16, "Input 2"),
            (0x6000, 3, 8, "Status"),
            (0x6000, 1, 16, "Input 1")
        ]
    );
    // Disabling keeps the mapping; the text names the change.
    let out = sim_ok(&["pdo", "map", "5", "rpdo", "1", "--disable"]);
    assert!(
        out.lines()
            .nth(1)
            .unwrap()
            .starts_with("0x05  RPDO 1  0x205   no "),
        "{out}"
    );
}

#[test]
fn pdo_map_refuses_bad_requests_before_sending_and_reports_aborts() {
    let _one = one_station();
    for bad in [
        &["pdo", "map", "5", "tpdo", "0"][..],
        &["pdo", "map", "5", "tpdo", "513"],
        &["pdo", "map", "5", "xpdo", "1"],
        &["pdo", "map", "5", "tpdo", "2", "--add", "0x6000:1:65"],
        &["pdo", "map", "5", "tpdo", "2", "--add", "No such input"],
        &["pdo", "map", "5", "rpdo", "1", "--inhibit", "5"],
        &["pdo", "map", "5", "tpdo", "2", "--enable", "--disable"],
    ] {
        let r = sim(bad);
        assert_eq!(r.code, 2, "{bad:?}: {}", r.err);
        assert!(!r.err.contains("panicked"), "{bad:?}: {}", r.err);
    }
    // Too many bits for one PDO: the library says so (a usage error, nothing written).
    let r = sim(&[
        "pdo",
        "map",
        "5",
        "tpdo",
        "1",
        "--add",
        "0x6000:1:32",
        "--add",
        "0x6000:2:32",
    ]);
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(r.err.contains("64 bits"), "{}", r.err);
    // The simulated nodes cannot store parameters: the node's abort, exit 1.
    let r = sim(&["pdo", "map", "5", "tpdo", "1", "--store"]);
    assert_eq!(r.code, 1, "{}", r.err);
    assert!(r.err.contains("0x08000020"), "{}", r.err);
}

const WARN_EDS: &str = "\
[FileInfo]
FileName=warn.eds
[DeviceInfo]
VendorName=ACME
[MandatoryObjects]
SupportedObjects=1
1=0x1017
[1017]
ParameterName=Producer heartbeat time
DataType=0x0006
AccessType=rw
DefaultValue=1000
DefaultValue=2000
";

#[test]
fn eds_validate_names_every_problem_with_its_line() {
    let _one = one_station();
    let dir = temp_dir("validate");
    let warn = dir.join("warn.eds");
    std::fs::write(&warn, WARN_EDS).unwrap();
    let long = dir.join("long.eds");
    let mut text = "[FileInfo]\nFileName=long.eds\n[Comments]\nLines=1\nLine1=".to_string();
    text.push_str(&"x".repeat(9000));
    std::fs::write(&long, text).unwrap();
    let good = dir.join("good.eds");
    let r = sim(&["eds", "export", "7", "-o", good.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.err);

    // Warnings only: exit 0, each with its line; --strict makes them fatal.
    let r = duocan(&["eds", "validate", warn.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.err);
    let w = warn.display();
    assert_eq!(
        r.out,
        format!(
            "{w}:13: [1017] DefaultValue: warning: the key appears twice; taken: \"2000\", the last one (the first is on line 12)\n\
             {w}: warning: mandatory object 0x1000 is missing; taken: the file as it is\n\
             {w}: warning: mandatory object 0x1001 is missing; taken: the file as it is\n\
             {w}: warning: mandatory object 0x1018 is missing; taken: the file as it is\n\
             {w}: 4 warnings, strict read fails\n"
        )
    );
    let r = duocan(&["eds", "validate", "--strict", warn.to_str().unwrap()]);
    assert_eq!(r.code, 1, "{}", r.err);

    // An error (a line past the 8 KiB cap) is exit 1; the good file is ok.
    let r = duocan(&[
        "--json",
        "eds",
        "validate",
        good.to_str().unwrap(),
        long.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 1, "{}", r.err);
    let v = json(&r.out);
    assert_eq!(v[0]["verdict"], "ok");
    assert_eq!(v[0]["strict_ok"], true);
    assert_eq!(v[1]["verdict"], "error");
    assert_eq!(v[1]["problems"][0]["line"], 5);
    assert_eq!(v[1]["problems"][0]["level"], "error");

    // A file that cannot be read at all: exit 2, after the others were checked.
    let missing = dir.join("missing.eds");
    let r = duocan(&[
        "eds",
        "validate",
        warn.to_str().unwrap(),
        missing.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(r.out.contains("4 warnings"), "{}", r.out);
    assert!(r.out.contains("missing.eds: unreadable"), "{}", r.out);
}

#[test]
fn eds_export_of_a_sim_node_validates_and_describes_it() {
    let _one = one_station();
    let dir = temp_dir("export");
    let eds = dir.join("n5.eds");
    let r = sim(&["eds", "export", "5", "-o", eds.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.err);
    assert!(r.out.contains("entries read"), "{}", r.out);
    let r = duocan(&["eds", "validate", "--strict", eds.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}{}", r.out, r.err);
    let text = std::fs::read_to_string(&eds).unwrap();
    // The identity as read: vendor, and product code = node-ID.
    assert!(text.contains("VendorNumber=0xD0CA00"), "{text}");
    assert!(text.contains("ProductNumber=5\n"), "{text}");

    // A scan of 0x1000-0x1FFF without the description, and a DCF with the live values.
    let scanned = dir.join("n5-scan.eds");
    let r = sim(&[
        "eds",
        "export",
        "5",
        "--scan",
        "-o",
        scanned.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.err);
    let r = duocan(&["eds", "validate", "--strict", scanned.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}{}", r.out, r.err);
    let text = std::fs::read_to_string(&scanned).unwrap();
    assert!(text.contains("[1018]"), "{text}");
    assert!(text.contains("[1800]"), "{text}");
    // Entry by entry what the export from the description has in the scanned range: the
    // error history's slots past its count, the PDO mappings' entries past theirs, every PDO
    // and SDO parameter writable.
    let diff = differences(&read_eds(&eds), &read_eds(&scanned), 5, 0x1000..=0x1FFF);
    assert!(diff.is_empty(), "the scan differs:\n{}", diff.join("\n"));
    let dcf = dir.join("n5.dcf");
    let r = sim(&[
        "eds",
        "export",
        "5",
        "--as-dcf",
        "-o",
        dcf.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.err);
    let text = std::fs::read_to_string(&dcf).unwrap();
    assert!(
        text.contains("NodeID=5") || text.contains("NodeID=0x5"),
        "{text}"
    );
    assert!(text.contains("ParameterValue="), "{text}");
    // And the DCF attaches like any description: names work with it.
    let arg = format!("6={}", dcf.display());
    assert_eq!(
        sim_ok(&["--dcf", &arg, "sdo", "read", "6", "Producer heartbeat time"]),
        "100\n"
    );
}

#[test]
fn a_file_that_is_no_description_or_an_empty_image_is_refused() {
    let _one = one_station();
    let dir = temp_dir("not-eds");
    let noise = dir.join("noise.bin");
    let bytes: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    std::fs::write(&noise, bytes).unwrap();
    let r = duocan(&["eds", "validate", noise.to_str().unwrap()]);
    assert_eq!(r.code, 1, "{}", r.out);
    assert!(r.out.contains("not a device description"), "{}", r.out);
    let arg = format!("5={}", noise.display());
    let r = sim(&["--eds", &arg, "sdo", "read", "5", "0x1000", "0", "u32"]);
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(r.err.contains("not a device description"), "{}", r.err);
    let r = sim(&["flash", "5", "/dev/null"]);
    assert_eq!(r.code, 2, "{}", r.err);
    assert!(r.err.contains("the image is empty"), "{}", r.err);
}

#[test]
fn flash_on_a_node_without_program_download_fails_with_the_abort() {
    let _one = one_station();
    let dir = temp_dir("flash-none");
    let img = dir.join("img.bin");
    std::fs::write(&img, vec![0xA5u8; 4096]).unwrap();
    let r = sim(&["flash", "6", img.to_str().unwrap()]);
    assert_eq!(r.code, 1, "{}", r.err);
    assert!(
        r.err.contains("stop (0x1F51 = 0)") && r.err.contains("0x06020000"),
        "{}",
        r.err
    );
    let r = sim(&["flash", "5", dir.join("nothing.bin").to_str().unwrap()]);
    assert_eq!(r.code, 2, "{}", r.err);
    let r = sim(&["flash", "5", img.to_str().unwrap(), "--program", "0"]);
    assert_eq!(r.code, 2, "{}", r.err);
}
