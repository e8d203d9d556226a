#!/usr/bin/env bash
# The vbutcher command as a user runs it: good runs succeed and write files, bad arguments
# fail with a message naming the argument and a non-zero exit code.
set -u
vbutcher=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
last_out=
check() {  # check <description> <expected exit, or "nonzero"> <expected text> <command...>
  local what=$1 want=$2 text=$3
  shift 3
  local out status
  out=$("$@" 2>&1)
  status=$?
  last_out=$out  # for a further check of the same run
  local bad=0
  if [ "$want" = nonzero ]; then [ "$status" -ne 0 ] || bad=1; else [ "$status" -eq "$want" ] || bad=1; fi
  if [ "$bad" -ne 0 ] || ! grep -q -- "$text" <<<"$out"; then
    echo "FAIL: $what: exit $status (want $want), output:"
    echo "$out" | head -20
    failures=$((failures + 1))
  else
    echo "ok: $what"
  fi
}
check "synth writes a set" 0 "template:" "$vbutcher" synth --out "$work/set" --count 2 --seed 3 --sigma-mm 2 --cloud
for f in template.ply template_annotations.yaml template_skeleton.yaml synthetic_set.yaml \
         target_000.ply target_000_truth.ply target_000_truth.yaml target_001_cloud.ply; do
  [ -s "$work/set/$f" ] || { echo "FAIL: missing $f"; failures=$((failures + 1)); }
done
check "count must be positive" 2 "--count" "$vbutcher" synth --out "$work/x" --count 0
check "sigma must be a number" nonzero "sigma" "$vbutcher" synth --out "$work/x" --sigma-mm abc
check "missing needs cloud" 2 "--missing" "$vbutcher" synth --out "$work/x" --missing
check "out is required" nonzero "--out" "$vbutcher" synth --count 1
check "unknown subcommand" nonzero "" "$vbutcher" frobnicate
check "unwritable output" 1 "cannot create" "$vbutcher" synth --out /proc/vb-cannot-write --count 1

# morph: the template and a target of the set just written.
# Without --stage it is the whole morph: the coarse stage, the dense stage and the check.
check "morph writes the posed template and a report" 0 "coarse total" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/m.ply" --report "$work/r.json"
for line in "morph: dense: noise" "morph: check: "; do
  grep -q -- "$line" <<<"$last_out" || { echo "FAIL: morph without --stage printed no '$line'"; failures=$((failures + 1)); }
done
grep -q '"rounds"' "$work/r.json" || { echo "FAIL: report of a morph without --stage lacks the dense rounds"; failures=$((failures + 1)); }
check "morph --stage coarse stops after the posture alignment" 0 "coarse total" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/c.ply" \
  --stage coarse --report "$work/rc.json"
if grep -q "morph: dense:" <<<"$last_out" || grep -q '"dense"' "$work/rc.json"; then
  echo "FAIL: morph --stage coarse ran the dense stage"; failures=$((failures + 1))
fi
[ -s "$work/m.ply" ] || { echo "FAIL: morph wrote no mesh"; failures=$((failures + 1)); }
grep -q '"ok": true' "$work/r.json" || { echo "FAIL: report does not say ok"; failures=$((failures + 1)); }
grep -q '"placement"' "$work/r.json" || { echo "FAIL: report does not say where the placement came from"; failures=$((failures + 1)); }
grep -q '"kept"' "$work/r.json" || { echo "FAIL: report does not say whether the deformation was kept"; failures=$((failures + 1)); }
# The coarse stage's refit, as a reader of the report gets it: a scale within the refit's
# bounds (1/2 to 2) and a turn in degrees.
/usr/bin/python3 -c 'import json, sys
a = json.load(open(sys.argv[1]))["association"]
sys.exit(0 if 0.5 <= a["refit_scale"] <= 2.0 and 0.0 <= a["refit_turn_deg"] <= 180.0 else 1)' "$work/r.json" \
  || { echo "FAIL: report lacks the refit's scale and turn, or they are out of range"; failures=$((failures + 1)); }
# The placements the choice compared: one of them the chosen (no turn, the choice's score),
# the others turned from it.
/usr/bin/python3 -c 'import json, sys
a = json.load(open(sys.argv[1]))["association"]
p = a["placements_compared"]
chosen = [q for q in p if q["chosen"]]
sys.exit(0 if len(chosen) == 1 and chosen[0]["turn_from_chosen_deg"] < 1e-6
         and chosen[0]["disagreement"] == a["choice_disagreement"]
         and all(q["turn_from_chosen_deg"] > 0 for q in p if not q["chosen"]) else 1)' "$work/r.json" \
  || { echo "FAIL: report lacks the placements compared, or the chosen one is not the least"; failures=$((failures + 1)); }
# The upright prior: targets hanging from the gambrel, as on the line.
check "synth writes hanging targets" 0 "template:" "$vbutcher" synth --out "$work/up" --count 1 --seed 4 --upright
check "morph with the upright prior" 0 "coarse total" \
  "$vbutcher" morph --template "$work/up/template.ply" --target "$work/up/target_000.ply" --out "$work/u.ply" \
  --stage coarse --template-up 0 0 1 --target-up 0 0 1 --max-tilt-deg 30
check "the upright prior needs both directions" 2 "--target-up" \
  "$vbutcher" morph --template "$work/up/template.ply" --target "$work/up/target_000.ply" --out "$work/x.ply" --template-up 0 0 1
