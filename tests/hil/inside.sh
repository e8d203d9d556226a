#!/bin/bash
# Runs inside the HIL VM (tests/hil/can_hil_test.sh boots it): vcan interfaces, the
# reference saw controller, our sender with injected faults, cangw faults. Everything is
# printed to the console, which the host-side test parses. Usage: inside.sh VBUTCHER JOBS
set -u
vb=$1
# The host's root is shared read-only; /run is the VM's own tmpfs.
t=/run/vbhil
mkdir -p $t
export TMPDIR=$t
jobs=${2:-2000}
vbd_config=${3:-}   # a virtualbutcherd configuration on vcan0, for part D
frames_log=${4:-}   # the daemon's recorded frames (candump -L), for part E
ip link add dev vcan0 type vcan && ip link set up vcan0
ip link add dev vcan1 type vcan && ip link set up vcan1
echo "HIL: vcan up"
# wait_for <file> <text> <seconds>: a program started under emulation takes a while to load
# its libraries, so readiness is read from its log, not guessed with sleeps.
wait_for() {
  local i
  for ((i = 0; i < $3 * 10; i++)); do
    grep -q -- "$2" "$1" 2>/dev/null && return 0
    sleep 0.1
  done
  echo "HIL: timed out waiting for '$2' in $1"
  return 1
}

# A. E2E: jobs, every other one with faults, one saw; candump records the bus.
candump -L vcan0 >$t/candump.log &
dump=$!
"$vb" saw-sim --can vcan0 --quiet --ids-out $t/accepted.txt >$t/sawA.log &
saw=$!
wait_for $t/sawA.log listening 60
"$vb" saw-send --can vcan0 --jobs "$jobs" --fault mix --fault-rate 0.5 --seed 7 --job-gap-ms 1 \
  --ids-out $t/clean.txt | sed 's/^/HIL A /'
# The sender has stopped: its heartbeat too, so the saw must go to safe stop.
sleep 0.6
kill -TERM $saw; wait $saw
kill $dump 2>/dev/null; wait $dump 2>/dev/null
echo "HIL A candump frames $(wc -l <$t/candump.log)"
grep -E "SAFE STOP|summary|wake_late" $t/sawA.log | sed 's/^/HIL A /'
sort $t/accepted.txt >$t/accepted.sorted
sort $t/clean.txt >$t/clean.sorted
echo "HIL A faulted_jobs_accepted $(comm -23 $t/accepted.sorted $t/clean.sorted | wc -l)" \
  "clean_jobs_accepted $(comm -12 $t/accepted.sorted $t/clean.sorted | wc -l)" \
  "clean_jobs $(wc -l <$t/clean.sorted)"

# B. Safe stop when the sender dies in the middle of its work (kill -9).
"$vb" saw-sim --can vcan0 --quiet >$t/sawB.log &
saw=$!
wait_for $t/sawB.log listening 60
"$vb" saw-send --can vcan0 --jobs 1000000 --job-gap-ms 20 >/dev/null &
sender=$!
wait_for $t/sawB.log "ACCEPT job carcass 1010 " 60   # the sender is well under way
kill -KILL $sender
killed=$EPOCHREALTIME   # bash's clock, read without forking, right after the kill
echo "HIL B killed_at_epoch_ms $(( ${killed/./} / 1000 ))"
sleep 0.6
kill -TERM $saw; wait $saw
grep -E "SAFE STOP|summary|wake_late" $t/sawB.log | sed 's/^/HIL B /'

# C. Faults made by the kernel's CAN gateway between the sender (vcan0) and the saw (vcan1).
run_c() {  # run_c <label>: 20 jobs through whatever cangw rules are set
  "$vb" saw-sim --can vcan1 --quiet >$t/saw_$1.log &
  local s=$!
  wait_for $t/saw_$1.log listening 60
  "$vb" saw-send --can vcan0 --jobs 20 --job-gap-ms 5 >$t/send_$1.log
  sleep 0.2
  kill -TERM $s; wait $s
  grep summary $t/send_$1.log | sed "s/^/HIL C $1 /"
  grep summary $t/saw_$1.log | sed "s/^/HIL C $1 /"
}
cangw -A -s vcan0 -d vcan1 -e
run_c clean
cangw -A -s vcan0 -d vcan1 -e   # a second route: every frame arrives twice
run_c duplicate
cangw -F
cangw -A -s vcan0 -d vcan1 -e -m XOR:D:000.0.0000000000010000   # flips one data bit
run_c bitflip
cangw -F
# D. The daemon itself on vcan0: its heartbeat takes the saw out of safe stop, and kill -9 of
# the daemon puts the saw back into safe stop within 3 heartbeat periods.
if [ -n "$vbd_config" ]; then
  vbd=$(dirname "$(dirname "$vb")")/daemon/virtualbutcherd
  "$vb" saw-sim --can vcan0 --quiet >$t/sawD.log &
  saw=$!
  wait_for $t/sawD.log listening 60
  "$vbd" --config "$vbd_config" >$t/vbd.log 2>&1 &
  vbd_pid=$!
  if wait_for $t/sawD.log "safe stop left" 120; then
    sleep 1
    kill -KILL $vbd_pid
    killed=$EPOCHREALTIME
    echo "HIL D killed_at_epoch_ms $(( ${killed/./} / 1000 ))"
    sleep 0.6
  else
    sed 's/^/HIL D daemon: /' $t/vbd.log | head -20
    kill -KILL $vbd_pid 2>/dev/null
  fi
  kill -TERM $saw; wait $saw
  grep -E "SAFE STOP|safe stop left" $t/sawD.log | sed 's/^/HIL D /'
fi
# F. The shipped configuration (config/ of this checkout) on a machine that has can0; then the
# same with a virtual scene added, which must be refused (no `simulation: true`).
if [ -n "$vbd_config" ]; then
  ip link add dev can0 type vcan && ip link set up can0
  shipped=$(cd "$(dirname "$0")/../../config" && pwd)/virtualbutcherd.yaml
  "$vbd" --check-config --config "$shipped" >$t/checkF.log 2>&1
  echo "HIL F shipped config check rc $?"
  sed 's/^/HIL F /' $t/checkF.log
  mkdir -p $t/F
  cp "$(dirname "$shipped")/rig.yaml" $t/F/
  sed "s#^template: .*#template: $(dirname "$(dirname "$vbd")")/share/lamb.vbt#; s#^\# virtual_scene: .*#virtual_scene: $(dirname "$vbd_config")/rig/scene.yaml#" \
    "$shipped" >$t/F/vbd.yaml
  "$vbd" --check-config --config $t/F/vbd.yaml >$t/checkF2.log 2>&1
  echo "HIL F virtual scene on can0 rc $?"
  sed 's/^/HIL F /' $t/checkF2.log
fi
# E. The daemon's own frames, recorded on the host, replayed onto vcan0 at their pace.
if [ -n "$frames_log" ]; then
  "$vb" saw-sim --can vcan0 --quiet >$t/sawE.log &
  saw=$!
  wait_for $t/sawE.log listening 60
  canplayer -I "$frames_log" vcan0=can0
  sleep 0.5
  kill -TERM $saw; wait $saw
  grep -E "ACCEPT|reject job|summary" $t/sawE.log | sed 's/^/HIL E /'
fi
echo "HIL done"
