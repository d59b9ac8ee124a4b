#!/bin/bash
# Coverage-guided fuzzing (libFuzzer through cargo fuzz) of every decoder and protocol machine
# that takes bytes from a bus or a file: fuzz/fuzz_targets/*.rs. Each target runs for
# FUZZ_SECONDS (default 30) from its corpus: FUZZ_CORPUS/<target> (default fuzz/corpus/<target>,
# kept between runs: each run goes on from the inputs the runs before it found) plus
# fuzz/seeds/<target>/ where present; a crash fails the tier and names the input that caused it (fuzz/artifacts/<target>/), which
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
# The first directory given is where libFuzzer writes what it finds: the kept corpus.
CORPUS=${FUZZ_CORPUS:-$ROOT/fuzz/corpus}
cargo fuzz build --sanitizer none || fail "building the fuzz targets"
# The targets run JOBS at a time (one per core by default): each is single-threaded, so the
# seconds each target gets are the same as one after the other, in half the time on two cores.
JOBS=${FUZZ_JOBS:-$(nproc)}
LOGS=$(mktemp -d)
run_one() {
  local t=$1 corpus=("$CORPUS/$t")
  mkdir -p "$CORPUS/$t"
  # Hand-made seeds (fuzz/seeds/<target>/, committed) join the corpus: inputs that reach deep
  # states (a slave configured through its PDOs) the fuzzer would need minutes to find.
  if [ -d "seeds/$t" ]; then
    corpus+=("seeds/$t")
  fi
  cargo fuzz run --sanitizer none "$t" "${corpus[@]}" -- -max_total_time="$SECONDS_EACH" \
    -print_final_stats=0 >"$LOGS/$t.log" 2>&1
  echo $? >"$LOGS/$t.rc"
}
TARGETS=$(cargo fuzz list)
echo "== fuzz: $(echo "$TARGETS" | wc -w) targets, ${SECONDS_EACH} s each, $JOBS at a time, corpus in $CORPUS"
for t in $TARGETS; do
  while [ "$(jobs -rp | wc -l)" -ge "$JOBS" ]; do wait -n || true; done
  run_one "$t" &
done
wait
failed=()
for t in $TARGETS; do
  rc=$(cat "$LOGS/$t.rc" 2>/dev/null || echo "no exit status")
  echo "== fuzz: $t: $(grep -E "^(#[0-9]+ +DONE|Done )" "$LOGS/$t.log" | tail -1)"
  if [ "$rc" != 0 ]; then
    grep -E "panicked|SUMMARY|Test unit written|^Error" "$LOGS/$t.log" || tail -20 "$LOGS/$t.log"
    failed+=("$t (exit $rc)")
  fi
done
[ ${#failed[@]} = 0 ] || fail "${failed[*]} crashed: each input is in fuzz/artifacts/<target>/ (replay: cargo fuzz run <target> <file>)"
rm -rf "$LOGS"
echo "fuzz: OK"
