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
cp "$root"/tests/data/gcode/*.ngc "$root"/samples/machines/mikron_ucp710_xyz.toml "$work/"
job() {  # job PROGRAM: a job planning PROGRAM on the XYZ Mikron with LinuxCNC's interpreter
  cat > "$work/job.toml" <<JOB
machine = "mikron_ucp710_xyz.toml"
[path]
kind = "gcode"
file = "$1"
interpreter = "rs274ngc"
JOB
}
for program in freecad_post fusion_post mastercam_arcs inch inverse_time nurbs dwell; do
  job "$program.ngc"
  if ! summary=$("$dtis" run "$work/job.toml" -o "$work/out.csv" --horizon 256 -q 2>&1); then
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
  rm -f "$work/out.csv"
  echo "ok $program ($rows rows, $streamed streamed)"
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
[ $failures -eq 0 ] || { echo "$failures failures"; exit 1; }
