#!/bin/sh
# Inside the vcan VM (busybox sh): duocan's LSS master (CiA 305) configures duocan LSS slaves
# over real SocketCAN, as two processes of the tool on the dual bus lssa,lssb. One slave is on
# both buses, the other on lssb only, so its answers reach the master on one bus: they still
# count. Started by .ci/tier-vcan.sh with the tool at /tests/duocan. Only the requests are
# compared with the protocol's count: in the emulated VM the answers counted can exceed it (362
# against 356 in one run), since a slave busy between its two writes puts a second copy later
# than the merge window, a frame of its own. One that lands in a later, unanswered step misleads
# a bit; the master then starts over (at most 3 times) and reports the requests it gave up, so
# the requests less those still equal the protocol's count.
T=/tests/duocan
fail() { echo "lss-vm: FAILED: $*"; cat /tmp/slave7.out /tmp/slave8.out 2>/dev/null; exit 1; }

$T --bus lssa,lssb device lss-slave --serial 7 > /tmp/slave7.out 2>&1 &
S7=$!
$T --bus lssb device lss-slave --serial 8 > /tmp/slave8.out 2>&1 &
S8=$!
sleep 2

# The VM emulates its CPU: give each answer more time than a real bus needs.
echo "=== lss fastscan --assign 0x30 on lssa,lssb"
out=$($T --bus lssa,lssb --json lss --answer-ms 300 --settle-ms 30 fastscan --assign 0x30) \
  || fail "fastscan exited non-zero: $out"
echo "$out"
for want in '"serial":7,"node":4[89],"booted":true' '"serial":8,"node":4[89],"booted":true'; do
  echo "$out" | grep -q "$want" || fail "fastscan result lacks $want"
done
# Both boards found: exactly the requests the protocol's own count predicts, besides those of
# the attempts the master gave up.
req=$(echo "$out" | sed -n 's/.*"requests":\([0-9]*\),.*"protocol".*/\1/p')
gave=$(echo "$out" | sed -n 's/.*"abandoned":\([0-9]*\),.*/\1/p')
restarts=$(echo "$out" | sed -n 's/.*"restarts":\([0-9]*\),.*/\1/p')
want=$(echo "$out" | sed -n 's/.*"protocol":{[^}]*"requests":\([0-9]*\).*/\1/p')
[ -n "$req" ] && [ -n "$gave" ] && [ -n "$want" ] && [ $((req - gave)) = "$want" ] \
  || fail "requests $req less $gave given up, the protocol's count $want"
echo "requests $req = the protocol's count $want + $gave given up in $restarts restarts"

grep -q "boot node-id 0x3[01]" /tmp/slave7.out || fail "serial 7 did not boot"
grep -q "boot node-id 0x3[01]" /tmp/slave8.out || fail "serial 8 did not boot"

# The booted nodes answer SDO with their serial numbers: one node-ID each.
s30=$($T --bus lssa,lssb sdo read 0x30 0x1018 4 u32) || fail "sdo read 0x30"
s31=$($T --bus lssa,lssb sdo read 0x31 0x1018 4 u32) || fail "sdo read 0x31"
echo "0x30 serial $s30, 0x31 serial $s31"
[ "$s30$s31" = 78 ] || [ "$s30$s31" = 87 ] || fail "serials $s30 $s31"

# Nobody is left without a node-ID.
left=$($T --bus lssa,lssb --json lss --answer-ms 300 identify --non-configured) || fail "identify"
[ "$left" = '{"answered":false}' ] || fail "identify non-configured: $left"
kill $S7 $S8
echo "lss-vm: OK"