check "the upright prior refuses a zero direction" 2 "--template-up" \
  "$vbutcher" morph --template "$work/up/template.ply" --target "$work/up/target_000.ply" --out "$work/x.ply" \
  --template-up 0 0 0 --target-up 0 0 1
check "the upright prior's tilt is range-checked" nonzero "max-tilt-deg" \
  "$vbutcher" morph --template "$work/up/template.ply" --target "$work/up/target_000.ply" --out "$work/x.ply" \
  --template-up 0 0 1 --target-up 0 0 1 --max-tilt-deg 200
printf 'OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n' > "$work/open.off"
# The full stage with the template's cut annotations: morphed mesh, cuts and part measures.
check "morph --stage full transfers the cuts, parts in litres and square metres" 0 \
  "part shoulder *volume [0-9.]* L (.*) area [0-9.]* m2" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_001_cloud.ply" --out "$work/f.ply" \
  --stage full --annotations "$work/set/template_annotations.yaml" --cuts "$work/c.json" --report "$work/fr.json"
for key in '"leg_loin"' '"loin_rack"' '"rack_shoulder"' '"confidence"' '"volume"' '"units"'; do
  grep -q -- "$key" "$work/c.json" 2>/dev/null || { echo "FAIL: cuts JSON lacks $key"; failures=$((failures + 1)); }
done
grep -q '"rounds"' "$work/fr.json" 2>/dev/null || { echo "FAIL: report lacks the dense rounds"; failures=$((failures + 1)); }
# The morph's threads change its speed, not its result: one and two threads write the same
# mesh and cuts, byte for byte (MorpherTest checks the same in-process).
for threads in 1 2; do
  check "morph --threads $threads" 0 "part shoulder" \
    "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_001_cloud.ply" \
    --out "$work/t$threads.ply" --stage full --annotations "$work/set/template_annotations.yaml" \
    --cuts "$work/t$threads.json" --threads "$threads"
done
for ext in ply json; do
  cmp -s "$work/t1.$ext" "$work/t2.$ext" ||
    { echo "FAIL: morph on 1 and 2 threads wrote different .$ext files"; failures=$((failures + 1)); }
done
check "morph refuses 0 threads" 2 "--threads: Value 0 not in range" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" --threads 0
check "bench shapes refuses 17 threads" 2 "--threads: Value 17 not in range" \
  "$vbutcher" bench shapes --threads 17 --csv "$work/x.csv"
check "bench shapes refuses an unknown skeleton" 2 "--template-features: bogus not in {levelset,mcf}" \
  "$vbutcher" bench shapes --template-features bogus --csv "$work/x.csv"
check "bench shapes refuses an unknown variant" 2 "--variants: 'bogus' is none of clean, shadow, clutter" \
  "$vbutcher" bench shapes --variants clean,bogus --csv "$work/x.csv"
check "bench shapes refuses no clutter" 2 "--clutter-fraction must lie in (0, 1]" \
  "$vbutcher" bench shapes --clutter-fraction 0 --csv "$work/x.csv"
# The template's skeleton reaches the morph: with the paper's MCF skeleton the coarse stage
# ends elsewhere on the shadowed lamb than with the level-set one. And the MCF skeleton does
# not depend on the process: another run (on one thread) writes the same rows.
for run in levelset mcf mcf_again; do
  check "bench shapes --template-features ${run%_again}" 0 "template model (${run%_again} skeleton)" \
    "$vbutcher" bench shapes --shapes lamb --lamb-pairs 1 --sigmas-mm 0 --variants shadow --no-png \
    --template-features "${run%_again}" --threads "$([ "$run" = mcf_again ] && echo 1 || echo 2)" \
    --csv "$work/features_$run.csv"
done
column_of() {  # column_of <csv> <method> <column name>: that column of the method's rows
  awk -F, -v method="$2" -v name="$3" 'NR == 1 { for (i = 1; i <= NF; i++) { if ($i == "method") m = i; if ($i == name) c = i } }
    NR > 1 && m && c && $m == method { print $c }' "$1"
}
levelset=$(column_of "$work/features_levelset.csv" coarse mean_err_rel)
mcf=$(column_of "$work/features_mcf.csv" coarse mean_err_rel)
[ -n "$levelset" ] && [ -n "$mcf" ] && [ "$levelset" != "$mcf" ] ||
  { echo "FAIL: the MCF and level-set templates gave coarse errors '$levelset' and '$mcf'"; failures=$((failures + 1)); }
for method in coarse full; do
  for name in mean_err_rel max_err_rel placement_err_deg; do
    [ "$(column_of "$work/features_mcf.csv" $method $name)" = "$(column_of "$work/features_mcf_again.csv" $method $name)" ] ||
      { echo "FAIL: two runs with the MCF template differ in the $method $name"; failures=$((failures + 1)); }
  done
done
# A profile key set for one run reaches the morph: without the coarse refit the shadowed lamb's
# coarse stage ends elsewhere than in the default run above. A bad setting is refused by name.
check "bench shapes --set" 0 "profile: set coarse.refit.rounds=0" \
  "$vbutcher" bench shapes --shapes lamb --lamb-pairs 1 --sigmas-mm 0 --variants shadow --no-png \
  --set coarse.refit.rounds=0 --csv "$work/no_refit.csv"
no_refit=$(column_of "$work/no_refit.csv" coarse mean_err_rel)
[ -n "$no_refit" ] && [ "$no_refit" != "$levelset" ] ||
  { echo "FAIL: with and without the refit the coarse errors were '$levelset' and '$no_refit'"; failures=$((failures + 1)); }
