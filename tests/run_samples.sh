#!/usr/bin/env bash
# Every sample job runs, and its setpoints pass `dtis verify` (VPOp jobs) or are read back by it
# (Taylor jobs, which know no axis limit and are only compared).
set -euo pipefail
dtis=$1
root=$2
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for job in "$root"/samples/jobs/*.toml; do
  name=$(basename "$job" .toml)
  machine=$(sed -n 's/^machine = "\(.*\)"/\1/p' "$job")
  machine=$(cd "$(dirname "$job")" && realpath "$machine")
  "$dtis" run "$job" -o "$out/$name.csv"
  if grep -q 'kind = "taylor' "$job"; then
    "$dtis" verify "$out/$name.csv" "$machine" >/dev/null || true
    test -s "$out/$name.csv"
  else
    "$dtis" verify "$out/$name.csv" "$machine"
  fi
  echo "sample $name: ok"
done

# A surface job's output does not depend on the number of threads planning its passes.
"$dtis" run "$root/samples/jobs/surface_plane_cl_3axis.toml" -o "$out/one.csv" -j 1 -q
"$dtis" run "$root/samples/jobs/surface_plane_cl_3axis.toml" -o "$out/two.csv" -j 2 -q
cmp "$out/one.csv" "$out/two.csv"
echo "surface job: byte-identical with 1 and 2 threads"

# The comparison of exports (issue 5) on the 5-axis sample: every variant verifies (exit 0), and the
# tables and exports are written.
"$dtis" compare "$root/samples/jobs/surface_tilt10_xyzac.toml" -q --csv "$out/cmp.csv" \
  --markdown "$out/cmp.md" --exports "$out/exports"
test "$(wc -l < "$out/cmp.csv")" -eq 6
test -s "$out/exports/surface_tilt10_xyzac_g1_1um.ngc"
test -s "$out/exports/surface_tilt10_xyzac_bspline_1um.mpf"
echo "compare: ok"
