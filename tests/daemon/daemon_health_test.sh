#!/usr/bin/env bash
# What operators see, read where they read it: sd_notify (our own NOTIFY_SOCKET), the log
# and VB_STATUS / VB_DIAGNOSTICS over udpm in a private network namespace (vbutcher
# lcm-listen decodes them as lcm-spy would).
#  1. A camera missing at start: READY=1 comes once the cameras have settled, and STATUS, a
#     warning in the log, VB_STATUS (DEGRADED, the camera MISSING) and VB_DIAGNOSTICS all
#     name it; the camera that works reports its measured frame rate and last frame time.
#  2. All cameras present, one starting 1.5 s after the other: VB_STATUS says STARTING until
#     both have a frame, then STATUS and VB_STATUS say ready; the version in VB_STATUS is the
#     one --version prints.
#  3. simulation: true: every log line and the status say SIMULATION.
#  4. The rig check: at start on an empty hook it says the target is not there; on SIGUSR1
#     with the target hung it finds the rig ok (VB_STATUS per camera); a rig whose cam1 is
#     said to stand 10 mm off is found MOVED at start: DEGRADED, a warning, jobs refused; a
#     check asked for while the one at start runs follows it.
# Usage: daemon_health_test.sh <vbutcher> <virtualbutcherd>
set -euo pipefail
vbutcher=$(realpath "$1")
daemon=$(realpath "$2")
if [ "${VB_IN_NETNS:-}" != 1 ]; then
  exec unshare -n env VB_IN_NETNS=1 bash "$0" "$@"
