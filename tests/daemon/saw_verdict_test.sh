#!/usr/bin/env bash
# The saw's verdict, read from the saw: virtualbutcherd on the virtual OpenNI2 rig sends its
# jobs to the reference saw controller in another process (`vbutcher saw-sim --unix`, the
# same controller as on the HIL VM's vcan, so it outlives a daemon restart). A stream of
# carcasses, each hung once the one before has its verdict (paced_line), a restart of the
# daemon halfway (its job numbers kept in its state file), then the rest. Every job the daemon
# sent must be one the saw accepted, by the saw's own counters, and the daemon's verdicts must
# say the same, with none refused: the first carcass of each daemon life is hung as it starts
# (its cameras may still be starting) and becomes a job only once the daemon serves (READY=1).
# Usage: saw_verdict_test.sh <vbutcher> <virtualbutcherd> [CARCASSES]
set -euo pipefail
vbutcher=$(realpath "$1")
daemon=$(realpath "$2")
total=${3:-50}
first=$((total / 2))
second=$((total - first))
work=$(mktemp -d)
trap 'kill $(jobs -p) 2>/dev/null || true; rm -rf "$work"' EXIT
fail() {
  echo "FAIL: $*"
  for f in "$work"/daemon*.log "$work/saw.log"; do echo "--- $f"; tail -40 "$f"; done
  exit 1
}

source "$(dirname "$0")/virtual_line.sh"
virtual_line "$vbutcher" "$work"
# Generous age and deadline: this test is about the saw's verdicts, not about speed on a
# loaded machine (scripts/bench-daemon measures that at the line rate).
line_config "$work/vbd.yaml" memq:// "unix:$work/saw.sock" \
  "state_file: job-state, max_result_age_ms: 20000, morph_deadline_ms: 20000"

"$vbutcher" saw-sim --unix "$work/saw.sock" --quiet --ids-out "$work/accepted.txt" >"$work/saw.log" &
saw=$!
for _ in $(seq 100); do grep -q listening "$work/saw.log" && break; sleep 0.1; done

# run_daemon <life> <jobs> <first seed>: one daemon life on a line of <jobs> carcasses.
run_daemon() {
  "$daemon" --config "$work/vbd.yaml" --max-jobs "$2" --run-seconds $(($2 * 20 + 60)) \
    2>"$work/daemon$1.log" &
  local pid=$!
  for _ in $(seq 200); do grep -q "LCM on" "$work/daemon$1.log" && break; sleep 0.1; done
  grep -q "LCM on" "$work/daemon$1.log" || fail "daemon $1 did not come up"
  paced_line "$vbutcher" "$work/rig/scene.yaml" "$2" "$3" "$work/daemon$1.log" $pid ||
    fail "daemon $1: a carcass got no verdict"
  wait $pid || fail "daemon $1 exited with an error"
  sed -i '/^carcass:/d' "$work/rig/scene.yaml"
  grep -q "stopped after $2 jobs" "$work/daemon$1.log" || fail "daemon $1 did not do its $2 jobs"
  # No job before the daemon serves: its first carcass was hung as it started.
  local serving job
  serving=$(grep -n -m1 "virtualbutcherd: serving" "$work/daemon$1.log" | cut -d: -f1 || true)
  job=$(grep -n -m1 "C[0-9]*: \(morphing\|saw verdict\)" "$work/daemon$1.log" | cut -d: -f1 || true)
  [ -n "$serving" ] && [ -n "$job" ] && [ "$serving" -lt "$job" ] ||
    fail "daemon $1: its first job (log line ${job:-none}) came before it served (${serving:-none})"
}
run_daemon 1 "$first" 100
run_daemon 2 "$second" 300
sleep 0.5
kill -TERM $saw
wait $saw
cat "$work"/daemon*.log >"$work/daemon.log"
summary=$(grep "saw-sim summary" "$work/saw.log")
echo "$summary"
grep "stopped after" "$work/daemon.log"
saw_accepted=$(sed -n 's/.* jobs accepted \([0-9]*\) rejected \([0-9]*\) .*/\1/p' <<<"$summary")
saw_rejected=$(sed -n 's/.* jobs accepted \([0-9]*\) rejected \([0-9]*\) .*/\2/p' <<<"$summary")
said_accepted=$(grep -c "saw verdict accepted;" "$work/daemon.log" || true)
said_refused=$(grep -c "saw verdict refused" "$work/daemon.log" || true)
said_other=$(grep -c "saw verdict \(rejected\|unconfirmed\)" "$work/daemon.log" || true)
ids=$(grep -o "C[0-9]*: saw verdict" "$work/daemon.log" | sort | uniq -d | wc -l)
echo "carcasses $total; daemon: accepted $said_accepted, refused $said_refused, rejected or" \
  "unconfirmed $said_other; saw: accepted $saw_accepted, rejected $saw_rejected; repeated carcass ids $ids"
# Every verdict but accepted, with its reason, before any check reads the counts.
grep "saw verdict [rue]" "$work/daemon.log" || true
# A job the daemon sent is one the saw accepted: none rejected or left unconfirmed, and the
# saw's count is the daemon's. None refused either (a morph its check did not trust, a camera
# down or still starting): on this line every carcass is one the daemon can cut.
[ "$said_other" -eq 0 ] || fail "$said_other jobs were rejected or left unconfirmed"
[ "$said_refused" -eq 0 ] || fail "$said_refused carcasses were refused"
[ $((said_accepted + said_refused)) -eq "$total" ] ||
  fail "the daemon reports $said_accepted accepted and $said_refused refused of $total"
[ "$saw_accepted" -eq "$said_accepted" ] ||
  fail "the saw accepted $saw_accepted jobs, the daemon says $said_accepted"
[ "$saw_rejected" -eq 0 ] || fail "the saw rejected $saw_rejected jobs"
[ "$ids" -eq 0 ] || fail "a carcass id was used twice"
[ "$(sort -u "$work/accepted.txt" | wc -l)" -eq "$said_accepted" ] ||
  fail "the saw's accepted ids are not $said_accepted distinct ones"
echo "ok: $total carcasses over a daemon restart, $said_accepted jobs sent and every one accepted by the saw"
