#!/usr/bin/env bash
# HTML reports in headless Chromium. Every sample job's `dtis run --report`, a `dtis
# compare --report`, a `dtis stream --report` and a `dtis report --job --limiters` must render with
# no script or console error, hold the expected plots and traces, and show the numbers `dtis verify`
# prints for the same setpoints, and name the machine and dtis version in their header; the path
# has a colour bar, no legend's or annotation's box overlaps a plot's toolbar, and micrometres read
# µm; with WebGL off every plot is drawn in SVG; `dtis figures` must write every plot as a PNG and
# an SVG at the size asked for (88 mm at 300 dpi, said in the PNG; the SVG in mm), no text under
# 9 px (6.75 pt).
# Keeps a screenshot of the 5-axis report and its figures in OUTDIR (default: the current folder,
# ctest's build/tests).
# Usage: report.sh DTIS ROOT [OUTDIR]
set -euo pipefail
dtis=$1
root=$2
out=${3:-$PWD}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Without plotly.js (the npm registry was out of reach at bootstrap) reports cannot be made: skip.
plotly=${DTIS_PLOTLY_JS:-$root/tools/report/node_modules/plotly.js-dist-min/plotly.min.js}
[ -s "$plotly" ] || { echo "report: skipped: no plotly.js at $plotly (scripts/bootstrap)"; exit 77; }
command -v chromium >/dev/null ||
  { echo "report: no chromium; scripts/bootstrap installs it (apt install chromium)" >&2; exit 1; }
browse() {  # extra chromium arguments..., page
  timeout 180 chromium --headless --no-sandbox --disable-gpu --use-gl=swiftshader \
    --enable-unsafe-swiftshader --virtual-time-budget=20000 --enable-logging=stderr --v=0 \
    --user-data-dir="$work/profile" "$@"
}
machine_of() {  # job -> its machine file, absolute
  local m
  m=$(sed -n 's/^machine *= *"\(.*\)"/\1/p' "$1")
  (cd "$(dirname "$1")" && realpath "$m")
}

