#!/usr/bin/env bash
# The real lamb scan (../shared/data/real-lamb/lambDenseKey.ply beside the checkout, MIT
# licence, not in this repository; VB_REAL_LAMB names another path) through the full morph
# with the compiled lamb, as `vbutcher morph` runs it. Its normals are all zero length: they
# must be dropped with a warning, and the morph must run and report its fit, placement,
# confidence and part shares. Skipped (exit 77) where the scan is not present.
set -u
vbutcher=$1
model=$2
scan=${VB_REAL_LAMB:-$3}
if [ ! -f "$scan" ]; then
  echo "skipped: no real lamb scan at $scan"
  exit 77
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
out=$("$vbutcher" morph --model "$model" --target "$scan" --stage full --out "$work/morph.ply" \
  --cuts "$work/cuts.json" 2>&1)
status=$?
echo "$out"
failures=0
[ "$status" -eq 0 ] || { echo "FAIL: morph exited $status"; failures=$((failures + 1)); }
for want in "normals are zero-length or not finite" "morph: fit: scan to morph distance mean" \
            "morph: placement:" "confidence" "% of the carcass"; do
  grep -qF -- "$want" <<<"$out" || { echo "FAIL: no '$want' in the output"; failures=$((failures + 1)); }
done
[ -s "$work/morph.ply" ] || { echo "FAIL: no morphed mesh"; failures=$((failures + 1)); }
exit "$failures"