fi
ip link set lo up multicast on
ip route add 224.0.0.0/4 dev lo
url="udpm://239.255.76.67:7667?ttl=0"
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; for f in "$work"/*.log "$work"/*.txt; do echo "--- $f"; cat "$f"; done; exit 1; }

"$vbutcher" synth --out "$work/set" --count 1 >/dev/null
"$vbutcher" template compile --template "$work/set/template.ply" \
  --annotations "$work/set/template_annotations.yaml" -o "$work/lamb.vbt" >/dev/null
"$vbutcher" virtual-rig --out "$work/rig" --cameras 2 >/dev/null
sed -i '/^carcass:/d' "$work/rig/scene.yaml"  # an empty hook
sed 's#uri: vbrig://VB0002#uri: vbrig://ABSENT#' "$work/rig/rig.yaml" >"$work/rig/rig_missing.yaml"
config() {  # config <file> <rig> [extra line]
  printf '%s\n' "format: virtualbutcherd-config" "version: 1" "template: lamb.vbt" "rig: $2" \
    "virtual_scene: rig/scene.yaml" "lcm: {url: \"$url\", status_period_ms: 250}" \
    "can: {interface: loopback}" "job: {state_file: job-state}" ${3:+"$3"} >"$work/$1"
}
printf 'vbutcher-job-state 1\ncarcass 0\nsequence 0\n' >"$work/job-state"
config missing.yaml rig/rig_missing.yaml
config good.yaml rig/rig.yaml
# late.yaml: cam1 (VB0002) starts 1.5 s after cam0, well within the 5 s it is given for a
# first frame there (a loaded sanitizer build renders the first image slowly).
cp "$work/rig/scene.yaml" "$work/rig/scene_late.yaml"
echo "start_delays_ms: {VB0002: 1500}" >>"$work/rig/scene_late.yaml"
sed 's#rig/scene.yaml#rig/scene_late.yaml#' "$work/good.yaml" >"$work/late.yaml"
echo "capture: {first_frame_timeout_ms: 5000}" >>"$work/late.yaml"
config sim.yaml rig/rig.yaml "simulation: true"

notify_listener() {  # notify_listener <socket> <log>
  /usr/bin/python3 - "$1" "$2" <<'PY' &
import socket, sys, time
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
s.bind(sys.argv[1])
s.settimeout(0.5)
end = time.time() + 30
with open(sys.argv[2], "w") as log:
    while time.time() < end:
        try:
            log.write(s.recv(4096).decode() + "\n---\n")
            log.flush()
        except socket.timeout:
            pass
PY
  for _ in $(seq 50); do [ -S "$1" ] && break; sleep 0.1; done
}
start() {  # start <name> <config> <seconds> <statuses> <timeout>: notify socket, listener, daemon
  notify_listener "$work/$1.sock" "$work/$1.notify.log"
  "$vbutcher" lcm-listen --url "$url" --count 0 --status-count "$4" --diagnostic-count 1 \
    --status --diagnostics --timeout "$5" >"$work/$1.listen.txt" &
  listener=$!
  for _ in $(seq 300); do grep -qs "^lcm-listen: listening on" "$work/$1.listen.txt" && break; sleep 0.1; done
  grep -qs "^lcm-listen: listening on" "$work/$1.listen.txt" || fail "$1: lcm-listen did not subscribe in 30 s"
  NOTIFY_SOCKET="$work/$1.sock" "$daemon" --config "$work/$2" --run-seconds "$3" \
    2>"$work/$1.daemon.log" &
  daemon_pid=$!
  [ -z "${during:-}" ] || (eval "$during")
}
run() {  # run <name> <config>: the daemon for 5 s, and 12 statuses heard
  start "$1" "$2" 5 12 20
  wait $daemon_pid || fail "$1: the daemon exited with $?"
  wait $listener || true
}
# run_until <name> <config> <checks>: as run, but the daemon serves until its log has given
# the outcome of that many rig checks (at most 60 s: a sanitizer build on a loaded machine
# checks the rig slowly) and 2 s more, so that VB_STATUS carries the last outcome; the
# listener hears every status until then.
run_until() {
  start "$1" "$2" 80 100000 90
  local end=$((SECONDS + 60)) seen=0
  while [ $SECONDS -lt $end ] && kill -0 $daemon_pid 2>/dev/null; do
    seen=$(grep -c "^<[0-7]>virtualbutcherd: rig check\(:\| failed:\) " "$work/$1.daemon.log" \
      2>/dev/null || true)
    [ "${seen:-0}" -ge "$3" ] && break
    sleep 0.1
  done
  [ "${seen:-0}" -ge "$3" ] || fail "$1: ${seen:-0} of $3 rig-check outcomes logged"
  sleep 2
  kill -TERM $daemon_pid 2>/dev/null || true
  wait $daemon_pid || fail "$1: the daemon exited with $?"
  sleep 0.5  # the listener prints (and flushes) each message as it comes
  kill -TERM $listener 2>/dev/null || true
  wait $listener || true
}
# wait_for_log <name> <pattern>: until the daemon's log holds the pattern (at most 60 s).
wait_for_log() {
  local end=$((SECONDS + 60))
  until grep -q "$2" "$work/$1.daemon.log" 2>/dev/null; do
    [ $SECONDS -lt $end ] || fail "$1: no '$2' in the log in 60 s"
    sleep 0.05
  done
}

version=$("$daemon" --version)
[[ "$version" =~ ^virtualbutcherd\ [0-9]+\.[0-9]+\.[0-9]+\ \((.+)\)$ ]] ||
  fail "--version printed '$version'"
revision=${BASH_REMATCH[1]}
[ "$("$vbutcher" --version)" = "vbutcher ${version#virtualbutcherd }" ] || fail "vbutcher --version differs"

# 1. A camera missing at start.
run missing missing.yaml
grep -q "READY=1" "$work/missing.notify.log" || fail "no READY=1 with a camera missing"
grep -A1 "READY=1" "$work/missing.notify.log" | grep -q "STATUS=DEGRADED.*cameras 1 of 2 ok (cam1 missing: cannot open the device)" ||
  grep -q "READY=1.*STATUS=DEGRADED.*cam1 missing" "$work/missing.notify.log" ||
  fail "READY=1 came without STATUS naming the missing camera"
grep -q "^<4>virtualbutcherd: camera cam1 (serial VB0002) is missing: cannot open the device" "$work/missing.daemon.log" ||
  fail "the missing camera was not logged at warning"
grep -q "^<4>virtualbutcherd: serving DEGRADED: cameras 1 of 2 ok (cam1 missing" "$work/missing.daemon.log" ||
  fail "no warning that the daemon serves degraded"
grep -q "VB_STATUS seq .* state DEGRADED version ${version#virtualbutcherd }: DEGRADED" "$work/missing.listen.txt" ||
  fail "VB_STATUS did not say DEGRADED with the version"
grep -q "camera cam1 serial VB0002 state MISSING fps 0.0 valid 0.00 last frame never" "$work/missing.listen.txt" ||
  fail "VB_STATUS did not show cam1 MISSING"
grep -q "VB_DIAGNOSTICS seq .* WARNING camera:cam1: camera cam1 (serial VB0002) is missing" "$work/missing.listen.txt" ||
  fail "VB_DIAGNOSTICS did not carry the camera's loss"
# The working camera: its measured rate (the virtual rig runs at 30 fps; allow a loaded
# machine's 20) and a recent last frame, in the last status received.
last=$(grep "camera cam0 serial VB0001" "$work/missing.listen.txt" | tail -1)
fps=$(sed -n 's/.* fps \([0-9.]*\) .*/\1/p' <<<"$last")
ago=$(sed -n 's/.* last frame \([0-9]*\) ms ago.*/\1/p' <<<"$last")
# A sanitizer build (no memory budget) polls slower on a loaded machine: its floor is lower.
floor=20
grep -q "no memory budget in this build" "$work/missing.daemon.log" && floor=10
awk -v f="${fps:-0}" -v lo=$floor 'BEGIN { exit !(f >= lo && f <= 33) }' ||
  fail "cam0 fps '$fps' is not the measured ~30 (at least $floor): $last"
