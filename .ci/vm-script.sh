#!/bin/bash
# Runs one of tier 2's shell tests in the vcan VM (two emulated CPUs), with the interfaces and
# files it needs: the duocan tool (release build, built beforehand: `cargo build --release -p
# duocan-cli`) and, for the kit, its scenario files. Used by .ci/tier-vcan.sh and by
# .ci/flake-hunt (`script:kit@vm`, `script:lss@vm`), so both run the test the same way.
#   .ci/vm-script.sh kit    the failover kit on vcan (.ci/kit-vm.sh)
#   .ci/vm-script.sh lss    LSS fastscan on a dual vcan bus (.ci/lss-vm.sh)
#   .ci/vm-script.sh station  examples/station/vcan.toml run by the station, its boards as
#                             processes, a board failing (.ci/station-vm.sh)
# VCANVM_LOAD (busy loops per vCPU beside the test) passes through to the VM.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
TARGET=$(cargo metadata --format-version 1 --no-deps \
  | python3 -c 'import sys,json; print(json.load(sys.stdin)["target_directory"])')
TOOL="$TARGET/release/duocan"
[ -x "$TOOL" ] || { echo "vm-script: no $TOOL (cargo build --release -p duocan-cli)" >&2; exit 1; }
case ${1:-} in
  kit)
    EXTRA="$TOOL:/tests/duocan"
    for f in cli/scenarios/*.toml; do EXTRA="$EXTRA $ROOT/$f:/tests/scenarios/$(basename "$f")"; done
    VCANS=vm1a,vm1b,vs1a,vs1b,vm2a,vm2b,vs2a,vs2b,kb0,kb1,kb2
    SCRIPT=kit-vm.sh ;;
  lss)
    EXTRA="$TOOL:/tests/duocan"
    VCANS=lssa,lssb
    SCRIPT=lss-vm.sh ;;
  station)
    EXTRA="$TOOL:/tests/duocan $ROOT/examples/station/vcan.toml:/tests/vcan.toml"
    VCANS=vcan0,vcan1,vcan2,vcan3
    SCRIPT=station-vm.sh ;;
  *) echo "vm-script: which test? kit, lss or station" >&2; exit 2 ;;
esac
VCANVM_SMP=2 VCANVM_EXTRA="$EXTRA" VCANS=$VCANS exec "$ROOT/.ci/vcanvm/vm-run.sh" "$ROOT/.ci/$SCRIPT"
