#!/bin/bash
# Tier 4: Wireshark's CANopen dissector decodes duocan's pcap captures (link type 227).
# Installs Debian's `tshark` non-interactively if missing, then runs tests/tshark.rs, which
# captures a simulated scenario and the demo's turnout rack (examples/demo) and asserts on
# tshark's CANopen fields.
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
cd "$ROOT"
fail() { echo "tier-tshark: FAILED: $*" >&2; exit 1; }

command -v cargo >/dev/null || fail "cargo not found"
if ! command -v tshark >/dev/null; then
  [ "$(id -u)" = 0 ] || fail "tshark missing and not root to apt-get install it"
  export DEBIAN_FRONTEND=noninteractive
  echo "wireshark-common wireshark-common/install-setuid boolean false" | debconf-set-selections \
    || fail "debconf preseed"
  apt-get update -qq && apt-get install -y -qq --no-install-recommends tshark >/dev/null \
    || fail "apt-get install tshark"
fi
tshark --version | head -1
echo "== tier-tshark: pcap captures decoded by tshark"
cargo test -p duocan-tiers --features tshark --test tshark || fail "tshark tests"
echo "tier-tshark: OK"