[ -n "$ago" ] && [ "$ago" -lt 1000 ] || fail "cam0's last frame is not recent: $last"

# 2. All cameras present (and the rig check at start, on an empty hook, has finished).
run_until good late.yaml 1
grep -q "READY=1" "$work/good.notify.log" || fail "no READY=1"
grep -q "STATUS=ready, waiting for a carcass; cameras 2 of 2 ok;" "$work/good.notify.log" ||
  fail "STATUS does not say ready with both cameras"
grep -q "VB_STATUS seq .* state READY version .*($revision): ready" "$work/good.listen.txt" ||
  fail "VB_STATUS did not say READY with the revision"
# While cam1 starts: STARTING, never READY before it.
grep -q "VB_STATUS seq .* state STARTING .*: starting, waiting for the cameras; cameras 1 of 2 ok (cam1 starting)" \
  "$work/good.listen.txt" || fail "VB_STATUS did not say STARTING while cam1 started"
first_ready=$(grep -n -m1 "VB_STATUS seq .* state READY " "$work/good.listen.txt" | cut -d: -f1)
last_starting=$(grep -n "VB_STATUS seq .* state STARTING " "$work/good.listen.txt" | tail -1 | cut -d: -f1)
[ -n "$last_starting" ] && [ -n "$first_ready" ] && [ "$last_starting" -lt "$first_ready" ] ||
  fail "VB_STATUS said STARTING after READY (lines $last_starting and $first_ready)"
! grep -v "no memory budget in this build" "$work/good.daemon.log" | grep -q "^<[0-4]>" ||
  fail "warnings with every camera present"
grep -q "^<6>virtualbutcherd: virtualbutcherd .*($revision)" "$work/good.daemon.log" ||
  fail "the start-up log does not give the version"

# 3. simulation: true.
run sim sim.yaml
# The daemon's lines (a sanitizer build's leak-check summary at exit is not one of them).
bad=$(grep -E "^<[0-7]>|virtualbutcherd:" "$work/sim.daemon.log" |
  grep -v "^<[0-7]>virtualbutcherd: SIMULATION: " || true)
[ -z "$bad" ] || fail "log lines without SIMULATION: $bad"
grep -q "STATUS=SIMULATION; ready" "$work/sim.notify.log" || fail "STATUS does not say SIMULATION"
grep -q "VB_STATUS seq .* state READY .*: SIMULATION; ready" "$work/sim.listen.txt" ||
  fail "VB_STATUS does not say SIMULATION"
# 4. The rig check. An empty hook at start, then the target hung and SIGUSR1.
grep -q "^<6>virtualbutcherd: rig check: not checked at .*: the calibration target is not on the hook (0 of 2 cameras" \
  "$work/good.daemon.log" || fail "the check at start did not say the target is not on the hook"
