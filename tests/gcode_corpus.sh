#!/usr/bin/env bash
# Programs as post-processors write them (tests/data/gcode), read by LinuxCNC's interpreter: each
# plans and passes the verifier (`dtis run` exits 3 otherwise, and `dtis verify` reads the file
# again), and `dtis stream` sends as many rows as `dtis run` plans at the same horizon; bad programs give LinuxCNC's message with the file and line, exit 1 and write nothing.
set -uo pipefail
dtis=$1
root=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
cp "$root"/tests/data/gcode/*.ngc "$root"/tests/data/gcode/*.tbl \
  "$root"/samples/machines/mikron_ucp710_xyz.toml "$work/"
job() {  # job PROGRAM [TOOL_TABLE]: PROGRAM on the XYZ Mikron with LinuxCNC's interpreter
  cat > "$work/job.toml" <<JOB
machine = "mikron_ucp710_xyz.toml"
[path]
kind = "gcode"
file = "$1"
interpreter = "rs274ngc"
JOB
  if [ $# -gt 1 ]; then echo "tool_table = \"$2\"" >> "$work/job.toml"; fi
}
# PROGRAM or PROGRAM+TABLE: the program with its tool table's offsets applied.
for case in freecad_post fusion_post fusion_post+fusion_post.tbl mastercam_arcs inch inverse_time \
    nurbs dwell; do
  program=${case%%+*}
  if [ "$case" = "$program" ]; then job "$program.ngc"; else job "$program.ngc" "${case#*+}"; fi
  quiet=-q  # the table's case keeps the summary, which names the table
  [ "$case" = "$program" ] || quiet=
  if ! summary=$("$dtis" run "$work/job.toml" -o "$work/out.csv" --horizon 256 $quiet 2>&1); then
    echo "FAIL $program: $summary"; failures=$((failures + 1)); continue
  fi
  if ! "$dtis" verify "$work/out.csv" "$work/mikron_ucp710_xyz.toml" >/dev/null 2>&1; then
    echo "FAIL $program: dtis verify refuses the setpoints"; failures=$((failures + 1)); continue
  fi
  rows=$(($(wc -l < "$work/out.csv")))
  streamed=$("$dtis" stream "$work/job.toml" --pace none --horizon 256 2>/dev/null | wc -l)
  if [ "$streamed" -ne "$rows" ]; then
    echo "FAIL $program: dtis stream sent $streamed rows, dtis run planned $rows"
    failures=$((failures + 1)); continue
  fi
  # With the table everything from G43 on runs 42.5 mm higher: the clearance Z15 at Z57.5.
  if [ "$case" != "$program" ]; then
    highest=$(awk -F, 'NR > 1 && ($4 > m || m == "") { m = $4 } END { printf "%.6f", m }' \
      "$work/out.csv")
    if [ "$highest" != "57.500000" ] || [[ "$summary" != *"tool table"* ]]; then
      echo "FAIL $case: highest Z $highest (expected 57.5), summary '$summary'"
      failures=$((failures + 1)); continue
    fi
  fi
  rm -f "$work/out.csv"
  echo "ok $case ($rows rows, $streamed streamed)"
done
rm -f "$work/out.csv"
for bad in "bad_word:4: E word with no G70" "bad_arc:4: Arc radius too small to reach end point"; do
  program=${bad%%:*}
  fragment="$program.ngc:${bad#*:}"
  job "$program.ngc"
  err=$("$dtis" run "$work/job.toml" -o "$work/out.csv" 2>&1 >/dev/null)
  rc=$?
  if [ $rc -ne 1 ] || [[ "$err" != *"$fragment"* ]] || [ -e "$work/out.csv" ]; then
    echo "FAIL $program: exit $rc, '$err' (expected 1 and '$fragment', no file)"
    failures=$((failures + 1)); continue
  fi
  echo "ok $program: $err"
done
# A bad tool table: its file and line, exit 1, nothing written.
printf 'T1 P1 Z42.5\nT2 P2 Z4x\n' > "$work/bad.tbl"
job fusion_post.ngc bad.tbl
err=$("$dtis" run "$work/job.toml" -o "$work/out.csv" 2>&1 >/dev/null)
rc=$?
if [ $rc -ne 1 ] || [[ "$err" != *"bad.tbl:2: Z: expected a number, got '4x'"* ]] ||
    [ -e "$work/out.csv" ]; then
  echo "FAIL bad tool table: exit $rc, '$err'"; failures=$((failures + 1))
else
  echo "ok bad tool table: $err"
fi
[ $failures -eq 0 ] || { echo "$failures failures"; exit 1; }
