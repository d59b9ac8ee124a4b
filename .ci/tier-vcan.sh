#!/bin/bash
# Tier 2: real SocketCAN on vcan0/vcan1/vcan2, inside a qemu VM running Debian's stock kernel
# (the host kernel has no CAN). Installs what it needs (qemu, busybox, the kernel deb's CAN
# modules, can-utils), runs tiers/tests/vcan.rs, tiers/tests/vcan_fd.rs, tiers/tests/vcan_echo.rs, tiers/tests/vcan_failover.rs,
# tiers/tests/vcan_fd_failover.rs, tiers/tests/vcan_redundant.rs, tiers/tests/vcan_reopen.rs, tiers/tests/vcan_load.rs, the
# failover kit (.ci/kit-vm.sh), LSS (.ci/lss-vm.sh), the station file for SocketCAN
# (.ci/station-vm.sh), these three through .ci/vm-script.sh,
# tiers/tests/vcan_canopennode.rs (CANopenNode's canopend, built on the host from
# ../shared/peers/canopennode, as the device, and two of them as a redundant pair through the
# failover kit), and the dual_vcan_failover example's
# self-test in the VM (and checks on the host that the example
# refuses to run without its interfaces, saying how to create them), then the runtime-overhead
# measurement (bare socketcan echo loop vs the tokio runtime, same VM).
#   .ci/tier-vcan.sh            tests + benchmark
#   .ci/tier-vcan.sh --no-bench tests only
# Exits non-zero, saying why, when anything cannot run.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
VM="$ROOT/.ci/vcanvm"
cd "$ROOT"
fail() { echo "tier-vcan: FAILED: $*" >&2; exit 1; }
BENCH=1
for a in "$@"; do
  case $a in
    --no-bench) BENCH=0 ;;
    *) fail "unknown argument $a (--no-bench)" ;;
  esac
done

command -v cargo >/dev/null || fail "cargo not found"
[ "$(id -u)" = 0 ] || fail "needs root (apt-get install of qemu-system-x86, busybox-static, cpio)"
"$VM/setup.sh" || fail "vcanvm setup (apt-get / kernel download) failed"
if ! command -v canplayer >/dev/null; then   # can-utils go into the VM for the log tests
  export DEBIAN_FRONTEND=noninteractive
  apt-get install -y -qq --no-install-recommends can-utils >/dev/null \
    || { apt-get update -qq && apt-get install -y -qq --no-install-recommends can-utils >/dev/null; } \
    || fail "apt-get install can-utils"
fi
export WITH_CANUTILS=1

export VCANS=vcan0,vcan1,vcan2
export RUST_TEST_THREADS=1            # tests switch interfaces down and up
export VCANVM_TIMEOUT=${VCANVM_TIMEOUT:-600}
export CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_RUNNER="$VM/vm-run.sh"

echo "== tier-vcan: SocketCAN integration tests in the VM"
cargo test -p duocan-tiers --features vcan --test vcan || fail "vcan tests"
echo "== tier-vcan: CAN FD on vcan: FD frames (BRS, ESI, up to 64 bytes) between ports opened for"
echo "   CAN FD on vcan0 (MTU 72); vcan2 at MTU 16 refused for CAN FD, naming it"
cargo test -p duocan-tiers --features vcan --test vcan_fd || fail "CAN FD on vcan"
echo "== tier-vcan: confirmed transmissions: vcan loaded with echo=1 (its driver echoes, as a CAN"
echo "   controller's does once a frame was on the bus): a port's own frames come back as TxOk"
VCANVM_ECHO=1 cargo test -p duocan-tiers --features vcan --test vcan_echo || fail "confirmed transmissions on vcan"
echo "== tier-vcan: the dual-bus layer (duocan-redundancy) failing over between vcan0 and vcan1"
cargo test -p duocan-tiers --features vcan --test vcan_failover || fail "dual-bus failover on vcan"
echo "== tier-vcan: the dual-bus layer carrying 64-byte CAN FD frames on vcan0 and vcan1 opened for"
echo "   CAN FD: vcan0 down and up mid-run, every frame delivered once, the port failed and back"
cargo test -p duocan-tiers --features vcan --test vcan_fd_failover || fail "dual-bus FD failover on vcan"
echo "== tier-vcan: the redundant network's front door on vcan0,vcan1 (open_named, SDO, a bus failover)"
cargo test -p duocan-tiers --features vcan --test vcan_redundant || fail "redundant front door on vcan"
echo "== tier-vcan: a port that disappears comes back: vcan1 deleted and created again, bus-off"
echo "   with and without the driver's restart report"
cargo test -p duocan-tiers --features vcan --test vcan_reopen -- --nocapture \
  || fail "ports re-opened and used again on vcan"
echo "== tier-vcan: the failover kit on vcan: every scenario through the fault bridge (masters and"
echo "   boards as processes), the simulator's verdicts beside it, and the bridge's own overhead"
# Release build: the VM emulates its CPU, and five processes share it.
cargo build --release -p duocan-cli || fail "build the duocan tool"
.ci/vm-script.sh kit || fail "the failover kit on vcan"

echo "== tier-vcan: LSS on vcan: the tool's LSS master configures two duocan LSS slaves (processes)"
echo "   by fastscan on lssa,lssb, one of them on lssb only"
.ci/vm-script.sh lss || fail "LSS on vcan"

