#!/bin/sh
# Inside the vcan VM (busybox sh): every failover scenario through the fault bridge on real
# vcan interfaces, the masters and boards as separate processes. Started by
# .ci/tier-vcan.sh with the tool at /tests/duocan and the scenarios in /tests/scenarios.
rc=0
for f in /tests/scenarios/*.toml; do
  echo "=== kit run $f (real vcan)"
  /tests/duocan kit run "$f" --out "/tmp/$(basename "$f" .toml)" || rc=1
  echo "=== kit sim $f (the simulator, for comparison)"
  /tests/duocan kit sim "$f" || rc=1
done
echo "=== kit bench: the bridge's own latency and throughput on vcan, against a bare path"
/tests/duocan kit bench --bare kb0 --a kb1 --b kb2 --frames 5000 || rc=1
exit $rc
