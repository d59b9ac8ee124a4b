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
