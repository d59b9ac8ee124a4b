#!/bin/bash
# Coverage-guided fuzzing (libFuzzer through cargo fuzz) of every decoder and protocol machine
# that takes bytes from a bus or a file: fuzz/fuzz_targets/*.rs. Each target runs for
# FUZZ_SECONDS (default 30) from an empty corpus (plus fuzz/seeds/<target>/ where present); a
# crash fails the tier and names the input that caused it (fuzz/artifacts/<target>/), which
# `cargo fuzz run <target> <file>` replays.
# cargo fuzz wants nightly compiler flags: RUSTC_BOOTSTRAP lets the stable toolchain take them.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
fail() { echo "fuzz: FAILED: $*" >&2; exit 1; }
command -v cargo >/dev/null || fail "cargo not found"
if ! cargo fuzz --version >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked || fail "cargo install cargo-fuzz (needs crates.io)"
fi
export RUSTC_BOOTSTRAP=1
SECONDS_EACH=${FUZZ_SECONDS:-30}
cd "$ROOT/fuzz"
cargo fuzz build --sanitizer none || fail "building the fuzz targets"
for t in $(cargo fuzz list); do
  echo "== fuzz: $t for ${SECONDS_EACH} s"
  log=$(mktemp)
  set +e
  # Hand-made seeds (fuzz/seeds/<target>/, committed) join the corpus: inputs that reach deep
  # states (a slave configured through its PDOs) the fuzzer would need minutes to find.
  corpus=()
  if [ -d "seeds/$t" ]; then
    mkdir -p "corpus/$t"
    corpus=("corpus/$t" "seeds/$t")
  fi
  cargo fuzz run --sanitizer none "$t" "${corpus[@]}" -- -max_total_time="$SECONDS_EACH" -print_final_stats=0 >"$log" 2>&1
  rc=$?
  set -e
  grep -E "^(#[0-9]+ +DONE|Done )" "$log" || true
  if [ $rc -ne 0 ]; then
    grep -E "panicked|SUMMARY|Test unit written|^Error" "$log" || tail -20 "$log"
    fail "$t crashed (exit $rc): the input is in fuzz/artifacts/$t/ (replay: cargo fuzz run $t <file>)"
  fi
done
echo "fuzz: OK"
