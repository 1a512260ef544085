#!/usr/bin/env bash
# Screenshots of every sample job's HTML report and of the 5-axis comparison, in headless Chromium,
# to look at whenever the reports change; and the figures `dtis figures` draws (at 150 dpi, for
# the web) of the 5-axis run and of the comparison. docs/images/ keeps a few of them (see
# docs/reports.md).
# Usage: tools/report/screenshots.sh [DTIS] [OUTDIR]
#   (defaults: build/cli/dtis, build/screenshots; about 3 minutes)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
dtis=${1:-$root/build/cli/dtis}
out=${2:-$root/build/screenshots}
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
shoot() {  # html png height
  timeout 180 chromium --headless --no-sandbox --disable-gpu --use-gl=swiftshader \
    --enable-unsafe-swiftshader --virtual-time-budget=20000 --hide-scrollbars \
    --user-data-dir="$work/profile" --window-size=1400,"$3" --screenshot="$2" "file://$1" \
    >/dev/null 2>&1
  echo "$2"
}
for job in "$root"/samples/jobs/*.toml; do
  name=$(basename "$job" .toml)
  "$dtis" run "$job" -o "$work/$name.csv" --report "$work/$name.html" -q || continue
  shoot "$work/$name.html" "$out/report_$name.png" 2350
done
"$dtis" compare "$root/samples/jobs/surface_tilt10_xyzac.toml" --report "$work/compare.html" -q \
  >/dev/null
shoot "$work/compare.html" "$out/report_compare.png" 2000
# The raw values, jerk band included, of the 5-axis run.
shoot "$work/surface_tilt10_xyzac.html#raw" "$out/report_surface_tilt10_xyzac_raw.png" 4000
for name in surface_tilt10_xyzac compare; do
  "$dtis" figures "$work/$name.html" -o "$out/figures_$name" --dpi 150 -q
  echo "$out/figures_$name"
done
