#!/usr/bin/env bash
# A small `vbutcher bench shapes`: one humanoid, one creature and the lamb, one pair each, two
# noise levels, the three variants. Reads back what it wrote: the CSV's columns and rows, the
# camera shadow's and the clutter's shares, each family's full-morph error against its
# measured value, clutter against clean, the example morphs, each exported morph read back
# against its row, and the PNG as an image. Then a humanoid whose pose changed far, placed the
# right way round; a creature's foreleg swung about a point out along its limb; a leg the dense
# stage keeps where the posture fit turned it; a fore leg turned onto the target fore leg the
# posture fit left bare; and the lamb in wider poses (--lamb-pose-scale); a limb's end a shadow
# cut off, put back (--variants severed); a floor the body rests on, left out (--variants
# floor); what two cameras, then one, see (--variants views); and two exported files of one
# name refused. Also the placements the coarse stage's choice compared, as the CSV gives them.
set -euo pipefail
vbutcher=$1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$vbutcher" bench shapes --shapes sydney,spiderblob,lamb --max-pairs 1 --lamb-pairs 1 \
  --sigmas-mm 0,16 --variants clean,shadow,clutter --csv "$work/shapes.csv" --export "$work/ply" \
  > "$work/out.txt" 2> "$work/progress.txt"
grep -q '^| lamb | lamb | shadow | 16 |' "$work/out.txt" || { echo "FAIL: no table row"; cat "$work/out.txt"; exit 1; }
grep -q '^\[18/18 ' "$work/progress.txt" || {
  echo "FAIL: no progress lines"; cat "$work/progress.txt"; exit 1; }
PYTHONDONTWRITEBYTECODE=1 /usr/bin/python3 - "$work/shapes.csv" "$work/shapes.png" "$work/shapes_examples" "$work/ply" \
  "$(dirname "$0")/../../scripts" <<'PY'
import csv, sys
from pathlib import Path
rows = list(csv.DictReader(open(sys.argv[1])))
fail = []
need = "shape,source,pair,sigma_mm,variant,method,mean_err_rel,max_err_rel,seconds".split(",")
missing = [c for c in need if c not in rows[0]]
if missing: fail.append(f"columns missing: {missing}")
if len(rows) != 3 * 2 * 3 * 4: fail.append(f"{len(rows)} rows, want 72")
by = {(r["shape"], r["sigma_mm"], r["variant"], r["method"]): r for r in rows}
for (shape, sigma, variant, method), r in by.items():
    if method in ("identity", "rigid_bound") and r["ok"] != "1": fail.append(f"{shape} {method} not ok")
    if method == "identity" and variant == "shadow":
        clean = int(by[(shape, sigma, "clean", "identity")]["points"])
        share = 1 - int(r["points"]) / clean
        if abs(share - 0.2) > 0.002: fail.append(f"{shape}: the shadow removed {share:.3f} of the points")
    if method == "identity" and variant == "clutter":
        clean = int(by[(shape, sigma, "clean", "identity")]["points"])
        share = int(r["points"]) / clean - 1
        if abs(share - 0.05) > 0.001: fail.append(f"{shape}: the clutter added {share:.3f} of the points")
    if not (r["source"] and r["pair"]): fail.append(f"{shape}: no source or pair")
# The coarse stage's and the full morph's mean error, clean, no noise, against what they
# measured with these pairs (bounds 1.5 times that): a regression guard per family (a
# humanoid, an eight-legged creature, the lamb), to tighten as the morph improves.
measured = {("lamb", "coarse"): 0.0155, ("sydney", "coarse"): 0.0307, ("spiderblob", "coarse"): 0.0136,
            ("lamb", "full"): 0.0051, ("sydney", "full"): 0.0162, ("spiderblob", "full"): 0.0097}
for (shape, method), value in measured.items():
    got = float(by[(shape, "0", "clean", method)]["mean_err_rel"])
    if not got < 1.5 * value:
        fail.append(f"{shape} {method} mean error {100 * got:.2f} % (measured {100 * value:.2f} %)")
