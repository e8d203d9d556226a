#!/usr/bin/env bash
# LCM over real UDP multicast, inside a private network namespace so nothing leaves it:
# vbutcher lcm-publish -> lcm-logger records; lcm-logplayer replays -> vbutcher lcm-listen;
# a malformed message (a negative array length, which LCM 1.3.1's decoder throws on) is
# counted and reported by lcm-listen, which goes on receiving.
# Usage: lcm_udpm_test.sh <vbutcher> <cuts.json>
set -euo pipefail
vbutcher=$1
cuts=$2
if [ "${VB_IN_NETNS:-}" != 1 ]; then
  exec unshare -n env VB_IN_NETNS=1 bash "$0" "$@"
fi
ip link set lo up multicast on
ip route add 224.0.0.0/4 dev lo
url="udpm://239.255.76.67:7667?ttl=0"
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
count=20
# listen <output> <args...>: a listener in the background, returned once it has subscribed.
listen() {
  local out=$1
  shift
  "$vbutcher" lcm-listen --url "$url" "$@" >"$out" &
  listener=$!
  for _ in $(seq 300); do
    grep -qs "^lcm-listen: listening on" "$out" && return 0
    kill -0 $listener 2>/dev/null || break
    sleep 0.1
  done
  echo "FAIL: lcm-listen did not subscribe (exited, or 30 s passed):"
  cat "$out"
  exit 1
}
# The sockets bound to the LCM port in this namespace: one per process that has subscribed.
receivers() { awk '$2 ~ /:1DF3$/' /proc/net/udp | wc -l; }

# 1. Live: a listener and the logger, then the publisher.
lcm-logger --lcm-url="$url" --quiet "$work/run.lcmlog" &
logger=$!
for _ in $(seq 300); do [ "$(receivers)" -ge 1 ] && break; sleep 0.1; done
[ "$(receivers)" -ge 1 ] || { echo "FAIL: lcm-logger did not bind the LCM port in 30 s"; exit 1; }
listen "$work/live.txt" --count $count --timeout 20
"$vbutcher" lcm-publish --url "$url" --cuts "$cuts" --carcass-id netns-test --count $count --period-ms 10
wait $listener || { echo "FAIL: live listener:"; cat "$work/live.txt"; exit 1; }
sleep 0.3
kill -INT $logger
wait $logger || true
grep -q "received $count invalid 0 out_of_order 0" "$work/live.txt" || { cat "$work/live.txt"; exit 1; }
# What lcm-logger recorded: the events of the log (sync word, event number, time, channel and
# data lengths, channel, data); those on the cut-lines channel counted.
logged=$(/usr/bin/python3 - "$work/run.lcmlog" <<'PY'
import struct, sys
data, at, n = open(sys.argv[1], "rb").read(), 0, 0
while at + 28 <= len(data):
    sync, _, _, channel_len, data_len = struct.unpack(">IqqII", data[at:at + 28])
    if sync != 0xEDA1DA01:
        sys.exit("not an LCM log event at byte %d" % at)
    n += data[at + 28:at + 28 + channel_len] == b"VB_CUT_LINES"
    at += 28 + channel_len + data_len
print(n)
PY
) || { echo "FAIL: the log lcm-logger wrote cannot be read: $logged"; exit 1; }
[ "$logged" = $count ] || { echo "FAIL: lcm-logger recorded $logged of $count cut-lines messages"; exit 1; }

# 2. Replay: lcm-logplayer plays the log back to a new listener.
listen "$work/replay.txt" --count $count --timeout 20
lcm-logplayer --lcm-url="$url" "$work/run.lcmlog"
wait $listener || { echo "FAIL: replay listener:"; cat "$work/replay.txt"; exit 1; }
grep -q "received $count invalid 0 out_of_order 0" "$work/replay.txt" || { cat "$work/replay.txt"; exit 1; }

# 3. A malformed cut-lines message, sent as raw LCM over UDP (magic "LC02", sequence,
# channel, then the payload lcm-gen's Python type encodes with num_cuts = -1), between
# good ones (from two publishers, so one sequence number starts again).
types=$(dirname "$(dirname "$(realpath "$vbutcher")")")/io/lcmtypes/python
listen "$work/malformed.txt" --count 3 --timeout 20
"$vbutcher" lcm-publish --url "$url" --cuts "$cuts" --carcass-id before --count 1 >/dev/null
/usr/bin/python3 - "$types" <<'PY'
import socket, struct, sys
sys.path.insert(0, sys.argv[1])
from vbutcher.cut_lines_t import cut_lines_t
m = cut_lines_t()
m.carcass_id, m.template_id, m.status = "bad", "bad", "bad"
m.num_cuts = -1
packet = struct.pack(">II", 0x4C433032, 1) + b"VB_CUT_LINES\0" + m.encode()
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)
s.sendto(packet, ("239.255.76.67", 7667))
PY
"$vbutcher" lcm-publish --url "$url" --cuts "$cuts" --carcass-id after --count 2 --period-ms 10 >/dev/null
rc=0
wait $listener || rc=$?
grep -q "VB_CUT_LINES: malformed message of [0-9]* bytes" "$work/malformed.txt" &&
  grep -q "received 3 invalid 0 out_of_order [01] malformed 1" "$work/malformed.txt" && [ $rc = 3 ] ||
  { echo "FAIL: malformed message (exit $rc):"; cat "$work/malformed.txt"; exit 1; }
echo "ok: $count cut-lines messages over udpm live and replayed from lcm-logger's log; a malformed one reported and survived"
