#!/usr/bin/env bash
# What virtualbutcherd must never send, each case read back from the saw (the reference saw
# controller in another process, `vbutcher saw-sim --unix`):
#  1. a camera that freezes as the carcass arrives: the job is refused, naming the camera;
#  2. a carcass replaced by another without an empty-hook gap: both get a job;
#  3. SIGTERM while a job is being morphed: the job is refused, no frame of it reaches the
#     saw, and the daemon exits cleanly;
#  4. a morph past job.morph_deadline_ms: abandoned and refused.
# Usage: daemon_faults_test.sh <vbutcher> <virtualbutcherd>
set -euo pipefail
vbutcher=$(realpath "$1")
daemon=$(realpath "$2")
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
fail() {
  echo "FAIL: $*"
  for f in "$work"/daemon*.log "$work"/saw*.log; do echo "--- $f"; tail -30 "$f"; done
  exit 1
}
scene=$work/rig/scene.yaml
# Seconds a carcass of case 2 hangs: longer where a build is slower (scripts/test --tsan sets
# VB_TEST_SLOWDOWN), so that the replacement is still there when it can be taken.
hang_s=$((4 * ${VB_TEST_SLOWDOWN:-1}))

source "$(dirname "$0")/virtual_line.sh"
virtual_line "$vbutcher" "$work"
job_keys="state_file: job-state, max_result_age_ms: 20000"
line_config "$work/vbd.yaml" memq:// "unix:$work/saw.sock" "$job_keys, morph_deadline_ms: 20000"
line_config "$work/vbd_deadline.yaml" memq:// "unix:$work/saw.sock" "$job_keys, morph_deadline_ms: 50"
# The frozen check's silence limit scales too (case 1 is caught by the repeated frame at once).
for f in "$work/vbd.yaml" "$work/vbd_deadline.yaml"; do
  echo "capture: {frozen_periods: $((5 * ${VB_TEST_SLOWDOWN:-1}))}" >>"$f"
done

start_saw() {  # start_saw <log>
  "$vbutcher" saw-sim --unix "$work/saw.sock" --quiet >"$1" &
  saw=$!
  for _ in $(seq 100); do grep -q listening "$1" && break; sleep 0.1; done
}
stop_saw() { kill -TERM $saw; wait $saw; }
start_daemon() {  # start_daemon <config> <log>
  "$daemon" --config "$1" --run-seconds 600 2>"$2" &
  daemon_pid=$!
  for _ in $(seq 200); do grep -q "LCM on" "$2" && break; sleep 0.1; done
  grep -q "LCM on" "$2" || fail "the daemon did not come up"
  sleep 1  # the cameras deliver; the saw leaves safe stop at the first READY heartbeat
}
# wait_for <file> <count> <pattern> <seconds>: the limits only stop a hang (a ThreadSanitizer
# build morphs in about 13 s); each wait ends as soon as its line is there.
wait_for() {
  for _ in $(seq $(($4 * 10))); do
    [ "$(grep -c -- "$3" "$1" || true)" -ge "$2" ] && return 0
    sleep 0.1
  done
  fail "waited $4 s for $2 x '$3' in $1"
}
hang() {  # hang <seed> <hang s> <gap s> [count]: carcasses on the line, in the background
  "$vbutcher" virtual-line --scene "$scene" --count "${4:-1}" --seed "$1" --hang-s "$2" \
    --gap-s "$3" >/dev/null &
  line=$!
}
empty_hook() { kill $line 2>/dev/null || true; wait $line 2>/dev/null || true; sed -i '/^carcass:/d' "$scene"; sleep 1.5; }

start_saw "$work/saw.log"
start_daemon "$work/vbd.yaml" "$work/daemon.log"
log=$work/daemon.log

# 1. Camera VB0002 freezes (repeats its frame of the empty hook) at the moment the carcass
# arrives: carcass and fault go into the scene in one write.
"$vbutcher" virtual-line --scene "$scene" --count 1 --seed 100 --hang-s 0.1 --gap-s 0 >/dev/null
sleep 1.5  # too short a visit to become a job; it leaves rig/carcass_100.ply behind
{ cat "$scene"; echo "carcass: carcass_100.ply"; echo "faults: {VB0002: frozen}"; } >"$work/with_carcass.yaml"
before=$(grep -c "saw verdict" "$log" || true)
mv "$work/with_carcass.yaml" "$scene"
wait_for "$log" $((before + 1)) "saw verdict" 240
grep -q "C[0-9]*: saw verdict refused: camera cam1 was \(repeating its last frame\|frozen\) while the carcass was captured" "$log" ||
  fail "1: the carcass captured with a frozen camera was not refused naming it"
sed -i -e '/^faults:/d' -e '/^  VB[0-9]*:/d' -e '/^carcass:/d' "$scene"
sleep 3  # the camera recovers (stream restart)
echo "1 ok: $(grep -o 'saw verdict refused: camera.*captured' "$log" | head -1)"

# 2. Two carcasses with no empty hook between them: two jobs, both accepted.
hang 110 "$hang_s" 0 2
wait_for "$log" $((before + 3)) "saw verdict" 400
grep -q "changed without an empty-hook gap" "$log" || fail "2: the replacement was not noticed"
[ "$(grep -c 'saw verdict accepted' "$log")" -eq 2 ] || fail "2: not two accepted jobs"
wait $line
empty_hook
echo "2 ok: $(grep -o 'changed without an empty-hook gap ([0-9]* %' "$log")"

# 3. SIGTERM while the next carcass is being morphed.
hang 120 60 0
wait_for "$log" 3 ": morphing " 240
kill -TERM $daemon_pid
wait $daemon_pid || fail "3: the daemon did not exit cleanly on SIGTERM"
grep -q "saw verdict refused: shutting down" "$log" || fail "3: the job under way was not refused"
empty_hook
stop_saw
grep "saw-sim summary" "$work/saw.log"
grep -q "jobs accepted 2 rejected 0 " "$work/saw.log" || fail "3: the saw saw a job after SIGTERM"
echo "3 ok: refused on shutdown; the saw got 2 jobs in all"

# 4. A morph deadline no morph can meet.
start_saw "$work/saw4.log"
start_daemon "$work/vbd_deadline.yaml" "$work/daemon4.log"
hang 130 60 0
wait_for "$work/daemon4.log" 1 "saw verdict" 240
grep -q "saw verdict refused: morph abandoned: still running after 50 ms" "$work/daemon4.log" ||
  fail "4: the late morph was not abandoned"
kill -TERM $daemon_pid
wait $daemon_pid || fail "4: the daemon did not exit cleanly"
stop_saw
grep -q "jobs accepted 0 rejected 0 " "$work/saw4.log" || fail "4: the saw got a job"
echo "4 ok: $(grep -o 'C[0-9]*: morphing.*' "$work/daemon4.log" | head -1); $(grep -o 'saw verdict refused: morph.*ms;' "$work/daemon4.log")"
echo "ok: frozen camera, replaced carcass, shutdown mid-job and a late morph each handled"
