#!/bin/sh
# Inside the vcan VM (busybox sh): the station file for SocketCAN (examples/station/vcan.toml,
# at /tests/vcan.toml) run by `duocan station run` over real vcan interfaces, its boards duocan
# processes on the same interfaces (`duocan device board`), watched through the station's REST
# API on loopback. Started by .ci/vm-script.sh station with the tool at /tests/duocan.
#   1. `station check` passes on the file as shipped.
#   2. The station runs it (with an audit trail added): the pair of each rack has its A board
#      running and the master is the active one; then the B boards join as standby.
#   3. An SDO read through REST reaches a board (its product code is its node-ID).
#   4. Board A of the turnout rack's pair is killed: that pair runs B (in the status and in the
#      event stream), counted as a failover; the signal rack's pair (its own buses) keeps A.
#   5. The signal rack's second bus goes down (ip link): shown failed, its pair still on A.
#   6. SIGTERM: the station exits 0, having closed its audit trail, which holds the switch-over.
# Every wait has a deadline; a failure names what was missing and shows the station's log.
T=/tests/duocan
URL=http://127.0.0.1:8080/api
PIDS=""
fail() {
  echo "station-vm: FAILED: $*"
  # Without the churn of buses briefly silent (the emulated CPU's pauses), which would fill it.
  echo "--- station log (tail, without 'suspect'/'ok again'/'lags'/'heard on' lines)"
  grep -v 'suspect (nothing received\|ok (frames received again\|lags\|heard on' /tmp/station.log 2>/dev/null \
    | tail -n 40
  echo "--- networks: $(wget -q -O - "$URL/networks" 2>/dev/null | cut -c1-1500)"
  for p in $PIDS; do kill "$p" 2>/dev/null; done
  exit 1
}

# The boards: each member of each pair a process, as a board is a device of its own. The A
# boards first, the B boards once A runs: a pair's first member to finish its configuration
# runs, and boards found together are configured in the order their SDO answers come, which on
# a stalling emulated CPU was B's now and then.
board() {  # $1 buses, $2 node-ID; sets B to its pid
  $T --bus "$1" device board --node "$2" --heartbeat-ms 200 > "/tmp/board-$1-$2.out" 2>&1 &
  B=$!; PIDS="$PIDS $B"
}
board vcan0,vcan1 0x11; KILLED=$B
board vcan2,vcan3 0x11

echo "=== station check /tests/vcan.toml"
out=$($T station check /tests/vcan.toml 2>&1) || fail "station check: $out"
echo "$out"
for want in "turnout rack on vcan0,vcan1" "signal rack on vcan2,vcan3"; do
  echo "$out" | grep -q "$want" || fail "station check does not show '$want'"
done

# The shipped file with an audit trail, so that the stop shows it closed and the switch-over
# is in it.
sed '/^\[station\]/a audit_dir = "/tmp/audit"' /tests/vcan.toml > /tmp/station.toml
echo "=== station run (with audit_dir = /tmp/audit)"
$T station run /tmp/station.toml > /tmp/station.log 2>&1 &
ST=$!; PIDS="$PIDS $ST"

# The network NAME's part of the status (from its "name" to the next network's; a port has a
# "name" too, but no "buses" after it).
net() { echo "$NETS" | sed 's/{"name":"\([^"]*\)","buses":/\n\1","buses":/g' | grep "^$1\""; }
# Waits up to $1 s until `$2` (a shell condition over $NETS) holds; says what it waits for ($3).
until_nets() {
  # By the clock, not by counting polls: a poll itself takes a while on the emulated CPU.
  t0=$(date +%s)
  while [ $(($(date +%s) - t0)) -lt "$1" ]; do
    kill -0 $ST 2>/dev/null || fail "the station exited while waiting until $3"
    NETS=$(wget -q -O - "$URL/networks" 2>/dev/null)
    if eval "$2"; then echo "within $(($(date +%s) - t0 + 1)) s: $3"; return 0; fi
    sleep 0.25
  done
  fail "not within $1 s: $3"
}
has() { net "$1" | grep -q "$2"; }

# Started: the master took each network (its peer, node 2, is not there) and started every A.
# The emulated CPU is slow to start the processes: a generous deadline.
until_nets 30 'has "turnout rack" "\"role\":\"active\"" && has "signal rack" "\"role\":\"active\"" &&
  has "turnout rack" "\"pair\":\"0x11/0x21\",\"active\":\"A\"" &&
  has "signal rack" "\"pair\":\"0x11/0x21\",\"active\":\"A\""' \
  "both racks' master active, every pair running A"
