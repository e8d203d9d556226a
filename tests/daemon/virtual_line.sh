# Sourced by the daemon's shell tests: a virtual line to run virtualbutcherd on.
# virtual_line <vbutcher> <work>: a compiled synthetic lamb template (work/lamb.vbt) and a
# 4-camera virtual rig (work/rig) with an empty hook.
virtual_line() {
  "$1" synth --out "$2/set" --count 1 --seed 1 >/dev/null
  "$1" template compile --template "$2/set/template.ply" \
    --annotations "$2/set/template_annotations.yaml" -o "$2/lamb.vbt" >/dev/null
  "$1" virtual-rig --out "$2/rig" >/dev/null
  sed -i '/^carcass:/d' "$2/rig/scene.yaml"  # the hook starts empty
}
# line_config <file> <lcm url> <can interface> <job keys>: a daemon configuration for it
# (relative paths from the file's folder, which must be the virtual_line work folder).
line_config() {
  cat >"$1" <<YAML
format: virtualbutcherd-config
version: 1
template: lamb.vbt
rig: rig/rig.yaml
virtual_scene: rig/scene.yaml
lcm: {url: "$2"}
can: {interface: "$3"}
morph: {template_up: [0, 0, 1], rig_up: [0, 0, 1], max_tilt_deg: 45}
job: {$4}
X_SawRig: {translation: [0, 0, 1.8], rotation_wxyz: [1, 0, 0, 0]}
YAML
}
# paced_line <vbutcher> <scene> <count> <first seed> <daemon log> <daemon pid>: hangs <count>
# carcasses one at a time, each until the daemon has taken it as a job, then empties the hook
# and waits for the job's saw verdict and for the daemon to see the hook empty before the
# next. A test of verdicts then does not depend on the machine's speed (a morph on a loaded
# 2-core machine took up to 2.8 s against the line's 2 s); `scripts/bench-daemon` measures the
# pace. Returns 1 naming the carcass when a step took over 60 s or the daemon exited.
paced_line() {
  local k line
  for k in $(seq "$3"); do
    "$1" virtual-line --scene "$2" --count 1 --seed $(($4 + k - 1)) --hang-s 600 --gap-s 0 \
      >/dev/null &
    line=$!
    # Taken: a job started (morphing) or was refused before its morph.
    _paced_wait "$5" "$6" "$k" 'C[0-9]*: \(morphing\|saw verdict\)' "-o" || true
    kill "$line" 2>/dev/null || true
    wait "$line" 2>/dev/null || true
    sed -i '/^carcass:/d' "$2"
    # (After the last, a daemon told to stop after it may exit before it sees the hook empty.)
    _paced_wait "$5" "$6" "$k" 'C[0-9]*: saw verdict ' "" && { [ "$k" -eq "$3" ] ||
      _paced_wait "$5" "$6" "$k" 'the carcass left\|changed without an empty-hook gap' ""; } || {
      echo "paced_line: carcass $k of $3 (seed $(($4 + k - 1))) has no saw verdict or did not" \
        "leave in $5" >&2
      return 1
    }
  done
}
# _paced_wait <log> <pid> <n> <pattern> <-o or "">: until <n> distinct carcasses (-o) or lines
# match <pattern> in <log>, for at most 60 s; 1 when not reached.
_paced_wait() {
  for _ in $(seq 600); do
    [ "$(_paced_count "$1" "$4" "$5")" -ge "$3" ] && return 0
    kill -0 "$2" 2>/dev/null || break
    sleep 0.1
  done
  # Once more: the daemon may have logged the last line and exited since the count above.
  [ "$(_paced_count "$1" "$4" "$5")" -ge "$3" ]
}
# _paced_count <log> <pattern> <-o or "">: distinct carcasses (-o) or lines matching.
_paced_count() {
  local n
  if [ -n "$3" ]; then
    n=$(grep -o "$2" "$1" | cut -d: -f1 | sort -u | wc -l || true)
  else
    n=$(grep -c "$2" "$1" || true)
  fi
  echo "${n:-0}"
}
