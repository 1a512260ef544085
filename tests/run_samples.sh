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
