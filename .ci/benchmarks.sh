#!/usr/bin/env bash
# Runs every command whose figure BENCHMARKS.md gives, in turn, and prints what each reports,
# headed by the machine and the date. Long (tens of minutes on two cores) and loud; it changes
# nothing: the figures are copied into BENCHMARKS.md by hand, with the date and the machine.
# The real-peer figures (python `canopen` side by side, vcan in the VM) need their tiers:
# `.ci/tier-python.sh` and `.ci/tier-vcan.sh` print them (the latter also the fault bridge's
# `duocan kit bench`).
set -euo pipefail
cd "$(dirname "$0")/.."

run() { printf '\n=== %s\n' "$*"; "$@"; }

echo "date: $(date -u +%F)"
echo "machine: $(nproc) CPUs, $(lscpu | sed -n 's/^Model name: *//p' | head -1)"
echo "load: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "rustc: $(rustc -V)"

for b in od node sdo pdo sim eds; do run cargo bench --bench "$b"; done
run cargo bench -p duocan-redundancy --bench merge
run cargo bench -p duocan-redundancy --bench supervisor
run cargo bench -p safety-gateway --bench driver
run cargo bench -p master-board --bench driver
run cargo test --release --test master network_boot -- --nocapture
run cargo test --test alloc
run cargo test --test net concurrent_sdo -- --nocapture
run cargo test -p duocan-redundancy --test link merge_memory
run cargo build -p safety-gateway --target thumbv7em-none-eabihf
run cargo test -p master-board --test heap -- --nocapture
run bash .ci/firmware.sh
printf '\n=== the demo, three runs\n'
cargo build --release --example demo
for _ in 1 2 3; do cargo run -q --release --example demo -- --out target/demo | tail -1; done
printf '\n=== the runtime against a bare socket loop (UDP bus, in a private network namespace)\n'
cargo build --release --features udp --example rt_overhead
unshare -rn sh -c 'ip link set lo up; ip route add 224.0.0.0/4 dev lo;
  cargo run -q --release --features udp --example rt_overhead udp 40000 5'