failures=0
# check NAME HTML SETPOINTS MACHINE PLOTS MIN_TRACES MAX_TRACES [TEXT...]: the page renders, with
# PLOTS plots and MIN..MAX traces, its summary equal to dtis verify's on SETPOINTS, and each TEXT
# somewhere in its tables.
check() {
  local name=$1 html=$2 csv=$3 machine=$4 want_plots=$5 min_traces=$6 max_traces=$7
  shift 7
  # #raw: the raw values' plots too (the page draws them when asked for).
  browse --dump-dom "file://$html#raw" >"$work/$name.dom" 2>"$work/$name.err"
  local body status errors plots traces time_v ratio_v summary problem="" colorbars overlaps
  body=$(grep -o '<body[^>]*>' "$work/$name.dom")
  status=$(sed -n 's/.*data-report-status="\([^"]*\)".*/\1/p' <<<"$body")
  errors=$(sed -n 's/.*data-console-errors="\([^"]*\)".*/\1/p' <<<"$body")
  plots=$(sed -n 's/.*data-plots="\([^"]*\)".*/\1/p' <<<"$body")
  traces=$(sed -n 's/.*data-traces="\([^"]*\)".*/\1/p' <<<"$body")
  colorbars=$(sed -n 's/.*data-colorbars="\([^"]*\)".*/\1/p' <<<"$body")
  overlaps=$(sed -n 's/.*data-legend-over-toolbar="\([^"]*\)".*/\1/p' <<<"$body")
  "$dtis" verify "$csv" "$machine" >"$work/$name.verify" || true
  time_v=$(sed -n 's/^\([0-9]*\) setpoints, period .* motion time \([0-9.]*\) s$/\2/p' "$work/$name.verify")
  ratio_v=$(sed -n 's/^worst ratio \([0-9.]*\) (.*/\1/p' "$work/$name.verify")
  # The page's text, without the scripts (plotly.js' own text).
  perl -0pe 's/<script.*?<\/script>//gs' "$work/$name.dom" | sed 's/<[^>]*>/|/g' | tr -s '|' >"$work/$name.text"
  summary=$(grep -o 'motion time|[0-9.]* s|setpoints|[^|]*|worst ratio|[0-9.]*' "$work/$name.text" || true)
  [ "$status" = ok ] || problem="status '$status'"
  [ "$errors" = 0 ] || problem="$problem; $errors console errors"
  grep -q "Uncaught" "$work/$name.err" && problem="$problem; uncaught exception: $(grep Uncaught "$work/$name.err" | head -1)"
  [ "$plots" = "$want_plots" ] || problem="$problem; $plots plots, expected $want_plots"
  [ "${colorbars:-0}" -ge 1 ] || problem="$problem; no colour bar on the path"
  [ "$overlaps" = 0 ] || problem="$problem; $overlaps plots with a legend or annotation over their toolbar"
  grep -qE '[0-9( ]um([^a-zA-Z]|$)' "$work/$name.text" &&
    problem="$problem; 'um' for µm: $(grep -oE '.{20}[0-9( ]um([^a-zA-Z]|$)' "$work/$name.text" | head -1)"
  [ "${traces:-0}" -ge "$min_traces" ] && [ "${traces:-0}" -le "$max_traces" ] ||
    problem="$problem; $traces traces, expected $min_traces to $max_traces"
  grep -q "motion time|$time_v s|" <<<"$summary" || problem="$problem; summary '$summary' lacks motion time $time_v"
  grep -q "worst ratio|$ratio_v" <<<"$summary" || problem="$problem; summary '$summary' lacks worst ratio $ratio_v"
  local text
  for text in "$@"; do
    grep -qF "|$text|" "$work/$name.text" || problem="$problem; no '$text' in its tables"
  done
  if [ -n "$problem" ]; then
    echo "FAIL $name: ${problem#; }"
    failures=$((failures + 1))
  else
    echo "ok $name: $plots plots, $traces traces, motion time $time_v s, worst ratio $ratio_v"
  fi
}
# check_without_webgl NAME HTML PLOTS: with WebGL off (--disable-3d-apis) the page renders every
# plot in SVG (the tool path from above) and shows no "WebGL is not supported"; with WebGL on (the
# DOM check() read) every plot but the 3-D path is SVG too. Its header names the machine and the
# dtis version.
check_without_webgl() {
  local name=$1 html=$2 want_plots=$3 body problem=""
  browse --disable-3d-apis --dump-dom "file://$html#raw" >"$work/$name.nogl.dom" 2>/dev/null
  body=$(grep -o '<body[^>]*>' "$work/$name.nogl.dom")
  grep -q 'data-webgl="no"' <<<"$body" || problem="WebGL was not off"
  grep -q 'data-report-status="ok"' <<<"$body" || problem="$problem; status not ok: $body"
  grep -q "data-drawn2d=\"$want_plots\"" <<<"$body" ||
    problem="$problem; not every one of $want_plots plots drawn in SVG: $body"
  # The library's own text is in a script; the page's is not.
  grep -q "WebGL is not supported" < <(perl -0pe 's/<script.*?<\/script>//gs' "$work/$name.nogl.dom") &&
    problem="$problem; the page says WebGL is not supported"
  body=$(grep -o '<body[^>]*>' "$work/$name.dom")
  # With WebGL the path is 3-D unless it lies in a plane.
  local flat=0
  grep -q 'data-path3d="no"' <<<"$body" && flat=1
  grep -q "data-drawn2d=\"$((want_plots - 1 + flat))\"" <<<"$body" ||
    problem="$problem; with WebGL, not every 2-D plot drawn in SVG: $body"
  grep -qF "|dtis|$("$dtis" --version | cut -d' ' -f2)|" "$work/$name.text" ||
    problem="$problem; no dtis version in its header"
  grep -qF "|machine|" "$work/$name.text" || problem="$problem; no machine in its header"
  if [ -n "$problem" ]; then
    echo "FAIL $name without WebGL: ${problem#; }"
    failures=$((failures + 1))
  else
    echo "ok $name without WebGL: $want_plots plots in SVG"
  fi
}
axes_of() { echo $(($(head -1 "$1" | tr ',' '\n' | wc -l) - 1)); }
# Traces of a run's report: path (+ tool axis in 5-axis, + surface), feed (+ programmed feed,
# + deciding constraint), the limit usage (per axis one for each of v, a, j), and per axis its
# values (position, velocity, acceleration, the jerk's band as 3) and 6 limit lines.
path_traces() {  # csv job
  local axes rotary surface
  axes=$(axes_of "$1")
  rotary=$((axes > 3 ? 1 : 0))
  surface=$(grep -q '^\[surface\]' "$2" && echo 1 || echo 0)
  echo $((1 + rotary + surface + 1 + axes * 3 + axes * 12))
}
# Plots of a run's report: path, feed, usage and one per axis.
plots_of() { echo $((3 + $(axes_of "$1"))); }

