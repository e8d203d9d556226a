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
# carcasses one at a time (1.6 s on the hook, 0.4 s gap), and hangs the next only once the
# daemon has logged a saw verdict for every one so far. A test of verdicts then does not
# depend on the machine's speed (a morph on a loaded 2-core machine took up to 2.8 s against
# the line's 2 s); `scripts/bench-daemon` measures the pace. Returns 1 naming the carcass
# when no verdict came within 60 s or the daemon exited.
paced_line() {
  local k verdicts
  for k in $(seq "$3"); do
    "$1" virtual-line --scene "$2" --count 1 --seed $(($4 + k - 1)) --hang-s 1.6 --gap-s 0.4 \
      >/dev/null || return 1
    for _ in $(seq 600); do
      verdicts=$(grep -c "C[0-9]*: saw verdict " "$5" || true)
      [ "$verdicts" -ge "$k" ] && break
      kill -0 "$6" 2>/dev/null || break
      sleep 0.1
    done
    if [ "$verdicts" -lt "$k" ]; then
      echo "paced_line: carcass $k of $3 (seed $(($4 + k - 1))) has no saw verdict in $5" >&2
      return 1
    fi
  done
}
