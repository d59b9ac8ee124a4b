//! `duocan kit`: the scenarios shipped in `cli/scenarios/` read, and pass in the simulator;
//! a bound set too tight fails there with exit 1; bad files are exit 2 naming the problem.

mod common;
use common::duocan;
use std::path::PathBuf;

fn scenarios() -> Vec<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&dir)
        .expect("cli/scenarios")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

#[test]
fn the_shipped_scenarios_pass_in_the_simulator() {
    let all = scenarios();
    let names: Vec<String> = all
        .iter()
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        names,
        [
            "babbling_node",
            "board_power_loss",
            "bus_cut",
            "master_power_loss",
            "partition",
            "port_cut"
        ]
    );
    for p in &all {
        let f = p.to_str().unwrap();
        let r = duocan(&["kit", "validate", f]);
        assert_eq!(r.code, 0, "{f}: {}", r.err);
        let r = duocan(&["kit", "sim", f]);
        println!("{}", r.out);
        assert_eq!(r.code, 0, "{f}: {}{}", r.out, r.err);
        assert!(!r.out.contains("FAIL"), "{}", r.out);
        let v: serde_json::Value =
            serde_json::from_str(&duocan(&["--json", "kit", "sim", f]).out).unwrap();
        let rows = v.as_array().unwrap();
        assert!(rows.len() >= 2, "{v}");
        assert!(rows.iter().all(|r| r["result"] == true), "{v}");
    }
}

#[test]
fn a_bound_too_tight_fails_with_its_figure() {
    let dir = std::env::temp_dir().join(format!("duocan-kit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let src = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenarios/board_power_loss.toml"),
    )
    .unwrap();
    // The standby is started 300 ms after the last heartbeat (the pair timeout): 290 is too
    // tight.
    let tight = dir.join("tight.toml");
    std::fs::write(&tight, src.replace("within_ms = 400", "within_ms = 290")).unwrap();
    let r = duocan(&["kit", "sim", tight.to_str().unwrap()]);
    assert_eq!(r.code, 1, "{}", r.out);
    assert!(r.out.contains("FAIL"), "{}", r.out);
    assert!(r.out.contains("300.06 ms on vs1b"), "{}", r.out);
    assert!(r.err.contains("1 of 2 expectations failed"), "{}", r.err);

    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        src.replace("device = \"board_a\"", "device = \"board_z\""),
    )
    .unwrap();
    let r = duocan(&["kit", "validate", bad.to_str().unwrap()]);
    assert_eq!(r.code, 2);
    assert!(r.err.contains("\"board_z\" is not a device"), "{}", r.err);
    let r = duocan(&["kit", "sim", "/nonexistent.toml"]);
    assert_eq!(r.code, 2);
    assert!(r.err.contains("/nonexistent.toml"), "{}", r.err);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The complete scenario of the user guide's failover-testing chapter reads; with duocan boards
/// in place of the user's, it passes in the simulator.
#[test]
fn the_guide_scenario_reads_and_passes_with_duocan_boards() {
    let chapter = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../guide/src/failover-testing.md"),
    )
    .unwrap();
    let start = chapter
        .find("```toml\nname = \"board A loses power")
        .expect("the guide's scenario");
    let body = &chapter[start + "```toml\n".len()..];
    let toml = &body[..body.find("```").unwrap()];
    let dir = std::env::temp_dir().join(format!("duocan-kit-guide-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("guide.toml");
    std::fs::write(&f, toml).unwrap();
    let r = duocan(&["kit", "validate", f.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}", r.err);
    let ours = toml
        .replace(
            r#"["./my-board", "--node", "0x10", "vs1a", "vs2a"]"#,
            r#"["{duocan}", "--bus", "vs1a,vs2a", "device", "board", "--node", "0x10", "--heartbeat-ms", "100"]"#,
        )
        .replace(
            r#"["./my-board", "--node", "0x50", "vs1b", "vs2b"]"#,
            r#"["{duocan}", "--bus", "vs1b,vs2b", "device", "board", "--node", "0x50", "--heartbeat-ms", "100"]"#,
        );
    std::fs::write(&f, ours).unwrap();
    let r = duocan(&["kit", "sim", f.to_str().unwrap()]);
    assert_eq!(r.code, 0, "{}{}", r.out, r.err);
    assert_eq!(r.out.matches(" pass ").count(), 2, "{}", r.out);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The scenario with CANopenNode's canopend as both boards (`cli/scenarios/canopend/`, run on
/// vcan by the VM tier) reads, with its two restarted boards; the simulator, which stands in
/// only for duocan devices, refuses it naming the first device it cannot stand in for.
#[test]
fn the_canopend_scenario_reads_and_the_simulator_refuses_its_boards() {
    let f =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenarios/canopend/board_power_loss.toml");
    let f = f.to_str().unwrap();
    let r = duocan(&["--json", "kit", "validate", f]);
    assert_eq!(r.code, 0, "{}", r.err);
    let v: serde_json::Value = serde_json::from_str(&r.out).unwrap();
    assert_eq!(
        (v["devices"].as_u64(), v["expectations"].as_u64()),
        (Some(4), Some(8)),
        "{v}"
    );
    let r = duocan(&["kit", "sim", f]);
    assert_eq!(r.code, 2, "{}{}", r.out, r.err);
    assert!(
        r.err
            .contains("device \"board_a\": the simulator stands in only for duocan devices"),
        "{}",
        r.err
    );
}
