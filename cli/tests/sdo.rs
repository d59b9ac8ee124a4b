//! `duocan sdo` and `duocan nmt` against the simulated nodes of `--bus sim-station`.

mod common;
use common::{duocan, one_station, sim, sim_ok};

#[test]
fn reads_by_index_by_name_and_as_json() {
    let _one = one_station();
    assert_eq!(
        sim_ok(&["sdo", "read", "5", "0x1018", "1", "u32"]),
        "13683200\n"
    );
    assert_eq!(
        sim_ok(&["sdo", "read", "5", "0x1018:1", "hex"]),
        "00 CA D0 00\n"
    );
    // The simulated nodes' description is attached: the type comes from it.
    assert_eq!(
        sim_ok(&["sdo", "read", "5", "Manufacturer device name"]),
        "duocan simulated node\n"
    );
    let v: serde_json::Value =
        serde_json::from_str(&sim_ok(&["--json", "sdo", "read", "5", "0x1018", "1"])).unwrap();
    assert_eq!(v["value"], 13_683_200);
    assert_eq!(v["name"], "Vendor-ID");
    assert_eq!(
        (v["index"].as_u64(), v["sub"].as_u64()),
        (Some(0x1018), Some(1))
    );
    assert_eq!(v["hex"], "00cad000");
}

#[test]
fn writes_and_verifies() {
    let _one = one_station();
    let out = sim_ok(&["sdo", "write", "5", "0x1017", "0", "u16", "250", "--verify"]);
    assert_eq!(out, "node 0x05 0x1017:00: written, 2 bytes, verified\n");
    let out = sim_ok(&[
        "sdo",
        "write",
        "5",
        "Producer heartbeat time",
        "300",
        "--verify",
    ]);
    assert!(out.ends_with("verified\n"), "{out}");
}

#[test]
fn errors_exit_1_for_the_network_and_2_for_the_command_line() {
    let _one = one_station();
    let r = sim(&["sdo", "read", "5", "0x1234", "1"]);
    assert_eq!(r.code, 1);
    assert!(
        r.err.contains("0x06020000 (object does not exist"),
        "{}",
        r.err
    );
    let r = sim(&["sdo", "write", "5", "0x1018", "1", "u32", "5"]);
    assert_eq!(r.code, 1);
    assert!(r.err.contains("read only"), "{}", r.err);
    let r = sim(&["--timeout", "50", "sdo", "read", "99", "0x1018", "0"]);
    assert_eq!(r.code, 1);
    assert!(r.err.contains("hint: `duocan scan`"), "{}", r.err);
    for bad in [
        &["sdo", "read", "5", "0x1018", "1", "u33"][..],
        &["sdo", "read", "0", "0x1018"],
        &["sdo", "read", "5", "0x10000"],
        &["sdo", "read", "5", "0x1018", "1", "u32", "extra"],
        &["sdo", "write", "5", "0x3000", "0", "250"],
        &["sdo", "write", "5", "0x1017", "0", "u16", "70000"],
        &["sdo", "read", "5", "No such entry"],
        &["nmt", "start", "all", "--wait"],
        &["nmt", "jump", "5"],
    ] {
        let r = sim(bad);
        assert_eq!(r.code, 2, "{bad:?}: {}", r.err);
        assert!(!r.err.contains("panicked"), "{bad:?}: {}", r.err);
    }
    let r = duocan(&["sdo", "read", "5", "0x1000"]);
    assert_eq!(r.code, 2);
    assert!(r.err.contains("no bus"), "{}", r.err);
}

/// `--bus sim-nodes` is the library's one-bus simulated network (nodes 1 to 10, their names
/// known); a bare `sim` is no network and the error names the ones there are.
#[test]
fn sim_nodes_is_one_bus_of_simulated_nodes_and_sim_names_none() {
    let r = duocan(&[
        "--bus",
        "sim-nodes",
        "sdo",
        "read",
        "10",
        "Manufacturer device name",
    ]);
    assert_eq!(
        (r.code, r.out.trim()),
        (0, "duocan simulated node"),
        "{}",
        r.err
    );
    let r = duocan(&["--bus", "sim", "sdo", "read", "5", "0x1000"]);
    assert_eq!(r.code, 2, "a usage error: {}", r.err);
    assert!(
        r.err.contains("sim-nodes") && r.err.contains("sim-station:faults"),
        "{}",
        r.err
    );
}