board vcan0,vcan1 0x21
board vcan2,vcan3 0x21
# B joins as the standby: configured, left pre-operational.
b_standby='"node":"0x21","state":"pre-operational","missing":false'
until_nets 30 'has "turnout rack" "$b_standby" && has "signal rack" "$b_standby" &&
  has "turnout rack" "\"pair\":\"0x11/0x21\",\"active\":\"A\"" &&
  has "signal rack" "\"pair\":\"0x11/0x21\",\"active\":\"A\""' \
  "both B boards standing by (pre-operational), every pair still running A"

net "signal rack" | cut -c1-400
echo "=== SDO read through REST: signal rack, board 0x21 (B, not running), 0x1018 sub 2 (product code)"
sdo=$(wget -q -O - "$URL/networks/signal%20rack/nodes/0x21/sdo/0x1018/2?type=u32" 2>&1) \
  || fail "the REST SDO read failed: $sdo"
echo "$sdo"
echo "$sdo" | grep -q '"value":33' || fail "the REST SDO read did not give board 0x21's product code 33"

# The rack's failovers so far (the emulated CPU's hiccups may have counted some already).
failovers() { net "$1" | sed 's/.*"failovers":\([0-9]*\),.*/\1/'; }
before=$(failovers "turnout rack")
# The event stream (SSE) a dashboard reads, listened to from before the kill.
wget -q -O /tmp/events.txt "$URL/events" 2>/dev/null &
SSE=$!; PIDS="$PIDS $SSE"
sleep 1
echo "=== board 0x11 of the turnout rack (A of pair 0x11/0x21) killed ($before failovers so far)"
kill -9 $KILLED
until_nets 15 'has "turnout rack" "\"pair\":\"0x11/0x21\",\"active\":\"B\""' \
  "the turnout rack's pair 0x11/0x21 running B"
# In the stream: the event named after the network, its data the switch-over.
t0=$(date +%s)
until grep -A1 '^event: *turnout rack' /tmp/events.txt 2>/dev/null | grep -q 'data: *pair 0x11/0x21: B active'; do
  [ $(($(date +%s) - t0)) -lt 5 ] \
    || fail "no 'pair 0x11/0x21: B active' for the turnout rack in /api/events: $(tail -c 600 /tmp/events.txt)"
  sleep 0.25
done
echo "in /api/events: $(grep -A1 '^event: *turnout rack' /tmp/events.txt | grep 'B active')"
kill $SSE
after=$(failovers "turnout rack")
[ "$after" -gt "$before" ] || fail "the switch-over is not counted as a failover ($before, then $after)"
has "signal rack" '"pair":"0x11/0x21","active":"A"' \
  || fail "the signal rack's pair 0x11/0x21 (its own buses) left A"

echo "=== the signal rack's bus 2 down (ip link set vcan3 down)"
ip link set vcan3 down || fail "ip link set vcan3 down"
until_nets 15 'has "signal rack" "\"name\":\"vcan3\",\"state\":\"failed\""' \
  "the signal rack's vcan3 shown failed"
has "signal rack" '"name":"vcan2","state":"ok"' || fail "the signal rack's vcan2 not ok"
has "signal rack" '"pair":"0x11/0x21","active":"A"' \
  || fail "the signal rack's pair left A when one bus failed"

echo "=== SIGTERM"
kill -TERM $ST
i=0
while kill -0 $ST 2>/dev/null; do
  [ $i -lt 40 ] || fail "the station still runs 10 s after SIGTERM"
  sleep 0.25; i=$((i + 1))
done
wait $ST; rc=$?
[ $rc = 0 ] || fail "the station exited $rc after SIGTERM"
grep -q "stopped" /tmp/station.log || fail "the log does not say the station stopped"
for n in "turnout rack" "signal rack"; do
  grep "audit closed" /tmp/station.log | grep -q "$n" || fail "the audit trail of $n not closed"
done
ls /tmp/audit
grep -q "active A -> B" /tmp/audit/turnout*.audit || fail "the audit trail lacks the switch-over"
grep "active A -> B" /tmp/audit/turnout*.audit
for p in $PIDS; do kill "$p" 2>/dev/null; done
echo "station-vm: OK"