# The placements the coarse stage's choice compared: at least one; none scored less than the
# chosen one; on the lamb the nearest to the truth is the chosen one, its rigid placement
# 1.71 degrees from the truth's best rotation (measured; bound 1.5 times that).
for (shape, sigma, variant, method), r in by.items():
    if method in ("coarse", "full") and r["ok"] == "1":
        if not (int(r["placements_compared"]) >= 1 and float(r["nearest_placement_score"]) >= 1.0):
            fail.append(f"{shape} {sigma} {variant} {method}: placements compared {r['placements_compared']}, "
                        f"the nearest scoring {r['nearest_placement_score']} of the chosen")
near = by[("lamb", "0", "clean", "coarse")]
if not (float(near["nearest_placement_deg"]) < 2.6 and float(near["nearest_placement_score"]) == 1.0):
    fail.append(f"lamb: nearest placement {near['nearest_placement_deg']} degrees from the truth, "
                f"scoring {near['nearest_placement_score']} of the chosen")
lamb = float(by[("lamb", "0", "clean", "full")]["mean_err_rel"])
# Stray points and a detached ball (5 % of the points) are left out before the morph: the full
# morph then errs about as on the clean cloud (measured: sydney 0.7 % more, spiderblob 1.7 %
# less, the lamb 0.3 % more).
for shape in ("sydney", "spiderblob", "lamb"):
    clean = float(by[(shape, "0", "clean", "full")]["mean_err_rel"])
    clutter = float(by[(shape, "0", "clutter", "full")]["mean_err_rel"])
    if not clutter < 1.1 * clean:
        fail.append(f"{shape}: full mean error {100 * clutter:.2f} % with clutter, {100 * clean:.2f} % clean")
for shape in ("sydney", "spiderblob", "lamb"):
    for part in ("target", "truth", "coarse", "full"):
        if not (Path(sys.argv[3]) / f"{shape}_{part}.xyz").stat().st_size: fail.append(f"empty {shape}_{part}.xyz")
# The export: per third-party shape its template, the rest and the one kept pose of its
# source; per pair its posed template in the model's frame and placed as the targets are; per
# morph (2 noise levels, 3 variants) the cloud and the coarse and full morphs. The lamb has no
# sources. Each a PLY whose header counts the vertices it holds.
exported = sorted(p.name for p in Path(sys.argv[4]).iterdir())
for shape, want in (("sydney", 23), ("spiderblob", 23), ("lamb", 21)):
    mine = [n for n in exported if n.startswith(shape + "_")]
    if len(mine) != want or f"{shape}_template.ply" not in mine:
        fail.append(f"{shape}: exported {len(mine)} files, want {want}: {mine}")
for name in exported:
    head = (Path(sys.argv[4]) / name).read_bytes()[:400]
    if not head.startswith(b"ply") or b"element vertex " not in head: fail.append(f"{name}: not a PLY")
# Each exported morph, read back against its placed truth, errs as its CSV row says (to the
# CSV's six significant digits); each cloud holds the points the row counts and, without noise
# and clutter, lies on the placed truth (every 100th point's nearest vertex, mean, within 1.5
# times the most measured, 0.53 % of the size; in the model's frame sydney's and the lamb's 27 to
# 43 %).
import numpy as np
sys.path.insert(0, sys.argv[5])
from vbply import read_vertices
def similarity_scale(a, b):  # of the least-squares similarity a -> b (Umeyama)
    a0, b0 = a - a.mean(0), b - b.mean(0)
    u, s, vt = np.linalg.svd(b0.T @ a0 / len(a))
    d = np.ones(3)
    d[2] = np.sign(np.linalg.det(u @ vt))
    return (s * d).sum() / (a0 ** 2).sum(1).mean()
