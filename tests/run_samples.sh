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