check "bench shapes refuses a key out of bounds" 2 "bench shapes: --set: coarse.refit.keep_fraction: 0.1 is outside \[0.5, 1\]" \
  "$vbutcher" bench shapes --set coarse.refit.keep_fraction=0.1 --csv "$work/x.csv"
check "bench refuses an unknown key" 2 "bench: --set: dense.nosuch: unknown key" \
  "$vbutcher" bench --set dense.nosuch=1 full --pairs 1 --sigmas-mm 0 --csv "$work/x.csv"
check "bench coarse refuses a key it does not read" 2 "bench: --set: dense.rounds: bench coarse runs the coarse stage alone" \
  "$vbutcher" bench coarse --pairs 1 --sigmas-mm 0 --set dense.rounds=2 --csv "$work/x.csv"
# A scan whose normals are all zero length (as the real lamb scan's are): they are dropped with
# a warning naming the file, estimated, and the full morph runs and reports its fit.
/usr/bin/python3 - "$work/set/target_001_cloud.ply" "$work/zero_normals.ply" <<'PY'
import sys
data = open(sys.argv[1], "rb").read()
head, body = data.split(b"end_header\n", 1)
count = int([l for l in head.decode().splitlines() if l.startswith("element vertex")][0].split()[2])
import struct
xyz = struct.unpack("<%dd" % (3 * count), body[:24 * count])
with open(sys.argv[2], "w") as out:
    out.write("ply\nformat ascii 1.0\nelement vertex %d\n" % count)
    out.write("".join("property float %s\n" % p for p in ("x", "y", "z", "nx", "ny", "nz")))
    out.write("end_header\n")
    for i in range(count):
        out.write("%.6f %.6f %.6f 0 0 0\n" % xyz[3 * i:3 * i + 3])
PY
check "morph drops a scan's zero-length normals, naming the file" 0 "zero_normals.ply: 20000 of 20000 normals are zero-length" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/zero_normals.ply" --out "$work/z.ply" \
  --stage full --annotations "$work/set/template_annotations.yaml"
check "morph --stage full reports the fit to the scan" 0 "morph: fit: scan to morph distance mean" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/zero_normals.ply" --out "$work/z.ply" \
  --stage full --annotations "$work/set/template_annotations.yaml"
# That scan is in metres: no warning about its units.
if grep -q "other units" <<<"$last_out"; then
  echo "FAIL: a scan in metres was warned about its units"; failures=$((failures + 1))
else
  echo "ok: a scan in metres is not warned about its units"
fi
# The same scan in millimetres: it morphs, with a warning that its lengths read as metres.
awk 'body { $1 *= 1000; $2 *= 1000; $3 *= 1000 } { print } /^end_header/ { body = 1 }' \
  "$work/zero_normals.ply" > "$work/millimetres.ply"
check "morph warns that a scan 1000 times a body's size is read as metres" 0 \
  "millimetres.ply is [0-9.]* m across, read in m:" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/millimetres.ply" --out "$work/mm.ply" \
  --stage coarse
grep -q -- "--target-units mm would read it as 1\.[0-9]* m" <<<"$last_out" ||
  { echo "FAIL: the units warning does not name --target-units mm"; failures=$((failures + 1)); }
# Told its units, the same scan morphs as the one in metres: no warning, the check reads the
# carcass's size, and the deformed template is written in millimetres, lying on the scan.
check "morph --target-units mm reads a scan in millimetres" 0 "confidence [0-9.]* (.*size [01]\.[0-9]*)" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/millimetres.ply" --out "$work/mm.ply" \
  --stage full --annotations "$work/set/template_annotations.yaml" --target-units mm
if grep -q "other units" <<<"$last_out"; then
  echo "FAIL: a scan whose units were given was warned about them"; failures=$((failures + 1))
fi
# The coarse stage alone writes back in the file's unit too.
check "morph --stage coarse of the scan in metres" 0 "coarse total" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/zero_normals.ply" --out "$work/zc.ply" \
  --stage coarse
check "morph --stage coarse --target-units mm" 0 "coarse total" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/millimetres.ply" --out "$work/mmc.ply" \
  --stage coarse --target-units mm
/usr/bin/python3 - "$work/mm.ply" "$work/z.ply" "$work/mmc.ply" "$work/zc.ply" <<'PY' || failures=$((failures + 1))
import sys
import numpy as np
def vertices(path):
    data = open(path, "rb").read()
    head, body = data.split(b"end_header\n", 1)
    lines = head.decode().splitlines()
    count = int([l for l in lines if l.startswith("element vertex")][0].split()[2])
    props = [l for l in lines if l.startswith("property double")]
    return np.frombuffer(body[:8 * len(props) * count], "<f8").reshape(count, len(props))[:, :3]
# Measured: 1.26e-6 m (full) and 1.5e-8 m (coarse), from the digits awk wrote the file with:
# the dense stage's discrete choices (which pairs it keeps) can turn that
# into a micrometre. A unit wrong anywhere would be millimetres or a factor of 1000.
for stage, mm_path, metres_path, most in (("full", sys.argv[1], sys.argv[2], 2e-6),
                                          ("coarse", sys.argv[3], sys.argv[4], 2.5e-8)):
    gap = np.abs(vertices(mm_path) / 1000 - vertices(metres_path)).max()
    if gap > most:
        sys.exit("FAIL: the %s morph of the scan in mm, in metres, is %.3g m from the one in metres" % (stage, gap))
    print("ok: the %s morph of the scan in mm is written in mm (%.3g m from the one in metres)" % (stage, gap))
PY
check "morph refuses an unknown unit" 2 "target-units" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/millimetres.ply" --out "$work/mm.ply" \
  --target-units km
