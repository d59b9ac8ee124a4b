//! The door's speed benchmark (no assertion: it reports): one-at-a-time SDO reads through
//! `duocan::net::Network` on one python-can UDP bus, and through the redundant door on two,
//! against the bare socket ping-pong on the same bus, side by side in one run, as ratios.
//!
//! Inside `unshare -n` (loopback multicast), as `.ci/tier-python.sh` runs the UDP tests:
//! `cargo test --release -p duocan-tiers --features python --test door_speed -- --nocapture`.
//! `DUOCAN_BENCH_ROUNDS` sets the rounds (default 5), `DUOCAN_BENCH_READS` the reads a round
//! (default 5,000).

#[path = "common/door_speed.rs"]
mod door_speed;
#[path = "../../tests/common/runtime.rs"]
mod rt;
#[path = "common/wire.rs"]
mod wire;

use duocan::port::udp::UdpBusConfig;

fn env(name: &str, default: usize) -> usize {
    std::env::var(name)
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
        .max(1)
}

#[test]
fn door_reads_against_the_bare_ping_pong() {
    let m = door_speed::measure(
        &[50, 51, 52, 53, 54].map(UdpBusConfig::numbered),
        env("DUOCAN_BENCH_READS", 5_000),
        env("DUOCAN_BENCH_ROUNDS", 5),
    );
    println!("\n{}", m.report());
}
