#!/usr/bin/env bash
# dtis run --report on every sample job, each report loaded in headless Chromium (issue 7): the page
# must render with no script or console error, hold the expected number of plots and traces, and
# show the numbers `dtis verify` prints for the same setpoints. Keeps a screenshot of the 5-axis
# report in OUTDIR (default: the current folder, ctest's build/tests).
# Usage: report.sh DTIS ROOT [OUTDIR]
set -euo pipefail
dtis=$1
root=$2
out=${3:-$PWD}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

if ! command -v chromium >/dev/null; then
  [ "$(id -u)" = 0 ] || { echo "report: chromium missing and not root: apt install chromium" >&2; exit 1; }
  install() {
    DEBIAN_FRONTEND=noninteractive timeout 600 apt-get install -y -q --no-install-recommends \
      chromium >>"$work/apt.log" 2>&1
  }
  install || { timeout 600 apt-get update -qq >>"$work/apt.log" 2>&1 && install; } ||
    { tail -20 "$work/apt.log" >&2; exit 1; }
fi
browse() {  # extra chromium arguments..., page
  timeout 180 chromium --headless --no-sandbox --disable-gpu --use-gl=swiftshader \
    --enable-unsafe-swiftshader --virtual-time-budget=20000 --enable-logging=stderr --v=0 \
    --user-data-dir="$work/profile" "$@"
}

failures=0
for job in "$root"/samples/jobs/*.toml; do
  name=$(basename "$job" .toml)
  machine=$(sed -n 's/^machine *= *"\(.*\)"/\1/p' "$job")
  machine=$(cd "$(dirname "$job")" && realpath "$machine")
  "$dtis" run "$job" -o "$work/$name.csv" --report "$work/$name.html" -q || true
  axes=$(($(head -1 "$work/$name.csv" | tr ',' '\n' | wc -l) - 1))
  browse --dump-dom "file://$work/$name.html" >"$work/$name.dom" 2>"$work/$name.err"
  body=$(grep -o '<body[^>]*>' "$work/$name.dom")
  status=$(sed -n 's/.*data-report-status="\([^"]*\)".*/\1/p' <<<"$body")
  errors=$(sed -n 's/.*data-console-errors="\([^"]*\)".*/\1/p' <<<"$body")
  plots=$(sed -n 's/.*data-plots="\([^"]*\)".*/\1/p' <<<"$body")
  traces=$(sed -n 's/.*data-traces="\([^"]*\)".*/\1/p' <<<"$body")
  # Path (+ tool axis in 5-axis); feed (+ programmed feed, + deciding constraint); per axis 4
  # series and 6 limit lines.
  rotary=$((axes > 3 ? 1 : 0))
  want_plots=$((2 + axes))
  # The summary: motion time and worst ratio as dtis verify prints them.
  "$dtis" verify "$work/$name.csv" "$machine" >"$work/$name.verify" || true
  time_v=$(sed -n 's/^\([0-9]*\) setpoints, period .* motion time \([0-9.]*\) s$/\2/p' "$work/$name.verify")
  ratio_v=$(sed -n 's/^worst ratio \([0-9.]*\) (.*/\1/p' "$work/$name.verify")
  summary=$(sed 's/<[^>]*>/|/g' "$work/$name.dom" | tr -s '|' | grep -o 'motion time|[0-9.]* s|setpoints|[^|]*|worst ratio|[0-9.]*' || true)
  problem=""
  [ "$status" = ok ] || problem="status '$status'"
  [ "$errors" = 0 ] || problem="$problem; $errors console errors"
  grep -q "Uncaught" "$work/$name.err" && problem="$problem; uncaught exception: $(grep Uncaught "$work/$name.err" | head -1)"
  [ "$plots" = "$want_plots" ] || problem="$problem; $plots plots, expected $want_plots"
  min_traces=$((1 + rotary + 1 + axes * 10))
  [ "${traces:-0}" -ge "$min_traces" ] && [ "${traces:-0}" -le $((min_traces + 2)) ] ||
    problem="$problem; $traces traces, expected $min_traces to $((min_traces + 2))"
  grep -q "motion time|$time_v s|" <<<"$summary" || problem="$problem; summary '$summary' lacks motion time $time_v"
  grep -q "worst ratio|$ratio_v" <<<"$summary" || problem="$problem; summary '$summary' lacks worst ratio $ratio_v"
  if [ -n "$problem" ]; then
    echo "FAIL $name: ${problem#; }"
    failures=$((failures + 1))
  else
    echo "ok $name: $plots plots, $traces traces, motion time $time_v s, worst ratio $ratio_v"
  fi
done
browse --window-size=1400,2400 --screenshot="$out/report_surface_tilt10_xyzac.png" \
  "file://$work/surface_tilt10_xyzac.html" >/dev/null 2>&1
test -s "$out/report_surface_tilt10_xyzac.png"
echo "screenshot: $out/report_surface_tilt10_xyzac.png"
[ $failures -eq 0 ]