# A hook apart from the carcass (300 points on a 4 cm ball 0.25 m above its top): left out,
# tried back with a second morph, and left out again; the morph line and the report say so.
/usr/bin/python3 - "$work/set/target_001_cloud.ply" "$work/hook.ply" <<'PY'
import math, struct, sys
data = open(sys.argv[1], "rb").read()
head, body = data.split(b"end_header\n", 1)
lines = head.decode().splitlines()
count = int([l for l in lines if l.startswith("element vertex")][0].split()[2])
stride = 8 * len([l for l in lines if l.startswith("property")])
pts = [struct.unpack("<3d", body[i * stride:i * stride + 24]) for i in range(count)]
top = max(pts, key=lambda p: p[2])
for i in range(300):
    z = 1 - 2 * (i + 0.5) / 300; r = math.sqrt(1 - z * z); a = 2.4 * i
    pts.append((top[0] + 0.04 * r * math.cos(a), top[1] + 0.04 * r * math.sin(a), top[2] + 0.25 + 0.04 * z))
with open(sys.argv[2], "w") as out:
    out.write("ply\nformat ascii 1.0\nelement vertex %d\n" % len(pts))
    out.write("property float x\nproperty float y\nproperty float z\nend_header\n")
    out.writelines("%.6f %.6f %.6f\n" % p for p in pts)
PY
check "morph tries a hook apart back and leaves it out" 0 \
  "the 300 points of the detached pieces tried back ([0-9.]* s): left out" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/hook.ply" --out "$work/h.ply" \
  --report "$work/hr.json"
/usr/bin/python3 - "$work/hr.json" <<'PY' || failures=$((failures + 1))
import json, sys
c = json.load(open(sys.argv[1]))["cleaning"]
got = (c["detached"], c["pieces_dropped"], c["tried_back"], c["rejoined"])
if got != (300, 1, 300, 0) or not c["tried_back_seconds"] > 0:
    sys.exit(f"FAIL: report cleaning {c}")
print("ok: the report says the hook was tried back and left out")
PY
# A cloud much denser than its noise: the morph reads and uses it at every n-th point.
check "synth writes a dense noisy cloud" 0 "template:" "$vbutcher" synth --out "$work/dense" --count 1 \
  --seed 5 --sigma-mm 16 --cloud --cloud-points 80000
check "morph uses a dense noisy cloud at every n-th point" 0 "one in [0-9]* of the points read used" \
  "$vbutcher" morph --template "$work/dense/template.ply" --target "$work/dense/target_000_cloud.ply" \
  --out "$work/d.ply" --stage full --report "$work/dr.json"
grep -Eq '"target_stride": ([2-9]|1[0-9])' "$work/dr.json" 2>/dev/null || { echo "FAIL: report lacks the stride"; failures=$((failures + 1)); }
# The report's density against the cloud's: 80,000 points over the template's area (the
# cloud covers the whole carcass), every stride-th read (more than 8 points per template
# vertex) and of those every stride-th used (the noise); and its noise in metres, as printed.
/usr/bin/python3 - "$work/dr.json" "$work/dense/template.ply" <<'PY' || failures=$((failures + 1))
import json, re, sys
import numpy as np
report = json.load(open(sys.argv[1]))
dense = report["dense"]
data = open(sys.argv[2], "rb").read()
head, _, body = data.partition(b"end_header\n")
head = head.decode()
nv = int(re.search(r"element vertex (\d+)", head).group(1))
nf = int(re.search(r"element face (\d+)", head).group(1))
props = re.findall(r"property (\w+) (\w+)\n", head.split("element face")[0])
vertex = np.dtype([(n, {"float": "<f4", "double": "<f8"}[t]) for t, n in props])
v = np.frombuffer(body[: nv * vertex.itemsize], dtype=vertex)
P = np.stack([v["x"], v["y"], v["z"]], 1).astype(float)
F = np.frombuffer(body[nv * vertex.itemsize :][: nf * 13], dtype=np.dtype([("n", "u1"), ("i", "<i4", 3)]))["i"]
area = np.linalg.norm(np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]]), axis=1).sum() / 2
if report["cleaning"]["read_stride"] < 2:  # 80,000 points, more than 8 per template vertex
    sys.exit(f"FAIL: cleaning read one point in {report['cleaning']['read_stride']}, want 2 or more")
if dense["target_stride"] < 2:  # and of those, the noise rule uses every n-th
    sys.exit(f"FAIL: the dense stage used one point in {dense['target_stride']}, want 2 or more")
want = 80000 / report["cleaning"]["read_stride"] / dense["target_stride"] / area
# Measured: 0.92 of it.
if abs(dense["density_per_m2"] / want - 1) > 0.12:
    sys.exit(f"FAIL: density {dense['density_per_m2']:.0f} per m2, want {want:.0f}")
if not 0 < dense["estimated_noise_m"] < 0.05:
    sys.exit(f"FAIL: noise {dense['estimated_noise_m']} m")
PY
check "morph --cuts needs --annotations" 2 "--annotations" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" --stage full --cuts "$work/x.json"
check "morph --cuts needs the full stage" 2 "--stage coarse" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" \
  --stage coarse --annotations "$work/set/template_annotations.yaml" --cuts "$work/x.json"
check "morph --annotations needs the full stage" 2 "--stage coarse" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" \
  --stage coarse --annotations "$work/set/template_annotations.yaml"
