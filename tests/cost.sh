#!/usr/bin/env bash
# bench/cost.py on the line sample: a row per planner; `vpop` spends nothing in the look-ahead's
# parts (it has no profile) and the look-ahead something in each, each part within the whole
# planning; both planners write the same number of setpoints within two (each plans the
# jerk-limited straight move); --update rewrites the cost block of a Markdown file and keeps
# what is around it; a dtis stripped of its symbols is refused with a message that says so.
# Skipped (77) where valgrind is not installed.
set -euo pipefail
dtis=$1
root=$2
command -v valgrind >/dev/null || { echo "valgrind not installed: skipped"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf 'before\n<!-- cost:begin -->\nold\n<!-- cost:end -->\nafter\n' >"$tmp/doc.md"
out=$(/usr/bin/python3 "$root/bench/cost.py" --dtis "$dtis" --update "$tmp/doc.md" \
  "$root/samples/jobs/line.toml")
echo "$out"
echo "$out" | /usr/bin/python3 -c '
import sys
rows = {}
for line in sys.stdin:
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    if len(cells) == 8 and cells[0] == "`line.toml`":
        rows[cells[1]] = [float(c.replace(" ", "")) for c in cells[2:]]
if set(rows) != {"vpop", "lookahead"}:
    sys.exit(f"FAIL: rows for {sorted(rows)}, not vpop and lookahead")
n_v, plan_v, flows_v, cap_v, release_v, _ = rows["vpop"]
n_l, plan_l, flows_l, cap_l, release_l, _ = rows["lookahead"]
if (flows_v, cap_v, release_v) != (0, 0, 0):
    sys.exit("FAIL: vpop has look-ahead parts: " + str(rows["vpop"]))
if not (plan_v > 0 and 0 < flows_l < plan_l and 0 < cap_l < plan_l and 0 < release_l < plan_l):
    sys.exit("FAIL: the parts do not lie within the planning: " + str(rows["lookahead"]))
if abs(n_v - n_l) > 2:
    sys.exit(f"FAIL: {n_v} setpoints with vpop, {n_l} with lookahead")
'
doc=$(cat "$tmp/doc.md")
if [ "$(head -1 <<<"$doc")" != before ] || [ "$(tail -1 <<<"$doc")" != after ] ||
  grep -q '^old$' <<<"$doc" || ! grep -q '`line.toml` | lookahead' <<<"$doc"; then
  echo "FAIL: --update did not replace the block alone:" >&2
  echo "$doc" >&2
  exit 1
fi
strip -o "$tmp/stripped" "$dtis"
if err=$(/usr/bin/python3 "$root/bench/cost.py" --dtis "$tmp/stripped" --planner vpop \
  "$root/samples/jobs/line.toml" 2>&1); then
  echo "FAIL: a stripped dtis was measured" >&2
  exit 1
fi
grep -q "stripped" <<<"$err" || {
  echo "FAIL: the stripped dtis' error does not say so: $err" >&2
  exit 1
}
echo "cost.py: ok"
