#!/usr/bin/env bash
# The systemd unit as systemd reads it, and the daemon's side of the notify protocol without
# systemd: `systemd-analyze verify` passes, `systemd-analyze security --offline=true` rates
# the exposure at 2.0 or lower, and virtualbutcherd sends READY=1, STATUS= and WATCHDOG=1 to
# a NOTIFY_SOCKET we bind ourselves, and STOPPING=1 on SIGTERM.
# Usage: systemd_unit_test.sh <unit file> <virtualbutcherd> <vbutcher>
set -euo pipefail
unit=$(realpath "$1")
daemon=$(realpath "$2")
vbutcher=$(realpath "$3")
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT

# verify wants ExecStart's binary where the unit says; point it at the built one.
sed "s|/usr/bin/virtualbutcherd|$daemon|g" "$unit" >"$work/virtualbutcherd.service"
out=$(systemd-analyze verify "$work/virtualbutcherd.service" 2>&1) || { echo "FAIL: verify: $out"; exit 1; }
[ -z "$out" ] || { echo "FAIL: verify complained: $out"; exit 1; }
exposure=$(systemd-analyze security --offline=true "$work/virtualbutcherd.service" 2>&1 |
  sed -n 's/.*Overall exposure level for .*: \([0-9.]*\).*/\1/p')
[ -n "$exposure" ] || { echo "FAIL: no exposure level"; exit 1; }
awk -v e="$exposure" 'BEGIN { exit !(e <= 2.0) }' || { echo "FAIL: exposure $exposure > 2.0"; exit 1; }
echo "ok: systemd-analyze verify clean, exposure $exposure"

# sd_notify: a datagram socket of our own as NOTIFY_SOCKET.
"$vbutcher" synth --out "$work/set" --count 1 >/dev/null
"$vbutcher" template compile --template "$work/set/template.ply" \
  --annotations "$work/set/template_annotations.yaml" -o "$work/lamb.vbt" >/dev/null
"$vbutcher" virtual-rig --out "$work/rig" --cameras 2 >/dev/null
# The second camera's first frame comes 1.5 s after the first's (well within the 5 s the
# daemon is given for a first frame here): frames from one camera with the other still
# starting must not become a job.
echo "start_delays_ms: {VB0002: 1500}" >>"$work/rig/scene.yaml"
cat >"$work/vbd.yaml" <<YAML
format: virtualbutcherd-config
version: 1
template: lamb.vbt
rig: rig/rig.yaml
virtual_scene: rig/scene.yaml
lcm: {url: "memq://"}
can: {interface: loopback}
capture: {first_frame_timeout_ms: 5000}
YAML
python3 - "$work/notify.sock" "$work/notify.log" <<'PY' &
import socket, sys, time
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
s.bind(sys.argv[1])
s.settimeout(1.0)
end = time.time() + 60
with open(sys.argv[2], "w") as log:
    while time.time() < end:
        try:
            log.write(s.recv(4096).decode() + "\n---\n")
            log.flush()
        except socket.timeout:
            pass
PY
for _ in $(seq 50); do [ -S "$work/notify.sock" ] && break; sleep 0.1; done
NOTIFY_SOCKET="$work/notify.sock" WATCHDOG_USEC=3000000 "$daemon" --config "$work/vbd.yaml" \
  --run-seconds 30 2>"$work/daemon.log" &
pid=$!
for _ in $(seq 100); do grep -q "WATCHDOG=1" "$work/notify.log" 2>/dev/null && break; sleep 0.1; done
kill -TERM $pid
wait $pid || { echo "FAIL: daemon exit"; cat "$work/daemon.log"; exit 1; }
sleep 0.5
for want in "READY=1" "WATCHDOG=1" "STOPPING=1"; do
  grep -q "$want" "$work/notify.log" || { echo "FAIL: no $want"; cat "$work/notify.log"; exit 1; }
done
# The status sent with READY=1 (the line after it): ready, both cameras ok and no job yet,
# though the scene's carcass hangs there from the start while the second camera starts (no
# carcass becomes a job before READY=1), and the memory budget (not in sanitizer builds, which
# have none).
ready=$(grep -A1 '^READY=1$' "$work/notify.log" | grep '^STATUS=' || true)
want="STATUS=ready, waiting for a carcass; cameras 2 of 2 ok; jobs accepted 0, rejected 0, "
want+="unconfirmed 0, refused 0"
grep -q "no memory budget in this build" "$work/daemon.log" ||
  want="$want; memory [0-9]* of 512 MiB, 0 from the heap"
want="$want; last -: -$"
grep -q "^$want" <<<"$ready" || {
  echo "FAIL: READY=1 came with '$ready', not '$want'"; cat "$work/notify.log"; exit 1; }
echo "ok: READY=1, STATUS= (with the memory budget), WATCHDOG=1 and STOPPING=1 over NOTIFY_SOCKET"

# A bad configuration: non-zero exit before READY, the file and key named.
sed 's/^version: 1/version: 7/' "$work/vbd.yaml" >"$work/bad.yaml"
: >"$work/notify.log"
if NOTIFY_SOCKET="$work/notify.sock" "$daemon" --config "$work/bad.yaml" 2>"$work/bad.log"; then
  echo "FAIL: started with a bad configuration"; exit 1
fi
grep -q "bad.yaml:2: version: 7 is not supported" "$work/bad.log" || { cat "$work/bad.log"; exit 1; }
sleep 0.3
! grep -q "READY=1" "$work/notify.log" || { echo "FAIL: READY=1 with a bad configuration"; exit 1; }
echo "ok: a bad configuration stops the daemon before READY=1, naming file, line and key"