sed 's/^vertex_count: .*/vertex_count: 12/' "$work/set/template_annotations.yaml" >"$work/other.yaml"
check "morph refuses annotations of another mesh, naming the file" 2 "other.yaml" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" --stage full --annotations "$work/other.yaml"
check "morph refuses an open template, naming it" 2 "open.off" \
  "$vbutcher" morph --template "$work/open.off" --target "$work/set/target_000.ply" --out "$work/x.ply"
check "morph refuses an unknown stage" 2 "--stage" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" --stage fine
: > "$work/empty.xyz"
check "morph refuses an empty target" 2 "no points" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/empty.xyz" --out "$work/x.ply"
check "morph refuses a missing target" 2 "absent.ply" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/absent.ply" --out "$work/x.ply"

# template compile: the model computed once, stored with the annotations; morph --model uses it.
check "template compile writes a model" 0 "loads in" \
  "$vbutcher" template compile --template "$work/set/template.ply" --annotations "$work/set/template_annotations.yaml" -o "$work/t.vbt"
check "template info verifies it" 0 "checksums good" "$vbutcher" template info "$work/t.vbt"
check "template info lists the stored morph profile" 0 "coarse.articulation.target_keep_fraction" \
  "$vbutcher" template info "$work/t.vbt"
check "morph --model transfers the stored cuts" 0 "part shoulder" \
  "$vbutcher" morph --model "$work/t.vbt" --target "$work/set/target_001_cloud.ply" --out "$work/g.ply" --stage full --cuts "$work/g.json"
# The whole-morph check's size, read back from the cuts JSON: a lamb morphed in metres is
# about the template's size; the same template written in millimetres is warned of when
# compiled, and its morph of a cloud in metres sends nothing (every cut confidence 0).
/usr/bin/python3 - "$work/g.json" <<'PY' || failures=$((failures + 1))
import json, math, sys
check = json.load(open(sys.argv[1]))["check"]
if not (math.isfinite(check["size"]) and 0.5 < check["size"] < 2.0):
    sys.exit(f"FAIL: cuts JSON check.size {check['size']} is not near 1")
# The reach of a right morph of a cloud with 2 mm noise: the vertex spacing and the noise
# (measured 0.0069 of the template's size).
if not 0 < check["reach"] < 0.010:
    sys.exit(f"FAIL: cuts JSON check.reach {check['reach']} is not that of a right morph")
# What the noise and the vertex spacing explain of it: 2.6 noise levels and the template's
# mean edge over sqrt(3); a right morph reads within it (measured 0.0037 under it).
beyond = check["reach"] - check["reach_allowance"]
if not (check["noise"] > 0 and beyond < -0.0024):
    sys.exit(f"FAIL: cuts JSON check.reach {check['reach']} lies {beyond} beyond its allowance")
PY
/usr/bin/python3 - "$work/set/template.ply" "$work/template_mm.ply" <<'PY' || failures=$((failures + 1))
import struct, sys
data = open(sys.argv[1], "rb").read()
end = data.index(b"end_header\n") + len(b"end_header\n")
header = data[:end].decode()
assert "format binary_little_endian" in header, "FAIL: the template is not binary PLY"
props = [l.split()[-1] for l in header.split("element vertex")[1].split("element")[0].splitlines()
         if l.startswith("property")]
assert all(l.split()[1] == "double" for l in header.splitlines()
           if l.startswith("property") and "list" not in l), "FAIL: not doubles"
count = int(header.split("element vertex")[1].split()[0])
stride = 8 * len(props)
out = bytearray(data[:end])
for i in range(count):
    v = list(struct.unpack_from(f"<{len(props)}d", data, end + stride * i))
    for k, name in enumerate(props):
        if name in ("x", "y", "z"):
            v[k] *= 1000.0
    out += struct.pack(f"<{len(props)}d", *v)
out += data[end + stride * count:]
open(sys.argv[2], "wb").write(out)
PY
check "template compile warns of a template in millimetres" 0 \
  "template_mm.ply is 1[0-9]* across, read as metres: is it in other units?" \
  "$vbutcher" template compile --template "$work/template_mm.ply" --annotations "$work/set/template_annotations.yaml" -o "$work/mm.vbt"
check "a morph 1000 times smaller than its template is not trusted" 0 \
  "confidence 0.00 (.*): the morph is 0.00[0-9]* times the template's size" \
  "$vbutcher" morph --model "$work/mm.vbt" --target "$work/set/target_001_cloud.ply" --out "$work/mm.ply" --stage full --cuts "$work/mm.json"
/usr/bin/python3 - "$work/mm.json" <<'PY' || failures=$((failures + 1))
import json, sys
report = json.load(open(sys.argv[1]))
if report["check"]["confidence"] != 0 or any(c["confidence"] != 0 for c in report["cuts"]):
    sys.exit("FAIL: a morph in other units left a cut with confidence above 0")
PY
head -c 2000 "$work/t.vbt" >"$work/cut.vbt"
check "a truncated model is refused, naming the file" 2 "cut.vbt: checksum mismatch" "$vbutcher" template info "$work/cut.vbt"
check "morph refuses a truncated model" 2 "cut.vbt" \
  "$vbutcher" morph --model "$work/cut.vbt" --target "$work/set/target_000.ply" --out "$work/x.ply"
check "morph wants --template or --model" 2 "either --template or --model" \
  "$vbutcher" morph --target "$work/set/target_000.ply" --out "$work/x.ply"
check "template compile refuses annotations of another mesh" 2 "other.yaml" \
  "$vbutcher" template compile --template "$work/set/template.ply" --annotations "$work/other.yaml" -o "$work/x.vbt"

