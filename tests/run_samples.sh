#!/usr/bin/env bash
# Every sample job runs with each planner docs/samples.md gives a figure for (a starred one is
# measured, not run here), its setpoints pass
# `dtis verify` and its motion time is that figure (Taylor jobs, which know no axis limit, are only
# read back).
set -euo pipefail
dtis=$1
root=$2
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# The motion time docs/samples.md prints for a job and planner ("" when it has none, or marks it
# as not run by this test with a *).
documented() {
  awk -F'|' -v job="samples/jobs/$1.toml" -v col="$2" '
    { gsub(/[ `]/, "", $2) }
    $2 == job { v = $(col == "vpop" ? 4 : col == "lookahead" ? 5 : 6); gsub(/ /, "", v); if (v !~ /\*/) print v }
  ' "$root/docs/samples.md"
}

for job in "$root"/samples/jobs/*.toml; do
  name=$(basename "$job" .toml)
  machine=$(sed -n 's/^machine = "\(.*\)"/\1/p' "$job")
  machine=$(cd "$(dirname "$job")" && realpath "$machine")
  if grep -q 'kind = "taylor' "$job"; then
    "$dtis" run "$job" -o "$out/$name.csv"
    "$dtis" verify "$out/$name.csv" "$machine" >/dev/null || true
    test -s "$out/$name.csv"
    echo "sample $name: ok"
    continue
  fi
  grep -q "samples/jobs/$name.toml" "$root/docs/samples.md" || {
    echo "sample $name: not in docs/samples.md" >&2
    exit 1
  }
  vpop_motion=""
  lookahead_motion=""
  for planner in vpop lookahead least-time; do
    limit=$(documented "$name" "$planner")
    [ -n "$limit" ] || continue
    "$dtis" run "$job" --planner "$planner" -o "$out/$name.csv" 2>"$out/summary"
    "$dtis" verify "$out/$name.csv" "$machine"
    motion=$(sed -n 's/^motion time *\([0-9.]*\) s$/\1/p' "$out/summary")
    # Motion times are whole periods (1 ms): the printed figure is the planned time exactly.
    awk -v m="$motion" -v l="$limit" 'BEGIN { d = m - l; exit !(m != "" && d <= 1e-9 && d >= -1e-9) }' || {
      echo "sample $name, $planner: motion time $motion s, docs/samples.md says $limit s" >&2
      exit 1
    }
    echo "sample $name, $planner: ok, $motion s (docs: $limit s)"
    if [ "$planner" = vpop ]; then vpop_motion=$motion; fi
    if [ "$planner" = lookahead ]; then lookahead_motion=$motion; fi
    # The least-time planner starts from the look-ahead's plan (or `vpop`'s where that is faster
    # on a path with corners) and only shortens it: never slower than the look-ahead, and not
    # slower than `vpop` by more than 1 % (surface passes start from the look-ahead's alone).
    if [ "$planner" = least-time ]; then
      for other in "$lookahead_motion 1" "$vpop_motion 1.01"; do
        set -- $other
        [ $# -eq 2 ] || continue
        awk -v l="$motion" -v o="$1" -v f="$2" 'BEGIN { exit !(l <= f * o + 1e-9) }' || {
          echo "sample $name: least-time $motion s is more than $2 x another planner's $1 s" >&2
          exit 1
        }
      done
    fi
    # The look-ahead planner is never more than 0.5 % slower than the paper's, but on the
    # zigzag's 90-degree corners 7 mm apart, where it is 3.0 % slower (docs/limits.md).
    over=1.005
    if [ "$name" = zigzag ]; then over=1.031; fi
    if [ "$planner" = lookahead ] && [ -n "$vpop_motion" ]; then
      awk -v l="$motion" -v v="$vpop_motion" -v o="$over" 'BEGIN { exit !(l <= o * v) }' || {
        echo "sample $name: lookahead $motion s is more than $over x vpop's $vpop_motion s" >&2
        exit 1
      }
    fi
  done
done

# A surface job's output does not depend on the number of threads planning its passes.
"$dtis" run "$root/samples/jobs/surface_plane_cl_3axis.toml" -o "$out/one.csv" -j 1 -q
"$dtis" run "$root/samples/jobs/surface_plane_cl_3axis.toml" -o "$out/two.csv" -j 2 -q
cmp "$out/one.csv" "$out/two.csv"
echo "surface job: byte-identical with 1 and 2 threads"

# The comparison of exports on the 5-axis sample: every variant, planned by each planner,
# verifies (exit 0), and the tables and exports are written.
"$dtis" compare "$root/samples/jobs/surface_tilt10_xyzac.toml" -q --csv "$out/cmp.csv" \
  --markdown "$out/cmp.md" --exports "$out/exports"
test "$(wc -l < "$out/cmp.csv")" -eq 13
test "$(grep -c ',vpop,' "$out/cmp.csv")" -eq 6
test "$(grep -c ',lookahead,' "$out/cmp.csv")" -eq 6
"$dtis" compare "$root/samples/jobs/surface_tilt10_xyzac.toml" -q --planner lookahead \
  --csv "$out/cmp1.csv"
test "$(wc -l < "$out/cmp1.csv")" -eq 7
test -s "$out/exports/surface_tilt10_xyzac_g1_1um.ngc"
test -s "$out/exports/surface_tilt10_xyzac_bspline_1um.mpf"
echo "compare: ok"
