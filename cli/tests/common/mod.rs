//! Running the built `duocan` binary.

#![allow(dead_code)]

use std::process::{Command, Output, Stdio};

pub mod fd;

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
    run_of(o)
}

/// [`duocan`] with `input` on standard input (closed after it: a gateway's script).
pub fn duocan_with_input(args: &[&str], input: &str) -> Run {
    use std::io::Write;
    let mut child = Command::new(env!("CARGO_BIN_EXE_duocan"))
        .args(args)
        .env_remove("DUOCAN_BUS")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run duocan");
    let mut stdin = child.stdin.take().expect("stdin piped");
    stdin.write_all(input.as_bytes()).expect("write the input");
    drop(stdin);
    run_of(child.wait_with_output().expect("duocan ends"))
}

fn run_of(o: Output) -> Run {
    Run {
        code: o.status.code().unwrap_or(-1),
        out: String::from_utf8_lossy(&o.stdout).into_owned(),
        err: String::from_utf8_lossy(&o.stderr).into_owned(),
    }
}

/// Runs `duocan --bus sim-station` with `args` and expects exit 0.
pub fn sim_ok(args: &[&str]) -> String {
    let mut all = vec!["--bus", "sim-station"];
    all.extend_from_slice(args);
    let r = duocan(&all);
    assert_eq!(r.code, 0, "duocan {all:?} failed: {}", r.err);
    r.out
}

/// Runs `duocan --bus sim-station` with `args`; returns the run whatever its exit code.
pub fn sim(args: &[&str]) -> Run {
    let mut all = vec!["--bus", "sim-station"];
    all.extend_from_slice(args);
    duocan(&all)
}

/// One simulated station at a time from a test file: each is a dozen devices carrying two
/// buses at a real bus's rate in the tool's debug build, and several at once on a two-core
/// machine would each fall behind the clock (a slow test, or one whose waits run out, not a
/// finding about the tool). Hold the guard for the test.
pub fn one_station() -> std::sync::MutexGuard<'static, ()> {
    static ONE: std::sync::Mutex<()> = std::sync::Mutex::new(());
    ONE.lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// `duocan station run FILE` as the station tests start it: no `DUOCAN_LOG` or
/// `JOURNAL_STREAM` from the environment (the default log, each line with its time; a test may
/// set `DUOCAN_LOG` again), standard output dropped, standard error piped for the test to read.
pub fn station_run(file: impl AsRef<std::ffi::OsStr>) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_duocan"));
    c.args(["station", "run"])
        .arg(file)
        .env_remove("DUOCAN_LOG")
        .env_remove("JOURNAL_STREAM")
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    c
}
