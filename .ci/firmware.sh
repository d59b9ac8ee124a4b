#!/usr/bin/env bash
# The firmware images (firmware/: a workspace of their own, bare-metal only): lint, build both in
# release for the STM32F413, and print and check their figures against their budgets (flash,
# static RAM, the master's heap high-water mark measured on the host, the start-up stack).
#
# What it needs on a fresh Debian with rustup: the thumbv7em target, rustup's llvm-tools (for
# llvm-objdump, the stack figure) and python3. FIRMWARE_HEAP_FROM_TESTS=1 takes the master's
# heap figure from the workspace's test run that just happened (.ci/run does; the test writes
# tmp/master-heap-high-water in the target directory), otherwise the heap test runs here.
set -euo pipefail
cd "$(dirname "$0")/.."

# The budgets: each the measured figure (BENCHMARKS.md, "Firmware images") plus the stated margin,
# 4 KiB of flash, 2 KiB of RAM and 2 KiB of stack, rounded up to whole KiB, so that growth shows
# here before it reaches the part. The stack is the deepest chain from the reset handler, which
# includes what lives in the frame of `main` (the gateway, the master's station and
# dictionary); the RAM is statics (without the heap arena) + the heap's high-water mark + that
# stack, all the board must hold. Where the margin would take a budget beyond the one the
# images were given (gateway RAM 40 KiB, master RAM 96 KiB, gateway flash 64 KiB, master flash
# 192 KiB), the given one applies: the gateway's flash is 65,052 bytes against its 65,536, its
# RAM 39.7 KiB against its 40.
KIB=1024
GATEWAY_FLASH=$((64 * KIB))
GATEWAY_RAM=$((40 * KIB))
GATEWAY_STACK=$((38 * KIB))
MASTER_FLASH=$((182 * KIB))
MASTER_RAM=$((82 * KIB))
MASTER_STACK=$((46 * KIB))

rustup target add thumbv7em-none-eabihf >/dev/null
rustup component add llvm-tools >/dev/null \
  || { echo "cannot install rustup's llvm-tools (llvm-objdump: the stack figure)"; exit 1; }
objdump=$(ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-objdump 2>/dev/null | head -n1)
[ -x "$objdump" ] || { echo "llvm-objdump not found in the toolchain's llvm-tools"; exit 1; }

figure=${CARGO_TARGET_DIR:-target}/tmp/master-heap-high-water
if [ "${FIRMWARE_HEAP_FROM_TESTS:-}" != 1 ] || [ ! -f "$figure" ]; then
  cargo test -q -p master-board --test heap >/dev/null
fi
heap=$(cat "$figure")

# Each image on its own: built together, cargo would unify duocan's features and give the
# gateway, which has no allocator, the master's `alloc`.
(
  cd firmware
  cargo fmt --all --check
  cargo clippy -q --release -p duocan-board -p gateway-firmware -- -D warnings
  cargo clippy -q --release -p master-firmware -- -D warnings
  cargo build -q --release -p gateway-firmware
  cargo build -q --release -p master-firmware
)

elf=${CARGO_TARGET_DIR:-target}/thumbv7em-none-eabihf/release
status=0
python3 .ci/firmware-figures.py gateway "$elf/gateway-firmware" --objdump "$objdump" \
  --flash-budget "$GATEWAY_FLASH" --ram-budget "$GATEWAY_RAM" --stack-budget "$GATEWAY_STACK" \
  || status=1
python3 .ci/firmware-figures.py master "$elf/master-firmware" --objdump "$objdump" \
  --flash-budget "$MASTER_FLASH" --ram-budget "$MASTER_RAM" --stack-budget "$MASTER_STACK" \
  --heap-symbol HEAP_MEM --heap-high-water "$heap" || status=1
exit $status