folder, read_back, on_truth, truths = Path(sys.argv[4]), 0, 0.0, {}
for r in rows:
    if r["method"] not in ("coarse", "full"): continue
    stem = f"{r['shape']}_{r['pair']}_{float(r['sigma_mm']):g}mm_{r['variant']}"
    if r["ok"] != "1":
        fail.append(f"{stem} {r['method']}: failed")
        continue
    key = (r["shape"], r["pair"])
    if key not in truths:  # each pair's placed truth and size, read once
        rest = read_vertices(folder / f"{r['shape']}_template.ply")
        truth = read_vertices(folder / f"{r['shape']}_{r['pair']}_placed.ply")
        truths[key] = truth, np.linalg.norm(rest.max(0) - rest.min(0)) * similarity_scale(rest, truth)
    truth, size = truths[key]
    mean = np.linalg.norm(read_vertices(folder / f"{stem}_{r['method']}.ply") - truth, axis=1).mean() / size
    if not abs(mean / float(r["mean_err_rel"]) - 1) <= 6e-6:
        fail.append(f"{stem} {r['method']}: mean error {mean:.7f} read back, {r['mean_err_rel']} in the CSV")
    read_back += 1
    if r["method"] != "full": continue
    cloud = read_vertices(folder / f"{stem}_cloud.ply")
    if len(cloud) != int(r["points"]): fail.append(f"{stem}: the exported cloud does not hold {r['points']} points")
    if r["sigma_mm"] == "0" and r["variant"] != "clutter":
        some = cloud[::100]
        near = np.sqrt(((some[:, None, :] - truth[None, :, :]) ** 2).sum(2)).min(1).mean() / size
        on_truth = max(on_truth, near)
        if not near <= 0.008: fail.append(f"{stem}: the exported cloud lies {100 * near:.2f} % off its truth")
if read_back != 36: fail.append(f"{read_back} morphs read back, want 36")
import matplotlib.image
img = matplotlib.image.imread(sys.argv[2])
if img.shape[1] < 800 or img.shape[0] < 600: fail.append(f"picture is {img.shape}")
if fail:
    print("FAIL:", *fail, sep="\n  ")
    sys.exit(1)
print(f"ok: 72 rows, shadow 20 %, lamb full {100 * lamb:.2f} %, 36 exported morphs read back, "
      f"clouds within {100 * on_truth:.2f} % of their truth, "
      f"picture {img.shape[1]}x{img.shape[0]}")
PY
# A humanoid whose pose changed far (bcn t0-t9600, arms and legs turned): none of the placements
# from the skeletons or the principal axes is within 150 degrees of the truth; the best one
# turned half round about the template's long axis is (measured: placed 5 degrees off, coarse
# mean error 4.15 %; it was 178 degrees and 28.2 % before the turned candidates). Bound 1.5x.
"$vbutcher" bench shapes --shapes bcn --max-pairs 3 --lamb-pairs 0 --sigmas-mm 0 \
  --variants clean --no-png --csv "$work/bcn.csv" >/dev/null 2>&1
/usr/bin/python3 - "$work/bcn.csv" <<'PY'
import csv, sys
rows = {(r["pair"], r["method"]): r for r in csv.DictReader(open(sys.argv[1]))}
coarse = rows[("t0-t9600", "coarse")]
turned, mean = float(coarse["placement_err_deg"]), float(coarse["mean_err_rel"])
if not (turned < 90 and mean < 1.5 * 0.0415):
    print(f"FAIL: bcn t0-t9600 placed {turned:.0f} degrees off, coarse mean error {100 * mean:.2f} %")
    sys.exit(1)