/// A bus that cannot be opened exits 3, not the usage error's 2; with `--json` the error is a
/// JSON object on standard error.
#[test]
fn a_bus_that_cannot_be_opened_has_its_own_exit_code() {
    let r = duocan(&["--bus", "dcnone0", "sdo", "read", "5", "0x1000"]);
    assert_eq!(r.code, 3, "{}", r.err);
    assert!(r.err.contains("dcnone0"), "{}", r.err);
    let r = duocan(&["--bus", "dcnone0,dcnone1", "--json", "nmt", "start", "all"]);
    assert_eq!(r.code, 3, "{}", r.err);
    let e: serde_json::Value = serde_json::from_str(r.err.trim()).expect("a JSON error");
    assert_eq!(e["exit"], 3, "{e}");
    assert!(e["error"].as_str().unwrap().contains("dcnone0"), "{e}");
    // A usage error with --json is JSON too, and still 2.
    let r = duocan(&["--json", "sdo", "read", "5", "0x1000"]);
    assert_eq!(r.code, 2, "{}", r.err);
    let e: serde_json::Value = serde_json::from_str(r.err.trim()).expect("a JSON error");
    assert!(e["error"].as_str().unwrap().contains("no bus"), "{e}");
}

#[test]
fn nmt_commands_and_their_answers() {
    let _one = one_station();
    assert_eq!(
        sim_ok(&["nmt", "start", "5", "--wait"]),
        "NMT start sent to node 0x05: operational\n"
    );
    assert_eq!(
        sim_ok(&["nmt", "reset-comm", "6", "--wait"]),
        "NMT reset-comm sent to node 0x06: boot-up\n"
    );
    assert_eq!(
        sim_ok(&["nmt", "stop", "all"]),
        "NMT stop sent to all nodes\n"
    );
    let v: serde_json::Value =
        serde_json::from_str(&sim_ok(&["--json", "nmt", "preop", "7", "--wait"])).unwrap();
    assert_eq!(v["answer"], "pre-operational");
}

/// 64 KiB both ways on the simulated station (its buses run at 1 Mbit/s; the mebibyte runs in
/// the python tier over the UDP bus), as the tool shows it: a domain written from a file by
/// block transfer and read back (`--verify`), and a program flashed; the progress lines (one
/// per tenth when not on a terminal) go to the log. Not more here, to keep the suite short:
/// the station carries its buses at a real bus's rate.
#[test]
fn a_domain_and_a_program_by_block_transfer_with_progress_in_the_log() {
    let _one = one_station();
    const LEN: usize = 64 * 1024;
    let dir = std::env::temp_dir().join(format!("duocan-qmib-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let image: Vec<u8> = (0..LEN as u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    let f = dir.join("image.bin");
    std::fs::write(&f, &image).unwrap();
    let f = f.to_str().unwrap();

    let r = sim(&[
        "sdo", "write", "6", "0x2002", "--file", f, "--block", "--crc", "--verify",
    ]);
    println!("{}{}", r.err, r.out);
    assert_eq!(r.code, 0, "{}", r.err);
    assert!(
        r.out.contains(&format!("written, {LEN} bytes")),
        "{}",
        r.out
    );
    assert!(r.out.ends_with("verified\n"), "{}", r.out);
    let tenths = r
        .err
        .lines()
        .filter(|l| l.contains(&format!("/{LEN} bytes (")))
        .count();
    assert!(
        tenths >= 10,
        "a progress line per tenth, each way: {}",
        r.err
    );

    let r = sim(&["flash", "5", f]);
    println!("{}{}", r.err, r.out);
    assert_eq!(r.code, 0, "{}", r.err);
    assert!(
        r.err.contains(&format!("{LEN}/{LEN} bytes (100%)")),
        "{}",
        r.err
    );
    assert!(r.out.contains("started"), "{}", r.out);
    let _ = std::fs::remove_dir_all(&dir);
}
