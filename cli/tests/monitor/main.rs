//! `duocan monitor` against the simulated redundant station of `--bus sim-station`: plain and JSON
//! lines (`plain`), and the full screen in a real terminal driven through tmux (`tmux`, with
//! the `peers` feature).

#[path = "../common/mod.rs"]
mod common;
mod plain;
// Needs tmux: run by `.ci/run` (`--features peers`), not by `cargo test --workspace`.
#[cfg(feature = "peers")]
mod tmux;

/// The nodes of the simulated station and the state each settles in: masters 0x01 (active)
/// and 0x02, the A members 0x10 and 0x11 active, the B members 0x50 and 0x51 standby, plain
/// slaves 0x05-0x07.
const STATION: [(u8, &str); 9] = [
    (0x01, "operational"),
    (0x02, "operational"),
    (0x05, "pre-operational"),
    (0x06, "pre-operational"),
    (0x07, "pre-operational"),
    (0x10, "operational"),
    (0x11, "operational"),
    (0x50, "pre-operational"),
    (0x51, "pre-operational"),
];