"$vbutcher" calibrate target --mesh "$work/target.ply" >/dev/null
# The target is hung once the check at start has found the hook empty.
during='wait_for_log request "rig check: not checked"
  printf "carcass: %s\n" "$work/target.ply" >>"$work/rig/scene.yaml"; sleep 1; kill -USR1 $daemon_pid'
run_until request good.yaml 2  # the empty hook at start, then the one asked for
during=
grep -q "^<5>virtualbutcherd: SIGUSR1: a rig check on the next frames" "$work/request.daemon.log" ||
  fail "SIGUSR1 was not acknowledged"
grep -q "^<6>virtualbutcherd: rig check: ok at .*: 2 cameras agree within" "$work/request.daemon.log" ||
  fail "the requested check did not find the rig ok"
grep -q "lcm-listen:   rig check: ok at" "$work/request.listen.txt" || fail "VB_STATUS did not carry the check"
grep -q "camera cam1 serial VB0002 state OK .*; rig OK [0-9.]* mm" "$work/request.listen.txt" ||
  fail "VB_STATUS did not give cam1's check"
# A 3-camera rig with the target hung, whose cam1 is said to stand 10 mm further along x
# than it does: found at start, and pinned on cam1 (the other two agree).
"$vbutcher" virtual-rig --out "$work/rig3" --cameras 3 >/dev/null
sed -i "s#^carcass: .*#carcass: $work/target.ply#" "$work/rig3/scene.yaml"
awk '/translation: \[/ && ++n == 2 { match($0, /\[[-0-9.e]*/); x = substr($0, RSTART + 1, RLENGTH - 1);
       $0 = substr($0, 1, RSTART) sprintf("%.17g", x + 0.010) substr($0, RSTART + RLENGTH) } 1' \
  "$work/rig3/rig.yaml" >"$work/rig3/rig_moved.yaml"
printf '%s\n' "format: virtualbutcherd-config" "version: 1" "template: lamb.vbt" "rig: rig3/rig_moved.yaml" \
  "virtual_scene: rig3/scene.yaml" "lcm: {url: \"$url\", status_period_ms: 250}" \
  "can: {interface: loopback}" "job: {state_file: job-state}" >"$work/moved.yaml"
# SIGUSR1 while the check at start still waits for its frames (as soon as a camera is ok):
# the check asked for runs after it, not never.
during='wait_for_log moved "camera cam0 (serial VB0001) is ok"; kill -USR1 $daemon_pid'
run_until moved moved.yaml 2
during=
[ "$(grep -c "^<4>virtualbutcherd: rig check: MOVED at " "$work/moved.daemon.log")" = 2 ] ||
  fail "a check asked for (SIGUSR1) during the check at start did not run after it"
grep -q "^<4>virtualbutcherd: rig check: MOVED at .*: cam1 moved [0-9.]* mm, turned [0-9.]* deg; jobs are refused" \
  "$work/moved.daemon.log" || fail "the moved camera was not found at start (or not it alone)"
grep -q "VB_STATUS seq .* state DEGRADED .*rig check: MOVED" "$work/moved.listen.txt" ||
  fail "VB_STATUS did not say DEGRADED for the moved camera"
grep -q "camera cam1 serial VB0002 state OK .*; rig MOVED [0-9.]* mm" "$work/moved.listen.txt" ||
  fail "VB_STATUS did not mark cam1 MOVED"
grep -q "camera cam2 serial VB0003 state OK .*; rig OK [0-9.]* mm" "$work/moved.listen.txt" ||
  fail "VB_STATUS did not find cam2 ok"
grep -q "VB_DIAGNOSTICS seq .* WARNING rig_check: MOVED" "$work/moved.listen.txt" ||
  fail "VB_DIAGNOSTICS did not carry the moved camera"
moved_line=$(grep -o "cam1 moved [0-9.]* mm, turned [0-9.]* deg" "$work/moved.daemon.log" | head -1)

echo "ok: a missing camera is named in READY's STATUS, the log (warning), VB_STATUS and VB_DIAGNOSTICS; measured fps $fps and last frame $ago ms ago; version $version in the log and VB_STATUS; SIMULATION on every line; the rig check on request ok, at start $moved_line"