# A modelled mesh (assimp's spider: 19 open pieces, few vertices on its large faces, many on
# its details) is no template: the refusal names the command that wraps one closed surface
# around it, and the wrap is one. As a target, such a mesh is read as its surface, sampled
# uniformly, not as its vertices: the wrap then morphs onto it as it is. Measured: size 0.993,
# confidence 0.95; read as its 762 vertices, size 0.26 and confidence 0.
spider=/usr/share/assimp/models/OBJ/spider.obj
check "morph names the wrap for a template that is not one closed surface" 2 \
  "19 component(s).*vbutcher template wrap --mesh '$spider'" \
  "$vbutcher" morph --template "$spider" --target "$spider" --out "$work/x.ply"
check "template wrap makes one closed surface" 0 "wrote $work/spider.ply: one closed surface" \
  "$vbutcher" template wrap --mesh "$spider" -o "$work/spider.ply"
grep -q "the input's vertices lie [0-9.]* from the wrap on average" <<<"$last_out" ||
  { echo "FAIL: template wrap does not say how far the input lies from it"; failures=$((failures + 1)); }
check "morph reads an unevenly meshed target as its surface" 0 \
  "spider.obj is read as its surface (meshed unevenly; vertex areas spread [0-9.]* times, over 6 is uneven): 20000 points" \
  "$vbutcher" morph --template "$work/spider.ply" --target "$spider" --out "$work/x.ply" --stage full
check_line=$(grep -oE "morph: check: confidence [0-9.]+ .*size [0-9.]+\)" <<<"$last_out")
if awk -v l="$check_line" 'BEGIN { n = split(l, w, " "); size = w[n] + 0
                                  exit !(size > 0.985 && size < 1.015 && w[4] + 0 >= 0.9) }'; then
  echo "ok: the wrapped spider morphs onto the spider ($check_line)"
else
  echo "FAIL: the wrapped spider onto the spider: '$check_line' (measured size 0.993, confidence 0.95)"
  failures=$((failures + 1))
fi
# An evenly meshed target (the synthetic lamb's noisy mesh) is read as its vertices, unless
# the command says otherwise.
check "morph reads an evenly meshed target as its vertices" 0 "coarse total" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" \
  --stage coarse
if grep -q "read as its surface" <<<"$last_out"; then
  echo "FAIL: an evenly meshed target was read as its surface"; failures=$((failures + 1))
fi
check "morph --mesh-target surface samples it" 0 "target_000.ply is read as its surface (--mesh-target surface" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" \
  --stage coarse --mesh-target surface
check "morph --mesh-target takes auto, vertices or surface" nonzero "--mesh-target" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" \
  --mesh-target faces
# A ring wrapped is one closed surface with a handle: written, and said of when wrapped and
# when morphed; the synthetic lamb has none.
awk 'BEGIN { R = 1; r = 0.3; na = 32; nc = 16; pi = atan2(0, -1)
  print "OFF"; print na * nc, 2 * na * nc, 0
  for (i = 0; i < na; i++) for (j = 0; j < nc; j++)
    printf "%.6f %.6f %.6f\n", (R + r * cos(2 * pi * j / nc)) * cos(2 * pi * i / na),
      (R + r * cos(2 * pi * j / nc)) * sin(2 * pi * i / na), r * sin(2 * pi * j / nc)
  for (i = 0; i < na; i++) for (j = 0; j < nc; j++) {
    a = i * nc + j; b = ((i + 1) % na) * nc + j; c = ((i + 1) % na) * nc + (j + 1) % nc; d = i * nc + (j + 1) % nc
    print 3, a, b, c; print 3, a, c, d } }' > "$work/ring.off"
check "template wrap says a wrap has a handle" 0 "ring.ply has 1 handle (Euler characteristic 0)" \
  "$vbutcher" template wrap --mesh "$work/ring.off" -o "$work/ring.ply"
check "morph says its template has a handle" 0 "morph: warning: .*ring.ply has 1 handle" \
  "$vbutcher" morph --template "$work/ring.ply" --target "$work/ring.off" --out "$work/x.ply" --stage coarse
check "a template without handles is not warned of" 0 "coarse total" \
  "$vbutcher" morph --template "$work/set/template.ply" --target "$work/set/target_000.ply" --out "$work/x.ply" \
  --stage coarse
if grep -q "handle" <<<"$last_out"; then
  echo "FAIL: the synthetic lamb's template was said to have handles"; failures=$((failures + 1))
fi
# Pieces farther apart than alpha stay apart: not a template, and nothing is written.
printf 'OFF\n8 8 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n100 0 0\n101 0 0\n100 1 0\n100 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n3 4 6 5\n3 4 5 7\n3 4 7 6\n3 5 6 7\n' \
  > "$work/apart.off"
check "template wrap refuses pieces it cannot join" 3 "2 component(s).*larger --alpha" \
  "$vbutcher" template wrap --mesh "$work/apart.off" -o "$work/apart_wrap.ply"
[ ! -e "$work/apart_wrap.ply" ] || { echo "FAIL: a wrap in two pieces was written"; failures=$((failures + 1)); }
check "template wrap refuses a cloud format before wrapping" 2 "cannot hold faces" \
  "$vbutcher" template wrap --mesh "$spider" -o "$work/spider.xyz"
check "template wrap refuses a missing folder before wrapping" 2 "does not exist" \
  "$vbutcher" template wrap --mesh "$spider" -o "$work/absent/spider.ply"
