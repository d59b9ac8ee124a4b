//! Running the built `duocan` binary.

#![allow(dead_code)]

use std::process::{Command, Output};

/// What a run of the tool gave: exit code, standard output, standard error.
pub struct Run {
    pub code: i32,
    pub out: String,
    pub err: String,
}

/// Runs `duocan` with `args` (no `DUOCAN_BUS` from the environment).
pub fn duocan(args: &[&str]) -> Run {
    let o: Output = Command::new(env!("CARGO_BIN_EXE_duocan"))
        .args(args)
        .env_remove("DUOCAN_BUS")
        .output()
        .expect("run duocan");
    Run {
        code: o.status.code().unwrap_or(-1),
        out: String::from_utf8_lossy(&o.stdout).into_owned(),
        err: String::from_utf8_lossy(&o.stderr).into_owned(),
    }
}

/// Runs `duocan --bus sim` with `args` and expects exit 0.
pub fn sim_ok(args: &[&str]) -> String {
    let mut all = vec!["--bus", "sim"];
    all.extend_from_slice(args);
    let r = duocan(&all);
    assert_eq!(r.code, 0, "duocan {all:?} failed: {}", r.err);
    r.out
}

/// Runs `duocan --bus sim` with `args`; returns the run whatever its exit code.
pub fn sim(args: &[&str]) -> Run {
    let mut all = vec!["--bus", "sim"];
    all.extend_from_slice(args);
    duocan(&all)
}
