#!/usr/bin/env bash
# virtualbutcherd on recordings, as a test engineer runs it on .oni files from a rig: the
# virtual rig is recorded with a carcass already on the hook (vbutcher record), then the
# service starts on the playback calibration alone (no virtual scene) and must make that
# carcass a job the saw accepts, though its cameras start while the carcass hangs there: it
# is taken once the daemon serves (READY=1). The verdict is the in-process saw controller's,
# read from the log. The rule that a job is judged by the frame set it is made from (not by a
# camera's state in earlier sets) failed 2 of 3 starts here before it was fixed, when jobs
# could start while a camera was still starting.
# Usage: daemon_playback_test.sh <vbutcher> <virtualbutcherd>
set -euo pipefail
vbutcher=$(realpath "$1")
daemon=$(realpath "$2")
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*"; echo "--- daemon log"; cat "$work/daemon.log" 2>/dev/null; exit 1; }

source "$(dirname "$0")/virtual_line.sh"
virtual_line "$vbutcher" "$work"
echo "carcass: carcass.ply" >>"$work/rig/scene.yaml"  # virtual-rig wrote it; hang it
"$vbutcher" record --rig "$work/rig/rig.yaml" --scene "$work/rig/scene.yaml" \
  --out "$work/rec" --seconds 3 >/dev/null || fail "record"
# 3 s of recording: OpenNI2's player loops it, and a reader that pauses about one loop (a
# sanitised fusion takes 1.7 s) is handed the frame it read before, which capture skips.
unset VB_VIRTUAL_SCENE
# A sanitizer build morphs 20x slower: the deadline and the result's age allow it.
cat >"$work/vbd.yaml" <<YAML
format: virtualbutcherd-config
version: 1
template: lamb.vbt
rig: rec/rig.yaml
lcm: {url: "memq://"}
can: {interface: loopback}
morph: {template_up: [0, 0, 1], rig_up: [0, 0, 1], max_tilt_deg: 45}
job: {morph_deadline_ms: 60000, max_result_age_ms: 60000}
X_SawRig: {translation: [0, 0, 1.8], rotation_wxyz: [1, 0, 0, 0]}
YAML
# Three starts: which camera is still starting when the first frame sets arrive varies.
for run in 1 2 3; do
  "$daemon" --config "$work/vbd.yaml" --max-jobs 1 --run-seconds 300 >"$work/daemon.log" 2>&1 ||
    fail "run $run: the daemon exited with an error"
  grep -q "C[0-9]*: saw verdict accepted" "$work/daemon.log" ||
    fail "run $run: the carcass on the recordings was not accepted"
  grep -q "loopback saw controller: jobs accepted 1, rejected 0" "$work/daemon.log" ||
    fail "run $run: the saw controller did not accept the job"
  echo "run $run ok: $(grep -o 'saw verdict accepted; [0-9]* points' "$work/daemon.log")"
done