check "template wrap bounds alpha" nonzero "--alpha" \
  "$vbutcher" template wrap --mesh "$spider" -o "$work/x.ply" --alpha 0.0001

# The virtual OpenNI2 rig: capture one frame set, fuse it; record and play back.
check "virtual-rig writes a rig" 0 "VB_VIRTUAL_SCENE" "$vbutcher" virtual-rig --out "$work/rig" --cameras 3
check "capture fuses the rig's frames" 0 "wrote" \
  "$vbutcher" capture --rig "$work/rig/rig.yaml" --scene "$work/rig/scene.yaml" --out "$work/fused.ply"
[ -s "$work/fused.ply" ] || { echo "FAIL: capture wrote no cloud"; failures=$((failures + 1)); }
# A rig that sees the carcass from one side only: the morph places the hidden half from the
# template alone, and the cuts' coverage must keep them under the daemon's job.min_confidence
# (0.6), so that the saw would get no waypoints; two cameras must clear it. Measured, the
# lowest cut confidence: with one camera 0.45 to 0.53 (virtual rigs of seeds 1 to 5), with
# two 0.87 to 0.94 (seeds 1, 2, 4, 5). A seed's captures are the same frames every run.
for cameras in 1 2; do
  check "virtual-rig writes a $cameras-camera rig" 0 "VB_VIRTUAL_SCENE" \
    "$vbutcher" virtual-rig --out "$work/rig$cameras" --cameras "$cameras" --seed 1
  check "capture fuses $cameras camera(s)" 0 "wrote" "$vbutcher" capture --rig "$work/rig$cameras/rig.yaml" \
    --scene "$work/rig$cameras/scene.yaml" --out "$work/fused$cameras.ply"
  check "morph of $cameras camera(s)' cloud" 0 "part shoulder" \
    "$vbutcher" morph --model "$work/t.vbt" --target "$work/fused$cameras.ply" --out "$work/view$cameras.ply" \
    --template-up 0 0 1 --target-up 0 0 1 --cuts "$work/view$cameras.json"
done
/usr/bin/python3 - "$work/view1.json" "$work/view2.json" <<'PY' || failures=$((failures + 1))
import json, sys
one, two = (min(c["confidence"] for c in json.load(open(f))["cuts"]) for f in sys.argv[1:])
print(f"lowest cut confidence: one camera {one:.2f}, two cameras {two:.2f}")
if not (0.4 <= one < 0.6):
    sys.exit(f"FAIL: one camera's lowest cut confidence {one:.2f} is not in [0.4, 0.6)")
if not two >= 0.6:
    sys.exit(f"FAIL: two cameras' lowest cut confidence {two:.2f} is under 0.6")
print("ok: one camera's cuts are not trusted, two cameras' are")
PY
check "record writes .oni files and a playback rig" 0 "playback calibration" \
  "$vbutcher" record --rig "$work/rig/rig.yaml" --scene "$work/rig/scene.yaml" --out "$work/rec" --seconds 0.5
check "record refuses a grace out of range before recording" 2 "grace-seconds must be in" \
  "$vbutcher" record --rig "$work/rig/rig.yaml" --scene "$work/rig/scene.yaml" --out "$work/rec" --grace-seconds 0.5
check "capture plays the recording back" 0 "wrote" \
  "$vbutcher" capture --rig "$work/rec/rig.yaml" --out "$work/replayed.ply"
check "cameras opens each recording of a playback rig" 0 "a recording" \
  "$vbutcher" cameras --rig "$work/rec/rig.yaml"
grep -q "depth stream 640x480 30 fps depth 1 mm, [0-9]* frames recorded" <<<"$last_out" ||
  { echo "FAIL: cameras gave no recorded mode and frames"; failures=$((failures + 1)); }
sed 's/resolution: \[640, 480\]/resolution: [320, 240]/' "$work/rec/rig.yaml" >"$work/rec/small.yaml"
check "cameras says a recording's resolution differs from its calibration" 3 "MISMATCH: the calibration says 320x240" \
  "$vbutcher" cameras --rig "$work/rec/small.yaml"
check "cameras --uri gives a recording's rig entry with intrinsics from its field of view" 0 \
  "intrinsics: {fx: 570.30, fy: 570.30, cx: 319.5, cy: 239.5}" \
  "$vbutcher" cameras --uri "$(ls "$work"/rec/*.oni | head -1)"
sed 's/fx: [0-9.]*/fx: -1/' "$work/rig/rig.yaml" >"$work/badrig.yaml"
check "capture refuses a bad calibration, naming file and key" 2 "badrig.yaml:.*intrinsics.fx" \
  "$vbutcher" capture --rig "$work/badrig.yaml" --out "$work/x.ply"
sed 's/^fps: .*/fps: 0/' "$work/rig/scene.yaml" >"$work/rig/badscene.yaml"
check "capture refuses a bad scene, naming file and key" 2 "badscene.yaml:.*fps" \
  "$vbutcher" capture --rig "$work/rig/rig.yaml" --scene "$work/rig/badscene.yaml" --out "$work/x.ply"

# Bring-up on the virtual rig: list the cameras, hang the sphere target, capture it, solve
# the cameras' poses, check the rig, calibrate the saw from paired points.
check "cameras lists each device with its rig entry" 0 "serial VB0002, USB 0000:0000" \
  "$vbutcher" cameras --rig "$work/rig/rig.yaml" --scene "$work/rig/scene.yaml"
"$vbutcher" virtual-rig --out "$work/rig4" --cameras 4 >/dev/null
check "cameras names a rig entry with no device" 3 "rig entry cam3 (serial VB0004, URI vbrig://VB0004): no device" \
  "$vbutcher" cameras --rig "$work/rig4/rig.yaml" --scene "$work/rig/scene.yaml"
