#!/usr/bin/env bash
# The install rules: programs, unit, configuration, compiled template and OpenNI2's private
# runtime land where they should under a prefix, and the installed programs find their
# OpenNI2 driver folder (RUNPATH $ORIGIN/../lib/...) and work from there.
# Usage: install_test.sh <build dir>
set -euo pipefail
build=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cmake --install "$build" --prefix "$work/usr" >/dev/null
for f in bin/virtualbutcherd bin/vbutcher lib/systemd/system/virtualbutcherd.service \
         etc/virtualbutcher/virtualbutcherd.yaml etc/virtualbutcher/rig.yaml \
         share/virtualbutcher/lamb.vbt share/virtualbutcher/plot-shapes lib/virtualbutcher/openni2/libOpenNI2.so.0 \
         lib/virtualbutcher/openni2/OpenNI2/Drivers/libVirtualButcherRig.so.0 \
         lib/virtualbutcher/openni2/OpenNI2/Drivers/libOniFile.so.0; do
  [ -e "$work/usr/$f" ] || { echo "FAIL: $f not installed"; exit 1; }
done
"$work/usr/bin/vbutcher" template info "$work/usr/share/virtualbutcher/lamb.vbt" >/dev/null
cd "$work"
"$work/usr/bin/vbutcher" virtual-rig --out rig --cameras 2 >/dev/null
"$work/usr/bin/vbutcher" capture --rig rig/rig.yaml --scene rig/scene.yaml --out fused.ply >/dev/null
[ -s fused.ply ] || { echo "FAIL: the installed vbutcher captured nothing"; exit 1; }
echo "ok: installed layout complete; the installed programs capture through their own OpenNI2 folder"
