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
