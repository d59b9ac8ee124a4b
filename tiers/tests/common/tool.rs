//! Where the built `duocan` tool is, for the tier tests that run it.

use std::path::PathBuf;

/// target/<profile>/duocan, next to this test's target/<profile>/deps/.
pub fn tool() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    let bin = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("target/<profile>/deps/<test>")
        .join("duocan");
    assert!(
        bin.exists(),
        "{} is missing: build it first with `cargo build -p duocan-cli`",
        bin.display()
    );
    bin
}

/// Runs `duocan --bus <bus> <args>` (no `DUOCAN_BUS` from the environment): exit code, standard
/// output, standard error.
#[allow(dead_code)]
pub async fn duocan(bus: &str, args: &[&str]) -> (i32, String, String) {
    let out = tokio::process::Command::new(tool())
        .arg("--bus")
        .arg(bus)
        .args(args)
        .env_remove("DUOCAN_BUS")
        .output()
        .await
        .expect("run duocan");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}
