#!/usr/bin/env bash
# Hardware-in-loop test of the saw link on a real Linux CAN stack: this machine's kernel has
# no AF_CAN, so it boots Debian's kernel in qemu (software emulation) with the host's root
# shared read-only over 9p, and runs tests/hil/inside.sh there on vcan interfaces.
# Usage: can_hil_test.sh VBUTCHER WORK_DIR [JOBS]
# WORK_DIR keeps the kernel package and the VM image between runs.
set -euo pipefail
vbutcher=$(readlink -f "$1")
work=$2
jobs=${3:-3000}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$work"
work=$(readlink -f "$work")

# The kernel: Debian's linux-image-amd64 (its CAN, vcan, can-gw and 9p modules are plain .ko).
deb=$(ls "$work"/linux-image-*-amd64_*.deb 2>/dev/null | head -1 || true)
if [ -z "$deb" ]; then
  package=$(apt-cache depends linux-image-amd64 2>/dev/null | awk '/Depends: linux-image-[0-9]/ {print $2; exit}' || true)
  if [ -z "$package" ]; then  # no package lists yet on a fresh machine
    apt-get update -q -o DPkg::Lock::Timeout=600 >/dev/null
    package=$(apt-cache depends linux-image-amd64 | awk '/Depends: linux-image-[0-9]/ {print $2; exit}')
  fi
  [ -n "$package" ] || { echo "FAIL: apt-cache knows no linux-image-amd64 (run apt-get update)"; exit 1; }
  (cd "$work" && apt-get download "$package" 2>&1 | tail -1)
  deb=$(ls "$work"/linux-image-*-amd64_*.deb | head -1)
fi
if [ ! -s "$work/vm/vmlinux" ] || [ "$deb" -nt "$work/vm/vmlinux" ] || [ "$here/make-vm.py" -nt "$work/vm/initramfs.cpio.gz" ]; then
  /usr/bin/python3 "$here/make-vm.py" "$deb" "$work/vm"
fi

# Part D runs virtualbutcherd itself on vcan0: a one-camera virtual rig with an empty hook
# (no carcass: only its heartbeat and its death matter there), LCM on memq.
vbd=$(dirname "$(dirname "$vbutcher")")/daemon/virtualbutcherd
vbd_config=
if [ -x "$vbd" ]; then
  d="$work/daemon"
  rm -rf "$d"
  "$vbutcher" synth --out "$d/set" --count 1 --seed 1 >/dev/null
  "$vbutcher" template compile --template "$d/set/template.ply" \
    --annotations "$d/set/template_annotations.yaml" -o "$d/lamb.vbt" >/dev/null
  "$vbutcher" virtual-rig --out "$d/rig" --cameras 1 --fps 5 >/dev/null
  sed -i '/^carcass:/d' "$d/rig/scene.yaml"
  printf '%s\n' "format: virtualbutcherd-config" "version: 1" "template: lamb.vbt" \
    "rig: rig/rig.yaml" "virtual_scene: rig/scene.yaml" "capture: {fps: 5}" \
    'lcm: {url: "memq://"}' "can: {interface: vcan0}" >"$d/vbd.yaml"
  vbd_config="$d/vbd.yaml"
fi

log="$work/console.log"
start=$(date +%s)
timeout 1500 qemu-system-x86_64 -m 1024 -smp 2 -nographic -no-reboot \
  -kernel "$work/vm/vmlinux" -initrd "$work/vm/initramfs.cpio.gz" \
  -append "console=ttyS0 quiet panic=-1 vbtest=$here/inside.sh vbargs=$vbutcher,$jobs,$vbd_config" \
  -virtfs local,path=/,mount_tag=hostroot,security_model=none,readonly=on,multidevs=remap \
  -nic none </dev/null >"$log" 2>&1 || true
echo "HIL VM ran $(( $(date +%s) - start )) s; console in $log"
grep -a "^HIL" "$log" | tr -d '\r'

failures=0
fail() { echo "FAIL: $*"; failures=$((failures + 1)); }
line() { grep -a "$1" "$log" | tr -d '\r' | head -1; }
field() { sed -n "s/.* $2 \([0-9a-f]*\).*/\1/p" <<<"$1"; }

grep -aq "HIL done" "$log" || fail "the VM did not finish (see $log)"
send=$(line "HIL A saw-send summary")
faults=$(field "$send" faults)
[ "${faults:-0}" -ge 10000 ] || fail "only ${faults:-0} faults injected, want >= 10000"
verdict=$(line "HIL A faulted_jobs_accepted")
[ "$(field "$verdict" faulted_jobs_accepted)" = 0 ] || fail "a job with injected faults was accepted: $verdict"
clean=$(field "$verdict" clean_jobs)
accepted=$(field "$verdict" clean_jobs_accepted)
# Availability, not safety: a fault in one job's start frame costs the next job its start
# too (the start counter must advance by exactly one), so some clean jobs are refused.
[ "${accepted:-0}" -ge $(( ${clean:-1} * 7 / 10 )) ] || fail "only $accepted of $clean clean jobs accepted"
stop_a=$(line "HIL A saw-sim: .*SAFE STOP")
after=$(sed -n 's/.*SAFE STOP \([0-9]*\) ms after the last heartbeat.*/\1/p' <<<"$stop_a")
[ -n "$after" ] && [ "$after" -le 300 ] || fail "A: no safe stop within 300 ms of the last heartbeat: $stop_a"
# stop_after_kill <part> <who>: the saw's safe stop within 3 heartbeat periods of kill -9.
stop_after_kill() {
  local killed stopped
  killed=$(field "$(line "HIL $1 killed_at_epoch_ms")" killed_at_epoch_ms)
  stopped=$(field "$(line "HIL $1 saw-sim: .*SAFE STOP")" epoch_ms)
  if [ -n "$killed" ] && [ -n "$stopped" ]; then
    echo "HIL $1 safe stop $((stopped - killed)) ms after kill -9 of $2"
    [ $((stopped - killed)) -le 300 ] || fail "$1: safe stop $((stopped - killed)) ms after $2 died"
  else
    fail "$1: no safe stop after $2 was killed"
  fi
}
stop_after_kill B "the sender"
if [ -n "$vbd_config" ]; then
  grep -aq "HIL D .*safe stop left" "$log" || fail "D: the daemon's heartbeat never took the saw out of safe stop"
  stop_after_kill D virtualbutcherd
fi
for c in "clean 20" "duplicate 0" "bitflip 0"; do
  set -- $c
  got=$(sed -n 's/.*jobs accepted \([0-9]*\) .*/\1/p' <<<"$(line "HIL C $1 saw-sim summary")")
  [ "$got" = "$2" ] || fail "C $1: $got jobs accepted, want $2"
done
echo "$failures failed"
[ "$failures" -eq 0 ]