for job in "$root"/samples/jobs/*.toml; do
  name=$(basename "$job" .toml)
  "$dtis" run "$job" -o "$work/$name.csv" --limiters "$work/$name.lim.csv" \
    --report "$work/$name.html" -q || true
  min=$(path_traces "$work/$name.csv" "$job")
  check "$name" "$work/$name.html" "$work/$name.csv" "$(machine_of "$job")" \
    "$(plots_of "$work/$name.csv")" "$min" $((min + 2))
  check_without_webgl "$name" "$work/$name.html" "$(plots_of "$work/$name.csv")"

done

# One pass of the 39 of the 3-axis surface job (#pass=2, as the report's selector and dtis figures
# --pass show it): the feed's axis spans that pass' arc lengths.
browse --dump-dom "file://$work/surface_plane_cl_3axis.html#pass=2" 2>/dev/null >"$work/pass.dom"
range=$(grep -o '<body[^>]*>' "$work/pass.dom" | sed -n 's/.*data-feed-range="\([^"]*\)".*/\1/p')
if [[ $range =~ ^([0-9.]+,[0-9.]+)\ of\ ([0-9.]+,[0-9.]+)$ ]] && [ "${BASH_REMATCH[1]}" = "${BASH_REMATCH[2]}" ]; then
  echo "ok pass 2 alone: arc lengths ${BASH_REMATCH[1]} mm"
else
  echo "FAIL pass 2 alone: the feed's axis is '$range'"
  failures=$((failures + 1))
fi

