#!/bin/bash
# Tier 3: python-can / python `canopen` as an independent peer over python-can's udp_multicast
# bus, inside a private network namespace (no packet can leave the machine), plus the runtime
# overhead measurement on the UDP bus (bare socket echo vs the tokio runtime), duocan and python
# `canopen` side by side on one UDP bus (tiers/tests/python_bench.rs), the dual-bus layer
# delivering exactly once under CPU load on two UDP buses (tiers/tests/udp_load.rs), the duocan tool
# against a duocan node on the UDP bus, the tool's CiA 309-3 gateway (over TCP) driving a
# python `canopen` node, and python `canopen` reading a duocan node by the names of the EDS
# duocan exported for it.
#   .ci/tier-python.sh            tests + benchmark
#   .ci/tier-python.sh --no-bench tests only
# Installs python3-venv if missing, pip-installs the peers into $TARGET/pyenv, builds first
# (the namespace has no route to the registries), then runs offline inside `unshare -n`.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
fail() { echo "tier-python: FAILED: $*" >&2; exit 1; }

command -v cargo >/dev/null || fail "cargo not found"
command -v unshare >/dev/null || fail "unshare (util-linux) not found"
command -v ip >/dev/null || fail "ip (iproute2) not found"
TARGET=$(cargo metadata --format-version 1 --no-deps | python3 -c 'import sys,json; print(json.load(sys.stdin)["target_directory"])') \
  || fail "cargo metadata"
VENV="$TARGET/pyenv"
if ! python3 -c 'import venv, ensurepip' 2>/dev/null; then
  [ "$(id -u)" = 0 ] || fail "python3-venv missing and not root to install it"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq && apt-get install -y -qq python3-venv >/dev/null || fail "apt-get install python3-venv"
fi
if ! "$VENV/bin/python" -c 'import can, canopen, msgpack' 2>/dev/null; then
  python3 -m venv "$VENV" || fail "cannot create venv $VENV"
  "$VENV/bin/pip" install -q python-can canopen msgpack || fail "pip install python-can canopen msgpack"
fi
"$VENV/bin/python" -c 'import can, canopen; print("python-can", can.__version__, "canopen", canopen.__version__)'

# The runtime, port and capture unit tests (features tokio, udp, socketcan) are the README's test
# command's (`cargo test --workspace` unifies those features: the tool asks for them): CI's tests
# step runs them; built here again with other features, they cost two minutes and ran the same
# 242 tests.

echo "== tier-python: build (outside the namespace)"
cargo test -p duocan-tiers --features python --test python_peer --test python_fd --test python_eds \
  --test python_starters --no-run || fail "build python_peer, python_fd, python_eds and python_starters tests"
# The duocan tool and its test (which runs the tool's binary against a duocan node).
cargo build -p duocan-cli || fail "build the duocan tool"
cargo test -p duocan-tiers --features python --test cli_udp --test cli_gateway --test kit_udp --test udp_reader \
  --test lss_udp --test station_udp --no-run \
  || fail "build the tool's tests"
# Release build: the receiver under load must keep up with 10,000 datagrams a second, niced.
cargo test --release -p duocan-tiers --features python --test udp_load --no-run \
  || fail "build the exactly-once-under-load test"
BENCH=1; [ "${1:-}" = "--no-bench" ] && BENCH=0
if [ $BENCH = 1 ]; then
  cargo build --release --features udp --example rt_overhead || fail "build rt_overhead"
  cargo test --release -p duocan-tiers --features python --test python_bench --no-run \
    || fail "build the side-by-side benchmark"
fi

echo "== tier-python: tests inside unshare -n"
export DUOCAN_PYTHON="$VENV/bin/python"
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test python_peer --test python_fd
' || fail "python peer tests (CAN FD and USDO with python-can as a raw peer among them)"
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test python_eds
' || fail "python canopen reading a duocan node by the names of its exported EDS"
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test cli_udp
' || fail "the duocan tool against a duocan node on the UDP bus"
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test lss_udp
' || fail "python canopen's LSS master and duocan lss configure a duocan LSS slave on the UDP bus"
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test udp_reader
' || fail "the UDP port read by a thread of its own"
# The failover kit for real: every shipped scenario through the fault bridge with the masters
# and boards as processes, each member interface a UDP bus; its verdicts and figures printed.
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test kit_udp -- --nocapture
' || fail "the failover kit on real processes gives the simulator's verdicts"
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test station_udp
' || fail "the shipped SocketCAN station file on the UDP bus: boards as processes, a killed board failed over"
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test cli_gateway
' || fail "a CiA 309-3 script over TCP to duocan gateway, a python canopen node on the UDP bus"
# One test at a time: each loads every CPU.
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --release --offline -p duocan-tiers --features python --test udp_load -- --nocapture \
    --test-threads 1
' || fail "exactly once under CPU load on two UDP buses (the receiver niced under a busy loop per CPU)"
unshare -n sh -ec '
  ip link set lo up
  ip route add 224.0.0.0/4 dev lo
  cargo test --offline -p duocan-tiers --features python --test python_starters
' || fail "the starter examples read_sdo and heartbeat_monitor against a python canopen node"

if [ $BENCH = 1 ]; then
  echo "== tier-python: runtime overhead on the UDP bus (inside unshare -n)"
  unshare -n sh -ec '
    ip link set lo up
    ip route add 224.0.0.0/4 dev lo
    "$0"/release/examples/rt_overhead udp 20000 5
  ' "$TARGET" || fail "rt_overhead udp"
  echo "== tier-python: duocan and python canopen side by side on the UDP bus (inside unshare -n)"
  unshare -n sh -ec '
    ip link set lo up
    ip route add 224.0.0.0/4 dev lo
    cargo test --release --offline -p duocan-tiers --features python --test python_bench -- --nocapture
  ' || fail "the side-by-side benchmark"
fi
echo "tier-python: OK"
