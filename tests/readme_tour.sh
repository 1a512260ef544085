#!/usr/bin/env bash
# The README's five-minute tour, taken from its text (between the tour:begin and tour:end marks)
# and run as written, from a folder laid out like the repository after scripts/bootstrap: every
# command must succeed and leave the files it names.
set -euo pipefail
dtis=$1
root=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The tour writes a report, which needs plotly.js (the npm registry was out of reach at bootstrap):
# without it, skip.
plotly=${DTIS_PLOTLY_JS:-$root/tools/report/node_modules/plotly.js-dist-min/plotly.min.js}
[ -s "$plotly" ] || { echo "readme_tour: skipped: no plotly.js at $plotly (scripts/bootstrap)"; exit 77; }

awk '/<!-- tour:begin -->/ { on = 1; next } /<!-- tour:end -->/ { on = 0 } on && !/^```/' \
  "$root/README.md" >"$work/tour.sh"
test "$(grep -c '^dtis ' "$work/tour.sh")" -ge 5 || {
  echo "readme_tour: no tour found in README.md" >&2
  exit 1
}
ln -s "$root/samples" "$work/samples"
mkdir -p "$work/build/cli"
ln -s "$dtis" "$work/build/cli/dtis"

cd "$work"
echo "--- the tour, as README.md has it:"
cat tour.sh
echo "---"
bash -euo pipefail tour.sh >tour.out 2>&1 || {
  cat tour.out >&2
  echo "readme_tour: a command of the tour failed" >&2
  exit 1
}
# Every file the tour writes (-o, --report, --markdown, --limiters, --to, --record) is there.
for f in $(grep -oE -- '(-o|--report|--markdown|--limiters|--to|--record) [^ ]+' tour.sh | cut -d' ' -f2); do
  test -s "$f" || { echo "readme_tour: $f was not written" >&2; exit 1; }
done
echo "readme_tour: ok ($(grep -c '^dtis ' tour.sh) commands)"
