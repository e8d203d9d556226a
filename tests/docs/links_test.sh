#!/usr/bin/env bash
# The documentation's own checks:
#  1. every relative link in README.md, docs/**/*.md, config/*.md and systemd/*.md resolves to
#     a file or folder inside the repository (and, for a link to a heading of a markdown file,
#     to a heading that exists there);
#  2. README.md stays a user's README: at most 20,000 bytes, no commit hashes, no dates;
#  3. docs/benchmarks.md is what scripts/benchmarks-doc makes of docs/bench/*.csv.
# Prints every problem and exits 1 when there is one.
# Usage: links_test.sh [repository root]   (default: two folders up from this script)
set -euo pipefail
root=$(realpath "${1:-$(dirname "$0")/../..}")
status=0
/usr/bin/python3 - "$root" <<'PY' || status=1
import os, re, sys, glob

root = sys.argv[1]
files = [os.path.join(root, "README.md")]
files += sorted(glob.glob(os.path.join(root, "docs", "**", "*.md"), recursive=True))
files += sorted(glob.glob(os.path.join(root, "config", "*.md")))
files += sorted(glob.glob(os.path.join(root, "systemd", "*.md")))

INLINE = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*(<[^>]*>|[^()\s]*(?:\([^()]*\)[^()\s]*)*)(?:\s+\"[^\"]*\")?\s*\)")
REFDEF = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*(\S+)")
SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def slug(heading, seen):
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"`([^`]*)`", r"\1", heading.strip())
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", text)
    s = re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")
    n = seen.get(s, 0)
    seen[s] = n + 1
    return s if n == 0 else "%s-%d" % (s, n)


anchors_of = {}


def anchors(path):
    if path not in anchors_of:
        seen, out, fence = {}, set(), False
        for line in open(path, encoding="utf-8"):
            if line.lstrip().startswith("```"):
                fence = not fence
                continue
            m = None if fence else re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
            if m:
                out.add(slug(m.group(1), seen))
        anchors_of[path] = out
    return anchors_of[path]


def links(path):
    fence = False
    for number, line in enumerate(open(path, encoding="utf-8"), 1):
        if line.lstrip().startswith("```"):
            fence = not fence
            continue
        if fence:
            continue
        text = re.sub(r"`[^`]*`", "", line)  # code spans are not links
        for m in INLINE.finditer(text):
            yield number, m.group(1).strip("<>")
        m = REFDEF.match(text)
        if m:
            yield number, m.group(1).strip("<>")


broken = 0
checked = 0
for path in files:
    if not os.path.exists(path):
        continue
    rel = os.path.relpath(path, root)
    for number, target in links(path):
        if not target or SCHEME.match(target):
            continue  # http(s), mailto, file: links are not the repository's
        checked += 1
        target_path, _, anchor = target.partition("#")
        if target_path:
            resolved = os.path.realpath(os.path.join(os.path.dirname(path), target_path))
        else:
            resolved = os.path.realpath(path)
        problem = None
        if os.path.commonpath([resolved, root]) != root:
            problem = "points outside the repository"
        elif not os.path.exists(resolved):
            problem = "no such file"
        elif anchor and resolved.endswith(".md") and os.path.isfile(resolved):
            if anchor.lower() not in anchors(resolved):
                problem = "no heading #%s in %s" % (anchor, os.path.relpath(resolved, root))
        if problem:
            broken += 1
            print("BROKEN %s:%d: (%s): %s" % (rel, number, target, problem))
print("links: %d relative links checked in %d files, %d broken" % (checked, len(files), broken))

readme = os.path.join(root, "README.md")
text = open(readme, encoding="utf-8").read()
size = len(text.encode("utf-8"))
if size > 20000:
    broken += 1
    print("README.md is %d bytes, over 20,000: move the detail into docs/" % size)
for m in re.finditer(r"\b(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b", text):
    broken += 1
    print("README.md holds what looks like a commit hash: %s (history goes to docs/decisions.md)" % m.group(0))
for m in re.finditer(r"\b(19|20)\d\d-[01]\d-[0-3]\d\b", text):
    broken += 1
    print("README.md holds a date: %s (dated runs go to docs/decisions.md or docs/benchmarks.md)" % m.group(0))
sys.exit(1 if broken else 0)
PY
if [ -x "$root/scripts/benchmarks-doc" ]; then
  /usr/bin/python3 "$root/scripts/benchmarks-doc" --check || status=1
fi
exit $status
