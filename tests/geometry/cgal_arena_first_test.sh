#!/usr/bin/env bash
# Every source file that includes a CGAL header includes geometry/cgal_arena.h before it, so
# that CGAL_ALLOCATOR is the same type in every translation unit (one definition rule) and
# CGAL's containers can draw from an arena (geometry/cgal_arena.h). Including it after a CGAL
# header does not compile; this check catches a file that leaves it out.
# First checks itself on two made-up files (one right, one wrong), then the repository.
# Prints every file at fault and exits 1 when there is one.
# Usage: cgal_arena_first_test.sh [repository root]   (default: two folders up)
set -euo pipefail
root=$(realpath "${1:-$(dirname "$0")/../..}")

# check DIR: the C++ files under DIR (git's list when DIR is a work tree) that include
# <CGAL/...> without including "geometry/cgal_arena.h" on an earlier line.
check() {
  /usr/bin/python3 - "$1" <<'PY'
import os, re, subprocess, sys

root = sys.argv[1]
try:
    listed = subprocess.run(["git", "-C", root, "ls-files", "-z"], check=True,
                            capture_output=True).stdout.decode().split("\0")
except (OSError, subprocess.CalledProcessError):
    listed = [os.path.relpath(os.path.join(d, f), root)
              for d, _, fs in os.walk(root) for f in fs]
sources = sorted(f for f in listed if re.search(r"\.(cc|cpp|h|hpp)$", f))
include = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')
bad = 0
for name in sources:
    arena_line = None
    with open(os.path.join(root, name), encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            m = include.match(line)
            if not m:
                continue
            if m.group(1) == '"' and m.group(2) == "geometry/cgal_arena.h":
                arena_line = number
            elif m.group(1) == "<" and m.group(2).startswith("CGAL/") and arena_line is None:
                print(f"{name}:{number}: includes <{m.group(2)}> before "
                      '"geometry/cgal_arena.h" (include it first)')
                bad += 1
                break
print(f"{len(sources)} files read, {bad} at fault")
sys.exit(1 if bad else 0)
PY
}

scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
mkdir -p "$scratch/right" "$scratch/wrong"
printf '#include "a.h"\n#include "geometry/cgal_arena.h"\n#include <CGAL/Surface_mesh.h>\n' \
  > "$scratch/right/a.cc"
printf '#include <vector>\n#include <CGAL/Surface_mesh.h>\n#include "geometry/cgal_arena.h"\n' \
  > "$scratch/wrong/b.cc"
check "$scratch/right" > /dev/null || { echo "self-check: a right file was refused"; exit 1; }
if check "$scratch/wrong" > /dev/null; then
  echo "self-check: a file including CGAL first was passed"
  exit 1
fi
check "$root"
