//! The failover kit for real: each shipped scenario (`cli/scenarios/`) run by `duocan kit run`
//! — the fault bridge between real interfaces, the masters and boards as separate processes —
//! with python-can's UDP bus standing in for vcan (each member interface a UDP bus of its own),
//! and its pass/fail compared with the same scenario in the simulator. Runs inside `unshare -n`
//! with the tool built first (`.ci/tier-python.sh` does both). The VM tier runs the same files
//! on vcan.

#[path = "common/tool.rs"]
mod tool;
use std::path::PathBuf;
use std::process::Command;
use tool::tool;

/// The scenario's member interfaces renamed to UDP buses 60–67.
fn on_udp(text: &str) -> String {
    let mut t = text.to_string();
    for (i, m) in [
        "vm1a", "vm1b", "vs1a", "vs1b", "vm2a", "vm2b", "vs2a", "vs2b",
    ]
    .iter()
    .enumerate()
    {
        t = t.replace(&format!("\"{m}"), &format!("\"udp:{}", 60 + i));
        t = t.replace(&format!(",{m}\""), &format!(",udp:{}\"", 60 + i));
    }
    t
}

#[test]
fn every_scenario_gives_the_same_verdicts_on_real_processes_as_in_the_simulator() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../cli/scenarios");
    let out = std::env::temp_dir().join(format!("duocan-kit-udp-{}", std::process::id()));
    std::fs::create_dir_all(&out).unwrap();
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert_eq!(files.len(), 6, "{files:?}");
    for f in files {
        let name = f.file_stem().unwrap().to_string_lossy().into_owned();
        let udp = out.join(format!("{name}.toml"));
        std::fs::write(&udp, on_udp(&std::fs::read_to_string(&f).unwrap())).unwrap();
        let verdicts = |args: &[&str]| {
            let o = Command::new(tool())
                .args(["--json", "kit"])
                .args(args)
                .output()
                .expect("run duocan");
            let text = String::from_utf8_lossy(&o.stdout).into_owned();
            // The last line is the expectations' table (a run prints its counters first).
            let last = text.lines().last().unwrap_or("[]").to_string();
            let v: serde_json::Value = serde_json::from_str(&last).unwrap_or_else(|e| {
                panic!("{name}: {e}: {text}{}", String::from_utf8_lossy(&o.stderr))
            });
            let results: Vec<(String, bool, String)> = v
                .as_array()
                .unwrap()
                .iter()
                .map(|r| {
                    (
                        r["expectation"].as_str().unwrap().to_string(),
                        r["result"].as_bool().unwrap(),
                        r["measured"].as_str().unwrap().to_string(),
                    )
                })
                .collect();
            (o.status.code(), results, text)
        };
        let logs = out.join(&name);
        let (real_code, real, text) = verdicts(&[
            "run",
            udp.to_str().unwrap(),
            "--out",
            logs.to_str().unwrap(),
        ]);
        let (sim_code, sim, _) = verdicts(&["sim", udp.to_str().unwrap()]);
        println!("== {name}\n{text}");
        for ((e, r, m), (_, s, sm)) in real.iter().zip(&sim) {
            println!(
                "  {e}\n    real: {} {m}\n    sim:  {} {sm}",
                pass(*r),
                pass(*s)
            );
        }
        assert_eq!(
            real.iter().map(|(e, r, _)| (e, r)).collect::<Vec<_>>(),
            sim.iter().map(|(e, s, _)| (e, s)).collect::<Vec<_>>(),
            "{name}: the verdicts differ"
        );
        assert_eq!((real_code, sim_code), (Some(0), Some(0)), "{name}");
    }
    let _ = std::fs::remove_dir_all(&out);
}

fn pass(p: bool) -> &'static str {
    if p {
        "pass"
    } else {
        "FAIL"
    }
}