echo "== tier-vcan: the station on vcan: examples/station/vcan.toml (two racks, each on two vcan"
echo "   interfaces) checked and run, its four boards as processes; every pair running A, an SDO"
echo "   read through REST, board A of one pair killed and B running (status and event stream), a"
echo "   bus taken down and shown failed, SIGTERM and a clean exit with the audit trail closed;"
echo "   vcan with echo=1, as CAN controllers echo (once on the bus): the station's ports confirm"
echo "   their transmissions, so the dual-bus layer's transmit-stall rule is armed all along"
VCANVM_ECHO=1 .ci/vm-script.sh station || fail "the station on vcan"

echo "== tier-vcan: CANopenNode's canopend as the device (node 4 on vcan0), duocan as the master:"
echo "   the tool's scan, SDO in every mode both ways, NMT in the heartbeat, its loss, a TPDO, an EMCY;"
echo "   LSS both ways: duocan's master configures canopend, canopend's gateway (through cocomm) a"
echo "   duocan LSS slave; the tool's eds export of canopend against the EDS it ships; the tool's"
echo "   dump and monitor decoding its traffic; one cocomm script to canopend's gateway and duocan's;"
echo "   two canopend as the A/B pair of two duocan redundant masters through the failover kit"
echo "   (board A loses power: B started within the pair's bound, once)"
# canopend is built on the host (static, a few seconds) from the sources kept beside the
# repository, and goes into the VM with its EDS, cocomm (its gateway's client) and the tool
# (release, built for the kit).
PEERS=${DUOCAN_PEERS:-$ROOT/../shared/peers}
CONODE=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import sys,json; print(json.load(sys.stdin)["target_directory"])')/canopennode
out=$(bash "$PEERS/canopennode/build.sh" "$CONODE" 2>&1) \
  || fail "build CANopenNode's canopend with $PEERS/canopennode/build.sh (needs make and a static libc): $out"
[ -x "$CONODE/canopend" ] && [ -x "$CONODE/cocomm" ] && [ -f "$CONODE/canopend.eds" ] \
  || fail "no canopend, cocomm or canopend.eds in $CONODE"
TOOL="$(dirname "$CONODE")/release/duocan"
[ -x "$TOOL" ] || fail "no $TOOL (built above for the kit)"
# The kit's interfaces beside vcan0 for the pair through the failover kit. One emulated CPU is
# enough for its five processes (the release tool, canopend); a second made the whole run take
# 64 s instead of 24 on a loaded host.
VCANS=vcan0,vcan1,vcan2,vm1a,vm1b,vs1a,vm2a,vm2b,vs2b \
VCANVM_EXTRA="$CONODE/canopend:/tests/canopend $CONODE/canopend.eds:/tests/canopend.eds $CONODE/cocomm:/tests/cocomm $TOOL:/tests/duocan" \
DUOCAN_CANOPEND=/tests/canopend DUOCAN_CANOPEND_EDS=/tests/canopend.eds DUOCAN_COCOMM=/tests/cocomm DUOCAN_TOOL=/tests/duocan \
  cargo test -p duocan-tiers --features vcan --test vcan_canopennode \
  || fail "CANopenNode's canopend on vcan"

echo "== tier-vcan: exactly once under CPU load: a busy loop per vCPU, the receiver (DualBus under"
echo "   the runtime) at nice 5, 20,000 frames at 1,000/s and at 5,000/s, and with vcan0 flapping"
# Release build (after the tool's, whose dependencies it shares): the VM emulates its CPU, and
# a debug receiver, niced, cannot keep up with 10,000 frames a second there.
cargo test --release -p duocan-tiers --features vcan --test vcan_load -- --nocapture \
  || fail "exactly once under load on vcan"

echo "== tier-vcan: the dual_vcan_failover example"
# Release build: the VM emulates its CPU (TCG, one core), and a debug build's scheduling delays
# between the two port tasks (a frame's two copies sent that far apart) exceed the merger's
# default 5 ms skew window; the self-test runs with a 25 ms window for the same reason (a real
# machine needs neither).
cargo build --release --features socketcan --example dual_vcan_failover || fail "build dual_vcan_failover"
TARGET=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import sys,json; print(json.load(sys.stdin)["target_directory"])')
EX="$TARGET/release/examples/dual_vcan_failover"
# Without the interfaces (the host has no CAN) it must exit non-zero saying how to create them.
missing_check() {  # $@: arguments; the interfaces they name do not exist
  set +e; out=$("$EX" "$@" 2>&1); rc=$?; set -e
  [ $rc -ne 0 ] || fail "dual_vcan_failover $* exited 0 without its interfaces"
  for want in "sudo modprobe vcan" "ip link add dev" "type vcan"; do
    case $out in *"$want"*) ;; *) fail "dual_vcan_failover $*: message lacks '$want': $out" ;; esac
  done
  echo "missing interfaces refused (exit $rc), with instructions"
}
missing_check --buses nocan8,nocan9 --self-test
if [ ! -e /sys/class/net/vcan0 ] && [ ! -e /sys/class/net/vcan1 ]; then missing_check --self-test; fi
"$VM/vm-run.sh" "$EX" --self-test --skew-ms 25 || fail "dual_vcan_failover --self-test in the VM"

if [ "$BENCH" = 1 ]; then
  echo "== tier-vcan: runtime overhead on vcan (in the VM)"
  cargo build --release --features socketcan --example rt_overhead || fail "build rt_overhead"
  BIN=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import sys,json; print(json.load(sys.stdin)["target_directory"])')/release/examples/rt_overhead
  "$VM/vm-run.sh" "$BIN" vcan 20000 || fail "rt_overhead in the VM"
fi
echo "tier-vcan: OK"