print(f"ok: bcn t0-t9600 placed {turned:.0f} degrees off, coarse mean error {100 * mean:.2f} %")
PY
# A creature whose foreleg's branch starts on the spine (wuson run618-walk11520): the leg is
# swung about a point out along its branch, not only about that root (measured: full max
# error 4.62 % of the size; 14.2 % swung about the root alone). And a leg the posture fit
# turned, on a cloud at 16 mm (run618-run2474), which the dense stage keeps turned: E_reg holds
# the coarse pose's sharp bends (measured: full max 14.5 %; 32.5 % with E_reg pulling
# back to the rest shape). And a fore leg the posture fit laid on the other fore leg's target,
# leaving that target leg bare, turned onto it (run618-run2474 at 0 mm, ReclaimLimbs; measured:
# full max 4.96 %; 33.3 % without). Bounds 1.5x.
"$vbutcher" bench shapes --shapes wuson --lamb-pairs 0 --sigmas-mm 0,16 \
  --variants clean --no-png --csv "$work/wuson.csv" >/dev/null 2>&1
/usr/bin/python3 - "$work/wuson.csv" <<'PY'
import csv, sys
rows = {(r["pair"], r["sigma_mm"], r["method"]): r for r in csv.DictReader(open(sys.argv[1]))}
fail = []
for pair, sigma, measured in (("run618-walk11520", "0", 0.0462), ("run618-run2474", "16", 0.145),
                              ("run618-run2474", "0", 0.0496)):
    worst = float(rows[(pair, sigma, "full")]["max_err_rel"])
    if not worst < 1.5 * measured:
        fail.append(f"wuson {pair} at {sigma} mm: full max error {100 * worst:.2f} % (measured {100 * measured:.2f} %)")
    else:
        print(f"ok: wuson {pair} at {sigma} mm: full max error {100 * worst:.2f} %")
if fail:
    print("FAIL:", *fail, sep="\n  ")
    sys.exit(1)
PY
# The lamb in wider poses (--lamb-pose-scale): its pair labelled with the scale, and the same
# body turned further from the template than the line's pose of it (the first run's lamb); a
# scale past 4 is refused.
"$vbutcher" bench shapes --shapes lamb --lamb-pairs 1 --lamb-pose-scale 2.5 --sigmas-mm 0 \
  --variants clean --no-png --csv "$work/wide.csv" >/dev/null 2>&1
/usr/bin/python3 - "$work/shapes.csv" "$work/wide.csv" <<'PY'
import csv, sys
line = [r for r in csv.DictReader(open(sys.argv[1])) if r["shape"] == "lamb" and r["method"] == "full"]
wide = [r for r in csv.DictReader(open(sys.argv[2])) if r["method"] == "full"]
if len(wide) != 1 or wide[0]["pair"] != line[0]["pair"] + "-angles2.5x":
    print("FAIL: wide pairs", [r["pair"] for r in wide], "line", line[0]["pair"])
    sys.exit(1)
a, b = float(line[0]["pose_change_deg"]), float(wide[0]["pose_change_deg"])
if not b > 1.5 * a:
    print(f"FAIL: pose change {b:.1f} degrees at 2.5 times the ranges, {a:.1f} on the line")
    sys.exit(1)
print(f"ok: the lamb's pose change {a:.1f} -> {b:.1f} degrees")
PY
# Two variants not run by default, on one lamb pair, each read against the clean cloud:
# - severed (a limb's end cut off by a shadow band): some points gone, and the limb's end put
#   back by the morph, whose error is then near the clean cloud's (measured 0.575 % severed,
#   0.525 % clean; 0.700 % with the end left out, `clean.rejoin_detached` off);
# - floor (a floor the body rests on, in one piece with it): the floor's points added, and the
#   morph as good as on the clean cloud once the cleaning takes the plane out (measured: 94 %
#   more points; 0.551 %; 57.6 % with `clean.touching_planes` 0);
# - views (what depth cameras see): two cameras on opposite sides leave the sides they graze
#   and what one part hides of another (measured 15 % of the points gone, 0.602 %); one camera
#   leaves the far side to the template (58 % gone, 2.50 %: worse than two, and bounded).
"$vbutcher" bench shapes --shapes lamb --lamb-pairs 1 --sigmas-mm 4 \
  --variants clean,severed,floor,views --no-png --csv "$work/variants.csv" >/dev/null 2>&1
