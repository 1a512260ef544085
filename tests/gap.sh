#!/usr/bin/env bash
# bench/gap.py on the trident at F 5 m/min: dtis_min_time's minimum is the reference of
# docs/references.md (1.6647 s) within a period, neither planner is faster than it by more than a
# period (the planners hold every limit within 100 %, the minimum within 1 + 3e-8), the path is
# cut at its three tips into five pieces, the time each planner loses on the pieces adds up to its
# gap, and so does each draw's (--draws 3: each planner at three lowered limits), each planner's
# draws end with their mean (the mean of the rows, between the least and the largest), and nothing
# is written next to the sample.
set -euo pipefail
dtis=$1
min_time=$2
root=$3
before=$(ls -A "$root/samples/jobs")
out=$(/usr/bin/python3 "$root/bench/gap.py" --dtis "$dtis" --min-time "$min_time" \
  --feed-mm-min 5000 --draws 3 "$root/samples/jobs/trident.toml")
echo "$out"
if [ "$(ls -A "$root/samples/jobs")" != "$before" ]; then
  echo "FAIL: gap.py wrote into samples/jobs" >&2
  exit 1
fi
echo "$out" | /usr/bin/python3 -c '
import re, sys
text = sys.stdin.read()
head = re.search(r"minimum ([0-9.]+) s, vpop ([0-9.]+) s .*, lookahead ([0-9.]+) s", text)
if not head:
    sys.exit("FAIL: no motion times in the first line")
minimum, vpop, ahead = map(float, head.groups())
fails = []
if abs(minimum - 1.6647) > 1e-3:
    fails.append(f"minimum {minimum} s, docs/references.md has 1.6647 s")
rows = [r for r in text.splitlines() if re.match(r"\| [0-9.]+ – [0-9.]+ \|", r)]
draws = [r for r in text.splitlines() if re.match(r"\| [0-9.]+ \| [0-9.]+ \| [+-]", r)]
if len(draws) != 6:
    fails.append(f"{len(draws)} draws, not 3 for each of the two planners")
for r in draws:
    cells = [c.strip() for c in r.strip("|").split("|")]
    total = float(cells[1])
    lost = sum(float(c.split()[0]) for c in cells[2:]) / 1000
    if len(cells) != 7 or abs(lost - (total - minimum)) > 2e-3:
        fails.append(f"draw at {cells[0]}: {len(cells) - 2} pieces losing {lost:.4f} s, "
                     f"motion {total} s against the minimum {minimum} s")
for name in ("vpop", "lookahead"):
    block = text.split(f"{name}, time lost")[-1]
    totals = [float(r.split("|")[2]) for r in block.splitlines()
              if re.match(r"\| [0-9.]+ \| [0-9.]+ \| [+-]", r)][:3]
    summary = re.search(r"least ([0-9.]+) s, largest ([0-9.]+) s, mean ([0-9.]+) ± ([0-9.]+) s",
                        block)
    if not summary:
        fails.append(f"no least, largest and mean of the {name} draws")
        continue
    least, largest, mean, error = map(float, summary.groups())
    if not (least <= mean <= largest) or abs(mean - sum(totals) / len(totals)) > 1e-3:
        fails.append(f"{name}: mean {mean} s of the draws {totals}, least {least}, "
                     f"largest {largest}")
if len(rows) != 5:
    fails.append(f"{len(rows)} pieces, not 5 (start, three tips, end)")
for k, (name, total) in enumerate((("vpop", vpop), ("lookahead", ahead))):
    if total < minimum - 1e-3:
        fails.append(f"{name} {total} s beats the minimum {minimum} s")
    lost = sum(float(r.split("|")[4 + 2 * k]) for r in rows) / 1000
    if abs(lost - (total - minimum)) > 2e-3:
        fails.append(f"{name} loses {lost:.4f} s on the pieces, {total - minimum:.4f} s in all")
if fails:
    sys.exit("FAIL: " + "; ".join(fails))
print("gap.py: ok")
'