check "calibrate target writes the target and its mesh" 0 "sphere 2: radius 60.0 mm" \
  "$vbutcher" calibrate target --out "$work/target.yaml" --mesh "$work/target.ply"
sed "s|^carcass: .*|carcass: $work/target.ply|" "$work/rig/scene.yaml" >"$work/rig/target_scene.yaml"
check "calibrate capture averages a view per camera" 0 "cam2 (VB0003): [0-9]* points, 10 frames averaged" \
  "$vbutcher" calibrate capture --rig "$work/rig/rig.yaml" --scene "$work/rig/target_scene.yaml" --out "$work/pos1"
check "calibrate rig solves the cameras from the target" 0 "wrote $work/calibrated.yaml" \
  "$vbutcher" calibrate rig --rig "$work/rig/rig.yaml" --captures "$work/pos1" --target "$work/target.yaml" \
  --out "$work/calibrated.yaml"
check "check-rig finds the calibrated rig consistent" 0 "rig ok" \
  "$vbutcher" check-rig --rig "$work/calibrated.yaml" --scene "$work/rig/target_scene.yaml"
# cam1 said to stand 10 mm further along x than it does.
awk '/translation: \[/ && ++n == 2 { match($0, /\[[-0-9.e]*/); x = substr($0, RSTART + 1, RLENGTH - 1);
       $0 = substr($0, 1, RSTART) sprintf("%.17g", x + 0.010) substr($0, RSTART + RLENGTH) } 1' \
  "$work/calibrated.yaml" >"$work/moved.yaml"
check "check-rig flags the camera that moved" 3 "| cam1 | VB0002 | 3 | [0-9.]* | [0-9.]* | MOVED: recalibrate |" \
  "$vbutcher" check-rig --rig "$work/moved.yaml" --scene "$work/rig/target_scene.yaml"
cat >"$work/saw_points.yaml" <<'YAML'
format: vbutcher-saw-points
version: 1
ball_radius_m: 0.04
points:                         # saw = rig turned 90 degrees about z, then moved (1, 2, 0.5)
  - {saw: [1.0, 2.1, 0.2], rig: [0.1, 0.0, -0.3]}
  - {saw: [1.2, 2.0, -0.1], rig: [0.0, -0.2, -0.6]}
  - {saw: [0.9, 1.7, -0.4], rig: [-0.3, 0.1, -0.9]}
  - {saw: [0.75, 2.25, 0.0], rig: [0.25, 0.25, -0.5]}
YAML
check "calibrate saw solves X_SawRig from paired points" 0 "rms 0.00 mm" \
  "$vbutcher" calibrate saw --rig "$work/calibrated.yaml" --points "$work/saw_points.yaml" --out "$work/saw.yaml"
grep -q "rotation_wxyz: \[0.7071067811865" "$work/saw.yaml" ||
  { echo "FAIL: calibrate saw wrote $(cat "$work/saw.yaml")"; failures=$((failures + 1)); }
sed 's/translation: \[1/translation: [1.01/' "$work/saw.yaml" >"$work/saw_moved.yaml"
check "calibrate saw --check says when X_SawRig no longer holds" 3 "no longer holds" \
  "$vbutcher" calibrate saw --rig "$work/calibrated.yaml" --points "$work/saw_points.yaml" --check "$work/saw_moved.yaml"

# bench --start-from-truth: the dense stage's start, fitted to the true surface, carries the
# cuts to within a millimetre by their lines' planes (what the dense stage then does is the
# measurement).
check "bench full starts from the truth" 0 "sigma 0: started from the truth at cut dist 0\.[0-9]* mm" \
  "$vbutcher" bench full --pairs 1 --sigmas-mm 0 --start-from-truth --csv "$work/bench.csv"
[ -s "$work/bench.csv" ] || { echo "FAIL: bench wrote no CSV"; failures=$((failures + 1)); }
check "bench refuses a pose scale beyond 4" 2 "pose-scale" \
  "$vbutcher" bench full --pairs 1 --sigmas-mm 0 --pose-scale 5
check "bench refuses too few cloud points" nonzero "cloud-points" \
  "$vbutcher" bench full --pairs 1 --cloud-points 5
# A --shapes mesh that cannot be read stops the bench before its first morph, naming the file.
printf 'OFF\n3 1 0\n0 0 0\n' > "$work/short.off"
for stage in coarse full; do
  check "bench $stage refuses an unreadable shape" 2 "bench: --shapes $work/short.off: .*counts 3 vertices" \
    "$vbutcher" bench "$stage" --pairs 1 --sigmas-mm 0 --shapes "$work/short.off" --csv "$work/refused.csv"
done
[ ! -e "$work/refused.csv" ] || { echo "FAIL: a refused bench wrote a CSV"; failures=$((failures + 1)); }

# bench inputs, its files at a thousandth of the limits: every reader reads or refuses its
# file (none fails otherwise), one CSV row per read.
check "bench inputs reads each parser's file" 0 "| oni_records | .* | read 1,000 frames walked |" \
  "$vbutcher" bench inputs --scale 0.001 --repeats 1 --csv "$work/inputs.csv"
rows=$(($(wc -l <"$work/inputs.csv") - 1))
[ "$rows" -eq 16 ] || { echo "FAIL: bench inputs wrote $rows rows, not 16"; failures=$((failures + 1)); }

echo "$failures failed"
[ "$failures" -eq 0 ]