"$vbutcher" bench shapes --shapes lamb --lamb-pairs 1 --sigmas-mm 4 --variants views --views 1 \
  --no-png --csv "$work/one_view.csv" >/dev/null 2>&1
/usr/bin/python3 - "$work/variants.csv" "$work/one_view.csv" <<'PY'
import csv, sys
by = {(r["variant"], r["method"]): r for r in csv.DictReader(open(sys.argv[1]))}
by.update({("one view", r["method"]): r for r in csv.DictReader(open(sys.argv[2]))})
clean = int(by[("clean", "full")]["points"])
# variant: (lowest, highest) change in points against the clean cloud, error range
limits = {"severed": (-0.1, -0.005, 0, 0.0064), "floor": (0.6, 1.2, 0, 0.0065),
          "views": (-0.22, -0.10, 0, 0.0090), "one view": (-0.7, -0.45, 0.0167, 0.0375)}
failed = False
for variant, (low, high, least, limit) in limits.items():
    change = int(by[(variant, "full")]["points"]) / clean - 1
    err = float(by[(variant, "full")]["mean_err_rel"])
    ok = low < change < high and least <= err < limit
    failed |= not ok
    print(f"{'ok' if ok else 'FAIL'}: {variant}: {100 * change:+.1f} % points, "
          f"full mean error {100 * err:.3f} %")
sys.exit(1 if failed else 0)
PY
# A noisy floor (16 mm) under the lamb's third pair of seed 1 (rest-s1000005): the plane search
# reads a refit's deviation from the median distance, so the lamb's touching cap in the band
# does not widen it into a "curved surface" and the floor goes (measured: full mean error
# 1.29 %; 16.7 % from the root mean square, with confidence 0.60). Bound 1.5x.
"$vbutcher" bench shapes --shapes lamb --lamb-pairs 3 --sigmas-mm 16 --variants floor \
  --no-png --csv "$work/floor16.csv" >/dev/null 2>&1
/usr/bin/python3 - "$work/floor16.csv" <<'PY'
import csv, sys
rows = {(r["pair"], r["method"]): r for r in csv.DictReader(open(sys.argv[1]))}
err = float(rows[("rest-s1000005", "full")]["mean_err_rel"])
ok = err < 1.5 * 0.0129
print(f"{'ok' if ok else 'FAIL'}: a 16 mm floor under rest-s1000005: full mean error {100 * err:.2f} %")
sys.exit(0 if ok else 1)
PY
status=0
"$vbutcher" bench shapes --shapes lamb --lamb-pose-scale 5 --csv "$work/no.csv" >/dev/null 2>&1 || status=$?
[ "$status" -eq 2 ] || { echo "FAIL: --lamb-pose-scale 5 exited $status, not 2"; exit 1; }
status=0
"$vbutcher" bench shapes --shapes lamb --views 9 --csv "$work/no.csv" >/dev/null 2>&1 || status=$?
[ "$status" -eq 2 ] || { echo "FAIL: --views 9 exited $status, not 2"; exit 1; }
# Two exported files of one run with the same name are refused before any morph (here two noise
# levels alike to 6 digits; a shape's name or a pose's label holding '_' can do the same).
status=0
"$vbutcher" bench shapes --shapes lamb --lamb-pairs 1 --sigmas-mm 4,4.0000001 --variants clean \
  --no-png --csv "$work/twice.csv" --export "$work/twice" > /dev/null 2> "$work/twice.txt" || status=$?
[ "$status" -eq 2 ] && grep -q "would both be written as lamb_.*_4mm_clean_cloud.ply" "$work/twice.txt" &&
  ! grep -q '^\[1/' "$work/twice.txt" && [ ! -e "$work/twice" ] || {
  echo "FAIL: two noise levels of one file name with --export exited $status:"; cat "$work/twice.txt"; exit 1; }
echo "ok: the refusals (--lamb-pose-scale 5, --views 9, two exports of one name)"