# The 5-axis surface job three more ways.
job=$root/samples/jobs/surface_tilt10_xyzac.toml
machine=$(machine_of "$job")
name=surface_tilt10_xyzac
min=$(path_traces "$work/$name.csv" "$job")
# dtis report of the run's files, with its job and limiter report: the same plots and traces as the
# run's own report (the surface, the programmed feed, the deciding constraint).
"$dtis" report "$work/$name.csv" --job "$job" --limiters "$work/$name.lim.csv" -o "$work/file.html"
check report-file "$work/file.html" "$work/$name.csv" "$machine" 8 $((min + 2)) $((min + 2))
# What was streamed, stop included.
"$dtis" stream "$job" --to "$work/stream.txt" --record "$work/stream.csv" --report "$work/stream.html" -q
check stream "$work/stream.html" "$work/stream.csv" "$machine" 8 $((min + 2)) $((min + 2))
# The comparison: its table (every variant's name, µm for um), one panel per variant with its feed
# (and the exact surface's of the same planner in grey under the others), a bar per variant and
# planner for time and for deviation, and the exact-surface run in full.
"$dtis" compare "$job" --csv "$work/compare.csv" --report "$work/compare.html" -q >/dev/null
mapfile -t rows < <(tail -n +2 "$work/compare.csv" | cut -d, -f1,2)
mapfile -t variants < <(printf '%s\n' "${rows[@]}" | cut -d, -f1 | sed 's/ um$/ µm/')
planners=$(printf '%s\n' "${rows[@]}" | cut -d, -f2 | sort -u | wc -l)
grep '^DTIS' "$work/compare.csv" >/dev/null
# The exact variant's setpoints are the run's (the same passes and links, planned the same way).
compared=$((min + 2 + 2 * ${#rows[@]} + planners))
check compare "$work/compare.html" "$work/$name.csv" "$machine" 10 "$compared" "$compared" "${variants[@]}"
check_without_webgl compare "$work/compare.html" 10

# Static figures: every plot of the report and of the comparison, as PNG and SVG at print size:
# 88 mm wide (a column), the PNG at 300 dpi and saying so, the SVG in mm, no text under 9 px
# (6.75 pt at that size). Python's zlib checks every PNG chunk's CRC.
"$dtis" figures "$work/$name.html" -o "$out/figures_$name" -q --width-mm 88 --dpi 300
"$dtis" figures "$work/compare.html" -o "$out/figures_compare" -q
png_check() {  # png -> "WIDTH DPI", or an error
  python3 - "$1" <<'PY'
import struct, sys, zlib
data = open(sys.argv[1], 'rb').read()
assert data[:8] == b'\x89PNG\r\n\x1a\n', 'no PNG signature'
at, width, dpi = 8, None, None
while at < len(data):
    length, kind = struct.unpack('>I4s', data[at:at + 8])
    body = data[at + 8:at + 8 + length]
    assert struct.unpack('>I', data[at + 8 + length:at + 12 + length])[0] == zlib.crc32(kind + body), kind
    if kind == b'IHDR': width = struct.unpack('>I', body[:4])[0]
    if kind == b'pHYs' and body[8] == 1: dpi = round(struct.unpack('>I', body[:4])[0] * 0.0254)
    at += 12 + length
print(width, dpi)
PY
}
figures_ok() {  # folder plots...
  local dir=$1 plot png svg good=0 want problem=""
  shift
  want=$#
  for plot in "$@"; do
    png=$dir/$plot.png svg=$dir/$plot.svg
    # 88 mm at 300 dpi: 1039 px, to the CSS pixel plotly lays it out on (96 to the inch).
    if ! size=$(png_check "$png" 2>&1); then
      problem="$problem; $png: $size"
    elif ! [[ $size =~ ^10[34][0-9]\ 300$ ]]; then
      problem="$problem; $png is '$size' (width px, dpi), expected about 1039 px at 300 dpi"
    elif ! head -c 400 "$svg" | grep -q '^<svg[^>]* width="88.00mm" height="[0-9.]*mm"'; then
      problem="$problem; $svg is not an SVG 88 mm wide"
    elif grep -oE 'font-size: [0-8](\.[0-9]*)?px' "$svg" | grep -q .; then
      problem="$problem; $svg has text under 9 px: $(grep -oE 'font-size: [0-8](\.[0-9]*)?px' "$svg" | head -1)"
    else
      good=$((good + 1))
    fi
  done
  if [ $good -eq "$want" ] && [ "$(find "$dir" -type f | wc -l)" -eq $((2 * want)) ]; then
    echo "ok figures: $want plots as PNG and SVG in $dir"
  else
    echo "FAIL figures: $good of $want plots good, $(find "$dir" -type f | wc -l) files${problem}"
    failures=$((failures + 1))
  fi
}
figures_ok "$out/figures_$name" path path-top feed usage axis-X axis-Y axis-Z axis-A axis-C
figures_ok "$out/figures_compare" compare-feed compare-bars path path-top feed usage axis-X axis-Y axis-Z axis-A axis-C

browse --window-size=1400,2400 --screenshot="$out/report_$name.png" "file://$work/$name.html" \
  >/dev/null 2>&1
test -s "$out/report_$name.png"
echo "screenshot: $out/report_$name.png"
[ $failures -eq 0 ]
