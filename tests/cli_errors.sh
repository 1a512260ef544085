#!/usr/bin/env bash
# Bad input on the command line: one clear message naming the file, line or key, the documented
# exit status (1 bad input, 2 usage, 3 verification failed), and no output file left behind.
set -uo pipefail
dtis=$1
root=$2
rs274=${3:-}  # "rs274": dtis was built with LinuxCNC's interpreter, the default G-code reader
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
checks=0
expect_status() {  # expect_status STATUS NAME FRAGMENT -- command...
  local want=$1 name=$2 fragment=$3
  checks=$((checks + 1))
  shift 4
  local err
  err=$("$@" 2>&1 >/dev/null)
  local rc=$?
  if [ $rc -ne "$want" ]; then
    echo "FAIL $name: exit $rc, expected $want ($err)"; failures=$((failures + 1)); return
  fi
  if [[ "$err" != *"$fragment"* ]]; then
    echo "FAIL $name: message '$err' lacks '$fragment'"; failures=$((failures + 1)); return
  fi
  if ls "$work"/out* >/dev/null 2>&1 || ls "$work"/.out* >/dev/null 2>&1; then
    echo "FAIL $name: left an output file"; failures=$((failures + 1)); rm -f "$work"/out* "$work"/.out*; return
  fi
  echo "ok $name"
}
expect() { expect_status 1 "$@"; }  # bad input
expect_usage() { expect_status 2 "$@"; }
cp "$root"/samples/machines/*.toml "$work/"
cat > "$work/base.toml" <<JOB
machine = "mikron_ucp710_xyz.toml"
feed_mm_min = 5000
[path]
kind = "line"
from = [0, 0, 0]
to = [100, 0, 0]
JOB
cp "$work/base.toml" "$work/line.toml"
expect missing-job "no-such.toml: cannot open" -- "$dtis" run "$work/no-such.toml" -o "$work/out.csv"
printf 'period_ms = -1\n' | cat - "$work/base.toml" > "$work/dt.toml"
expect bad-period "dt.toml:1: key 'period_ms': expected a number > 0, got -1" -- "$dtis" run "$work/dt.toml" -o "$work/out.csv"
# Runaway inputs: refused at once, naming the key or file, instead of a run that never ends.
printf 'period_ms = 300000\n' | cat - "$work/base.toml" > "$work/longdt.toml"
expect huge-period "longdt.toml:1: key 'period_ms': expected a period from 0.01 to 100 ms, got 300000" -- timeout 10 "$dtis" run "$work/longdt.toml" -o "$work/out.csv"
sed 's/^feed_mm_min = .*/feed_mm_min = 1e-12/' "$work/base.toml" > "$work/crawl.toml"
expect crawling-feed "takes at least 1.67e+12 h with feed_mm_min = 1e-12, more than the 24 h a job may take" -- timeout 10 "$dtis" run "$work/crawl.toml" -o "$work/out.csv"
printf '[tangential]\njerk_mm_s3 = 1e-12\n' | cat "$work/base.toml" - > "$work/tjerk.toml"
expect crawling-jerk "with [tangential] jerk_mm_s3 = 1e-12, more than the 24 h" -- timeout 10 "$dtis" run "$work/tjerk.toml" -o "$work/out.csv"
sed 's|^machine = .*|machine = "/dev/zero"|' "$work/base.toml" > "$work/devzero.toml"
expect device-machine "/dev/zero: is a device, not a file; expected a regular file" -- timeout 10 "$dtis" run "$work/devzero.toml" -o "$work/out.csv"
mkfifo "$work/fifo.toml"
expect fifo-job "fifo.toml: is a FIFO, not a file" -- timeout 10 "$dtis" run "$work/fifo.toml" -o "$work/out.csv"
expect directory-job "is a directory, not a file" -- timeout 10 "$dtis" run "$work" -o "$work/out.csv"
printf 'speed = 3\n' | cat "$work/base.toml" - > "$work/unknown.toml"
expect unknown-key "unknown.toml:7: unknown key 'path.speed'" -- "$dtis" run "$work/unknown.toml" -o "$work/out.csv"
sed 's/jerk = 5$/jerk = nan/' "$work/mikron_ucp710_xyz.toml" > "$work/nanjerk.toml"
sed 's/mikron_ucp710_xyz.toml/nanjerk.toml/' "$work/base.toml" > "$work/nan.toml"
expect nan-limit "nanjerk.toml:19: key 'axes.X.jerk': expected a finite number" -- "$dtis" run "$work/nan.toml" -o "$work/out.csv"
sed 's/velocity = 30$/velocity = 0/' "$work/mikron_ucp710_xyz.toml" > "$work/zerov.toml"
sed 's/mikron_ucp710_xyz.toml/zerov.toml/' "$work/base.toml" > "$work/zero.toml"
expect zero-limit "key 'axes.X.velocity': expected a number > 0, got 0" -- "$dtis" run "$work/zero.toml" -o "$work/out.csv"
cat > "$work/knots.toml" <<CURVE
degree = 3
knots = [0, 0, 0, 0, 0.5, 0.25, 1, 1, 1, 1]
poles = [[0, 0], [1, 1], [2, 0], [3, 1], [4, 0], [5, 1]]
CURVE
sed 's/kind = "line"/kind = "curve"\nfile = "knots.toml"/; /^from/d; /^to/d' "$work/base.toml" > "$work/curvejob.toml"
expect bad-knots "knots.toml:2: curve: knots must not decrease" -- "$dtis" run "$work/curvejob.toml" -o "$work/out.csv"
sed 's/^knots = .*/knots = [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1]/; $a weights = [1, 1, -1, 1, 1, 1]' "$work/knots.toml" > "$work/w.toml"
sed 's/knots.toml/w.toml/' "$work/curvejob.toml" > "$work/wjob.toml"
expect bad-weight "w.toml:4: curve: weight 2 is -1" -- "$dtis" run "$work/wjob.toml" -o "$work/out.csv"
# A pole out in space (a typo, a unit error): refused at once; one at the bound plans until
# the path leaves the machine's travel, quickly (the arc-length map ends at s's resolution).
sed 's/^knots = .*/knots = [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1]/; s/\[2, 0\]/[2, 1e300]/' "$work/knots.toml" > "$work/far.toml"
sed 's/knots.toml/far.toml/' "$work/curvejob.toml" > "$work/farjob.toml"
expect far-pole "far.toml:3: curve: pole 2 (2, 1e+300, 0) is more than 1e+06 mm from the origin" -- timeout 10 "$dtis" run "$work/farjob.toml" -o "$work/out.csv"
sed 's/1e300/1e6/' "$work/far.toml" > "$work/km.toml"
sed 's/knots.toml/km.toml/; s/^feed_mm_min = .*/feed_mm_min = 60000/' "$work/curvejob.toml" > "$work/kmjob.toml"
expect km-pole "outside its travel" -- timeout 10 "$dtis" run "$work/kmjob.toml" -o "$work/out.csv"
printf 't,X,Y,Z\n0,0,0,0\n0.001,abc,0,0\n' > "$work/bad.csv"
expect bad-csv "bad.csv:3: column 2 ('X') is not a finite number" -- "$dtis" verify "$work/bad.csv" "$work/mikron_ucp710_xyz.toml"
expect_usage no-args "JOB is required" -- "$dtis" run
# Surface jobs.
parts="$root/samples/parts"
expect step-nc "MACHINING_SCHEMA" -- "$dtis" faces "$parts/nist_iso14649_ex1E_freeform_operation.stp"
expect not-step "not a STEP file" -- "$dtis" faces "$work/base.toml"
cat > "$work/surf.toml" <<SURF
machine = "mikron_ucp710_xyz.toml"
feed_mm_min = 3000
[surface]
file = "$parts/occt_trj8_c2-db-214_single_bspline_face.stp"
face = 3
[tool]
kind = "ball_end"
radius_mm = 3
[strategy]
kind = "plane_cl"
plane_normal = [1, 0, 0]
direction = [0, 1, 0]
stepover_mm = 2
SURF
expect bad-face "surf.toml:5: key 'surface.face': face 3 does not exist" -- "$dtis" run "$work/surf.toml" -o "$work/out.csv"
sed 's/^face = 3/face = 4294967297/' "$work/surf.toml" > "$work/bigface.toml"
expect face-2to32 "bigface.toml:5: key 'surface.face': expected a face number from 1 to 2147483647 or a face name, got 4294967297" -- "$dtis" run "$work/bigface.toml" -o "$work/out.csv"
sed 's/^face = 3/face = "pocket"/' "$work/surf.toml" > "$work/noname.toml"
expect face-name "noname.toml:5: key 'surface.face': $parts/occt_trj8_c2-db-214_single_bspline_face.stp has no face named 'pocket'; its named faces: '127' (1)" -- "$dtis" run "$work/noname.toml" -o "$work/out.csv"
sed 's/^face = 3/face = 1\ncheck_faces = [2]/' "$work/surf.toml" > "$work/check.toml"
expect check-faces "check.toml:6: key 'surface.check_faces': face 2 does not exist" -- "$dtis" run "$work/check.toml" -o "$work/out.csv"
sed 's/^face = 3/face = [1, "127"]/' "$work/surf.toml" > "$work/twice.toml"
expect face-twice "twice.toml:5: key 'surface.face': face 1 of $parts/occt_trj8_c2-db-214_single_bspline_face.stp is given twice (as 1 and '127')" -- "$dtis" run "$work/twice.toml" -o "$work/out.csv"
sed 's/^face = 3/face = 1/; s/^stepover_mm = 2/stepover_mm = 2\non_gouge = "stop"/' "$work/surf.toml" > "$work/undercut.toml"
expect undercut "undercut" -- "$dtis" run "$work/undercut.toml" -o "$work/out.csv"
sed 's/^face = 3/face = 1/; s/^stepover_mm = 2/stepover_mm = 2\nbounds_min_mm = [0, 50, 0]\nbounds_max_mm = [10, 40, 10]/' "$work/surf.toml" > "$work/bounds.toml"
expect bounds "key 'strategy.bounds_max_mm': expected bounds_min_mm below bounds_max_mm in x, y and z, got (0, 50, 0) to (10, 40, 10)" -- "$dtis" run "$work/bounds.toml" -o "$work/out.csv"
sed 's/"stop"/"maybe"/' "$work/undercut.toml" > "$work/badgouge.toml"
expect on-gouge-value "key 'strategy.on_gouge'" -- "$dtis" run "$work/badgouge.toml" -o "$work/out.csv"
# Skipping (the default), the same job runs and its summary lists what was left out.
checks=$((checks + 1))
sed '/^on_gouge/d' "$work/undercut.toml" > "$work/skip.toml"
if err=$("$dtis" run "$work/skip.toml" -o "$work/skip.csv" 2>&1) &&
  [[ "$err" == *"unreachable      "*"stretches"*"undercut: "* ]]; then
  echo "ok on-gouge-skip"
else
  echo "FAIL on-gouge-skip: $err"; failures=$((failures + 1))
fi
rm -f "$work/skip.csv"
checks=$((checks + 1))
if err=$("$dtis" stream "$work/skip.toml" --to "$work/skip.txt" --pace none 2>&1) &&
  [[ "$err" == "unreachable      "*"stretches"*"stream           complete"* ]]; then
  echo "ok on-gouge-skip-stream"
else
  echo "FAIL on-gouge-skip-stream: $err"; failures=$((failures + 1))
fi
rm -f "$work/skip.txt"
sed "s/^face = 3/face = 1\nrotate_deg = [0, 90, 0]/; s/^stepover_mm = 2/stepover_mm = 2\nrange = [500, 510]/" "$work/surf.toml" > "$work/miss.toml"
expect misses "misses the face" -- "$dtis" run "$work/miss.toml" -o "$work/out.csv"

# G-code jobs: a bad block names the program's line (and, for dtis' own reader, its column);
# nothing is written. LinuxCNC's interpreter gives its own messages.
cat > "$work/gcode_dtis.toml" <<JOB
machine = "mikron_ucp710_xyz.toml"
[path]
kind = "gcode"
file = "bad.ngc"
interpreter = "dtis"
JOB
sed '/^interpreter/d' "$work/gcode_dtis.toml" > "$work/gcode.toml"
# gcode_case NAME PROGRAM DTIS_FRAGMENT RS274_FRAGMENT: the program read by dtis' own reader and,
# when built, by LinuxCNC's interpreter (an empty fragment: not checked with that reader).
gcode_case() {
  printf '%b' "$2" > "$work/bad.ngc"
  [ -z "$3" ] || expect "$1" "$3" -- "$dtis" run "$work/gcode_dtis.toml" -o "$work/out.csv"
  [ "$rs274" != rs274 ] || [ -z "$4" ] || expect "$1-rs274" "$4" -- "$dtis" run "$work/gcode.toml" -o "$work/out.csv"
}
gcode_case gcode-arc 'G0 X0 Y0\nG1 X10 F600\nG2 X20 Y0\nM2\n' \
  "bad.ngc:3:1: an arc (G2/G3) needs I and/or J, or R" "bad.ngc:3: R i j k words all missing for arc"
gcode_case gcode-word 'G0 X0 Y0\nG1 X10 F600 Q3\nM2\n' \
  "bad.ngc:2:13: word 'Q' is not supported" "bad.ngc:2: Q word with no G5, G10, G64"
gcode_case gcode-feed 'G0 X0 Y0\nG1 X10 F0\nM2\n' \
  "bad.ngc:2:8: feed F must be positive, got 0" "bad.ngc:2: Cannot do g1 with zero feed rate"
gcode_case gcode-rotary 'G0 X0 Y0\nG1 X10 F600 A5\nM2\n' \
  "bad.ngc: the program moves rotary axis A but machine" "bad.ngc: the program moves rotary axis A but machine"
# As LinuxCNC, its interpreter wants a program's end (M2, M30 or a closing %).
gcode_case gcode-end 'G0 X0 Y0\nG1 X10 F600\n' "" \
  "bad.ngc:2: File ended with no percent sign or program end"
gcode_case gcode-exponent 'G0 X0 Y0\nG1 X1e300 F600\nM2\n' \
  "bad.ngc:2:4: word 'X1e300': G-code numbers have no exponent" "bad.ngc:2: E word with no G70"
# A tool table: applied by LinuxCNC's interpreter only, and on XYZ machines only (a 5-axis
# machine's tool length is part of its kinematics).
printf 'T1 P1 Z40\n' > "$work/tools.tbl"
printf 'G0 X0 Y0\nG43 H1\nG1 X10 F600\nM2\n' > "$work/bad.ngc"
printf 'tool_table = "tools.tbl"\n' | cat "$work/gcode_dtis.toml" - > "$work/table_dtis.toml"
expect table-dtis-reader "table_dtis.toml:6: key 'path.tool_table': tool length offsets are applied by LinuxCNC's interpreter" -- "$dtis" run "$work/table_dtis.toml" -o "$work/out.csv"
if [ "$rs274" = rs274 ]; then
  cp "$root/samples/machines/mikron_ucp710_xyzac.toml" "$work/"
  sed 's/mikron_ucp710_xyz.toml/mikron_ucp710_xyzac.toml/' "$work/gcode.toml" |
    cat - <(printf 'tool_table = "tools.tbl"\n') > "$work/table_5axis.toml"
  expect table-5-axis "bad.ngc: the tool table $work/tools.tbl gives tool length offsets" -- "$dtis" run "$work/table_5axis.toml" -o "$work/out.csv"
fi

# --planner: one of the two, and only for the VPOp interpolator.
expect_usage planner-name "--planner: warp not in {vpop,lookahead,least-time}" -- "$dtis" run "$work/line.toml" --planner warp -o "$work/out.csv"
printf '\n[interpolator]\nkind = "taylor2"\n' | cat "$work/base.toml" - > "$work/taylor.toml"
expect planner-taylor "--planner lookahead: $work/taylor.toml plans with a Taylor interpolator" -- "$dtis" run "$work/taylor.toml" --planner lookahead -o "$work/out.csv"
# A file of another kind where a job is expected: say what to do with it.
cp "$root/samples/gcode/lock.ngc" "$work/part.ngc"
expect job-is-gcode "part.ngc: a job file (TOML) is expected, and this looks like a G-code program" -- "$dtis" run "$work/part.ngc" -o "$work/out.csv"
expect job-is-step "a job file (TOML) is expected, and this looks like a STEP part; list its faces with 'dtis faces" -- "$dtis" stream "$parts/occt_trj8_c2-db-214_single_bspline_face.stp" --to /dev/null --record "$work/out.csv"
expect_usage unknown-option "argument was not expected: --bogus" -- "$dtis" verify --bogus "$work/bad.csv" "$work/mikron_ucp710_xyz.toml"
# verify: 3 when the setpoints fail the check, 1 when a file cannot be read.
printf 't,X,Y,Z\n0,0,0,0\n0.001,0,0,0\n0.002,5,0,0\n0.003,5,0,0\n' > "$work/jump.csv"
expect_status 3 verify-fails "" -- "$dtis" verify "$work/jump.csv" "$work/mikron_ucp710_xyz.toml"
expect verify-no-machine "no-machine.toml: cannot open (no such file)" -- "$dtis" verify "$work/jump.csv" "$work/no-machine.toml"

# dtis compare: only surface jobs; a bad [compare] key names the file, line and key; no table is
# left behind.
printf '\n[compare]\n' >> "$work/base.toml"
expect compare-path "only surface jobs ([surface]) are compared" -- "$dtis" compare "$work/base.toml" --csv "$work/out.csv"
sed 's/^face = 3/face = 1\nrotate_deg = [0, 90, 0]/' "$work/surf.toml" > "$work/cmp.toml"
printf '\n[compare]\ng1_tolerances_mm = [0.01, -1]\n' >> "$work/cmp.toml"
expect compare-tol "key 'compare.g1_tolerances_mm': expected tolerances > 0 mm, got -1" -- "$dtis" compare "$work/cmp.toml" --csv "$work/out.csv"

expect stream-from "--from: 2 values; machine 'Mikron UCP 710 XYZ (Beudaert 2012, Table 1)' has 3 axes" -- "$dtis" stream "$work/line.toml" --from 1,2 --to /dev/null --record "$work/out.csv"
expect stream-to "$work/no-such-dir/s.txt: cannot open the stream output" -- "$dtis" stream "$work/line.toml" --to "$work/no-such-dir/s.txt" --record "$work/out.csv"
{ cat "$work/line.toml"; printf '\n[interpolator]\nplanner = "least-time"\n'; } > "$work/least.toml"
expect stream-least-time "least.toml: [interpolator] planner = \"least-time\" plans a path whole and cannot stream it" -- "$dtis" stream "$work/least.toml" --to "$work/out.txt" --record "$work/out.csv"
expect stream-hal-channel "--to hal:x: expected hal:N, N the streamer channel 0..7" -- "$dtis" stream "$work/line.toml" --to hal:x --record "$work/out.csv"
expect report-no-plotly "cannot read plotly.js for the HTML report from '$work/no-plotly.js'" -- env DTIS_PLOTLY_JS="$work/no-plotly.js" "$dtis" run "$work/line.toml" -o "$work/out.csv" --report "$work/out.html"


# LinuxCNC INI machines: a missing jerk names the joint, the axis and the key that supplies it; an
# unknown kinematics module names the INI line; the jerk time is only for INI machines.
cat > "$work/mill.ini" <<INI
[KINS]
KINEMATICS = trivkins
[TRAJ]
COORDINATES = X Y Z
LINEAR_UNITS = inch
[JOINT_0]
MIN_LIMIT = -10
MAX_LIMIT = 10
MAX_VELOCITY = 4
MAX_ACCELERATION = 50
[JOINT_1]
MIN_LIMIT = -10
MAX_LIMIT = 10
MAX_VELOCITY = 4
MAX_ACCELERATION = 50
[JOINT_2]
MIN_LIMIT = -8
MAX_LIMIT = 0.12
MAX_VELOCITY = 2
MAX_ACCELERATION = 30
INI
sed 's|^machine = .*|machine = "mill.ini"|' "$work/line.toml" > "$work/ini_job.toml"
expect ini-no-jerk "mill.ini: neither [JOINT_0] nor [AXIS_X] gives MAX_JERK; give the job key machine_jerk_time_ms" -- "$dtis" run "$work/ini_job.toml" -o "$work/out.csv"
expect import-no-jerk "mill.ini: neither [JOINT_0] nor [AXIS_X] gives MAX_JERK" -- "$dtis" machine import "$work/mill.ini" -o "$work/out.toml"
sed 's/trivkins/genhexkins/' "$work/mill.ini" > "$work/hex.ini"
expect import-kins "hex.ini:2: [KINS] KINEMATICS: kinematics 'genhexkins' is not one dtis models" -- "$dtis" machine import "$work/hex.ini" --jerk-time-ms 20 -o "$work/out.toml"
printf 'machine_jerk_time_ms = 20\n' | cat - "$work/line.toml" > "$work/toml_jerk.toml"
expect jerk-time-toml "toml_jerk.toml:1: key 'machine_jerk_time_ms': only used with a LinuxCNC INI machine" -- "$dtis" run "$work/toml_jerk.toml" -o "$work/out.csv"
expect_usage import-jerk-negative "--jerk-time-ms" -- "$dtis" machine import "$work/mill.ini" --jerk-time-ms -5 -o "$work/out.toml"
# The same machine with the jerk time: it plans, verifies against the INI, and imports to a file
# that verifies the same setpoints.
printf 'machine_jerk_time_ms = 20\n' | cat - "$work/ini_job.toml" > "$work/ini_ok.toml"
checks=$((checks + 1))
if "$dtis" run "$work/ini_ok.toml" -o "$work/ini.csv" -q &&
  "$dtis" verify "$work/ini.csv" "$work/mill.ini" --jerk-time-ms 20 >/dev/null &&
  "$dtis" machine import "$work/mill.ini" --jerk-time-ms 20 -o "$work/mill.toml" &&
  "$dtis" verify "$work/ini.csv" "$work/mill.toml" >/dev/null &&
  "$dtis" report "$work/ini.csv" "$work/mill.ini" --jerk-time-ms 20 -o "$work/ini.html" >/dev/null 2>&1 &&
  test -s "$work/ini.html"; then
  echo "ok ini-machine-plans"
else
  echo "FAIL ini-machine-plans"; failures=$((failures + 1))
fi
expect report-ini-no-jerk "mill.ini: neither [JOINT_0] nor [AXIS_X] gives MAX_JERK" -- "$dtis" report "$work/ini.csv" "$work/mill.ini" -o "$work/out.html"
expect serve-ini-no-jerk "mill.ini: neither [JOINT_0] nor [AXIS_X] gives MAX_JERK" -- "$dtis" serve --machine "$work/mill.ini" --socket "$work/ini.sock" --to /dev/null
# dtis serve on the INI machine with --jerk-time-ms takes the job planned for it and verifies it.
checks=$((checks + 1))
"$dtis" serve --machine "$work/mill.ini" --jerk-time-ms 20 --socket "$work/ini.sock" --to /dev/null \
  --pace none 2>"$work/serve.err" &
serve_pid=$!
for _ in $(seq 100); do [ -S "$work/ini.sock" ] && break; sleep 0.05; done
served=
if "$dtis" send --socket "$work/ini.sock" "{\"cmd\":\"submit\",\"job\":\"$work/ini_ok.toml\"}" >/dev/null; then
  for _ in $(seq 200); do
    status=$("$dtis" send --socket "$work/ini.sock" '{"cmd":"status"}' || true)
    if [[ "$status" == *'"end":"complete"'*'"verified":true'* ]]; then served=yes; break; fi
    sleep 0.05
  done
fi
kill "$serve_pid" 2>/dev/null; wait "$serve_pid" 2>/dev/null
if [ -n "$served" ]; then
  echo "ok serve-ini-machine"
else
  echo "FAIL serve-ini-machine: ${status:-no status} $(cat "$work/serve.err")"; failures=$((failures + 1))
fi

# Outputs a job names stay in the current folder; a setpoint file too short to verify is named.
printf '[output]\nsetpoints = "../escape.csv"\n' | cat "$work/line.toml" - > "$work/escape.toml"
expect output-escape "escape.toml:8: key 'output.setpoints': expected a path inside the current folder" -- "$dtis" run "$work/escape.toml"
printf '[output]\nlimiters = "/tmp/x.csv"\n' | cat "$work/line.toml" - > "$work/abs.toml"
expect output-absolute "key 'output.limiters': expected a path inside the current folder" -- "$dtis" run "$work/abs.toml" -o "$work/out.csv"
printf 't,X,Y,Z\n0,0,0,0\n' > "$work/one_row.csv"
expect verify-one-row "one_row.csv: a setpoint sequence needs at least 2 rows, got 1" -- "$dtis" verify "$work/one_row.csv" "$work/mikron_ucp710_xyz.toml"
expect report-one-row "one_row.csv: a setpoint sequence needs at least 2 rows" -- "$dtis" report "$work/one_row.csv" "$work/mikron_ucp710_xyz.toml" -o "$work/out.html"

# Reports: a limiter report of another run, or a malformed one, names the file and line; a report
# needs a machine; figures name the report, the format or the browser that failed.
"$dtis" run "$work/line.toml" -o "$work/line.csv" --limiters "$work/line_lim.csv" -q
head -n 100 "$work/line_lim.csv" > "$work/short_lim.csv"
expect report-limiters-rows "short_lim.csv: 99 rows; the setpoint file $work/line.csv has" -- "$dtis" report "$work/line.csv" "$work/mikron_ucp710_xyz.toml" --limiters "$work/short_lim.csv" -o "$work/out.html"
sed '3s/,[a-z_]*,\([A-Z]*\)$/,warp,\1/' "$work/line_lim.csv" > "$work/warp_lim.csv"
expect report-limiters-name "warp_lim.csv:3: column 4: unknown limiter 'warp'" -- "$dtis" report "$work/line.csv" "$work/mikron_ucp710_xyz.toml" --limiters "$work/warp_lim.csv" -o "$work/out.html"
expect report-no-machine "give the MACHINE file, or --job" -- "$dtis" report "$work/line.csv" -o "$work/out.html"
expect stream-report-no-plotly "cannot read plotly.js" -- env DTIS_PLOTLY_JS="$work/no-plotly.js" "$dtis" stream "$work/line.toml" --to /dev/null --record "$work/out.csv" --report "$work/out.html"
expect figures-missing "$work/no-such.html: no such report" -- "$dtis" figures "$work/no-such.html" -o "$work/out"
printf '<!DOCTYPE html><html><body>not a report</body></html>\n' > "$work/page.html"
expect figures-format "figure format 'gif': expected png, svg, jpeg or webp" -- "$dtis" figures "$work/page.html" --format png,gif -o "$work/out"
expect figures-browser "cannot run $work/no-chromium" -- env DTIS_CHROMIUM="$work/no-chromium" "$dtis" figures "$work/page.html" -o "$work/out"
if command -v chromium >/dev/null; then
  expect figures-page "page.html: the browser (" -- "$dtis" figures "$work/page.html" -o "$work/out"
fi

# Outputs that are not files: a device or a FIFO is written in place, never renamed over (as
# root, a rename replaced /dev/null with a file); a failed write is an error naming the file,
# leaving no other output; a job's name keeps its outputs in the current folder.
device_kept() {  # device_kept NAME PATH TYPE(c|p)
  checks=$((checks + 1))
  local kept=no
  if [ "$3" = c ]; then [ -c "$2" ] && kept=yes; else [ -p "$2" ] && kept=yes; fi
  if [ $kept = yes ]; then
    echo "ok $1"
  else
    echo "FAIL $1: $2 is no longer a $( [ "$3" = c ] && echo device || echo FIFO)"; failures=$((failures + 1))
  fi
}
expect_status 0 out-devnull "" -- "$dtis" run "$work/line.toml" -o /dev/null
device_kept out-devnull-kept /dev/null c
expect_status 0 limiters-devnull "" -- "$dtis" run "$work/line.toml" -o "$work/kept.csv" --limiters /dev/null
device_kept limiters-devnull-kept /dev/null c
rm -f "$work/kept.csv"
expect_status 0 record-devnull "" -- "$dtis" stream "$work/line.toml" --to /dev/null --record /dev/null -q
expect_status 0 import-devnull "" -- "$dtis" machine import "$work/mikron_ucp710_xyz.toml" -o /dev/null
device_kept import-devnull-kept /dev/null c
if [ -c /dev/full ] && [ -w /dev/full ]; then
  expect out-devfull "/dev/full: write failed (No space left on device)" -- "$dtis" run "$work/line.toml" -o /dev/full
  expect limiters-devfull "/dev/full: write failed (No space left on device)" -- "$dtis" run "$work/line.toml" -o "$work/out.csv" --limiters /dev/full
  expect record-devfull "/dev/full: write failed (No space left on device)" -- "$dtis" stream "$work/line.toml" --to /dev/null --record /dev/full -q
  expect import-devfull "/dev/full: write failed (No space left on device)" -- "$dtis" machine import "$work/mikron_ucp710_xyz.toml" -o /dev/full
  if [ -s "${DTIS_PLOTLY_JS:-$root/tools/report/node_modules/plotly.js-dist-min/plotly.min.js}" ]; then
    expect report-devfull "/dev/full: write failed (No space left on device)" -- "$dtis" run "$work/line.toml" -o "$work/out.csv" --report /dev/full
  fi
  device_kept devfull-kept /dev/full c
fi
# A FIFO stays a FIFO, and what reads it gets the setpoints.
mkfifo "$work/setpoints.fifo"
cat "$work/setpoints.fifo" > "$work/from_fifo.txt" &
fifo_reader=$!
expect_status 0 out-fifo "" -- timeout 20 "$dtis" run "$work/line.toml" -o "$work/setpoints.fifo" -q
wait "$fifo_reader"
device_kept out-fifo-kept "$work/setpoints.fifo" p
checks=$((checks + 1))
if [ "$(head -n 1 "$work/from_fifo.txt")" = "t,X,Y,Z" ] && [ "$(wc -l < "$work/from_fifo.txt")" -gt 1000 ]; then
  echo "ok out-fifo-read"
else
  echo "FAIL out-fifo-read: the reader got $(wc -l < "$work/from_fifo.txt") lines"; failures=$((failures + 1))
fi
# A job's name places NAME.csv: never outside the current folder, never nameless.
mkdir -p "$work/jobs/a/b"
for case in "escape ../../out_escape" "absolute $work/out_absolute" "empty "; do
  label=${case%% *} name=${case#* }
  printf 'name = "%s"\n' "$name" | cat - "$work/line.toml" > "$work/jobs/name_$label.toml"
  expect "name-$label" "name_$label.toml:1: key 'name': expected a name for the outputs (NAME.csv) inside the current folder" -- env -C "$work/jobs/a/b" "$dtis" run "$work/jobs/name_$label.toml" -q
done
checks=$((checks + 1))
if [ -z "$(find "$work" -name '*.csv' -newer "$work/jobs/name_empty.toml" ! -path "$work/from_fifo.txt")" ]; then
  echo "ok name-nothing-written"
else
  echo "FAIL name-nothing-written: $(find "$work" -name '*.csv' -newer "$work/jobs/name_empty.toml")"; failures=$((failures + 1))
fi
# --jerk-time-ms on run, stream and compare, as the job key: an INI job without MAX_JERK runs.
if "$dtis" run "$work/ini_job.toml" --jerk-time-ms 20 -o "$work/ini_cli.csv" -q &&
  "$dtis" verify "$work/ini_cli.csv" "$work/mill.ini" --jerk-time-ms 20 >/dev/null &&
  "$dtis" run "$work/ini_ok.toml" -o "$work/ini_key.csv" -q && cmp -s "$work/ini_cli.csv" "$work/ini_key.csv" &&
  "$dtis" stream "$work/ini_job.toml" --jerk-time-ms 20 --to /dev/null --record "$work/ini_stream.csv" -q &&
  "$dtis" verify "$work/ini_stream.csv" "$work/mill.ini" --jerk-time-ms 20 >/dev/null; then
  echo "ok ini-job-jerk-time-option"
else
  echo "FAIL ini-job-jerk-time-option"; failures=$((failures + 1))
fi
checks=$((checks + 1))
expect run-jerk-time-toml "--jerk-time-ms: only used with a LinuxCNC INI machine" -- "$dtis" run "$work/line.toml" --jerk-time-ms 20 -o "$work/out.csv"
expect_usage compare-jerk-time-negative "--jerk-time-ms" -- "$dtis" compare "$work/line.toml" --jerk-time-ms -1
# Where a G-code program starts: --from on run, for G-code jobs only.
printf 'G21 G90\nG1 X10 F600\nM2\n' > "$work/first_cut.ngc"
printf 'machine = "mikron_ucp710_xyz.toml"\n[path]\nkind = "gcode"\nfile = "first_cut.ngc"\ninterpreter = "dtis"\n' > "$work/first_cut.toml"
expect run-from-not-gcode "--from: $work/line.toml is not a G-code job" -- "$dtis" run "$work/line.toml" --from 0,0,0 -o "$work/out.csv"
expect run-from-count "--from: 2 values; machine" -- "$dtis" run "$work/first_cut.toml" --from 0,0 -o "$work/out.csv"
checks=$((checks + 1))
if "$dtis" run "$work/first_cut.toml" --from -5,0,0 -o "$work/first_cut.csv" 2>"$work/first_cut.err" &&
  grep -q "path 15 mm" "$work/first_cut.err" && grep -q "1 contour, 0 rapids" "$work/first_cut.err"; then
  echo "ok run-from-plans-the-first-cut"
else
  echo "FAIL run-from-plans-the-first-cut: $(cat "$work/first_cut.err")"; failures=$((failures + 1))
fi
# Bounds: every run's work is bounded from the job before planning, nonsense is refused and
# messages name the key. Each case is a clean error (exit 1, or 2 for the command line) within
# 10 s and 500 MB of address space, run from an empty folder that stays empty.
mkdir -p "$work/cwd"
bounded_case() {  # bounded_case STATUS NAME FRAGMENT -- command...
  local want=$1 name=$2 fragment=$3
  shift 4
  cd "$work/cwd" || return
  expect_status "$want" "$name" "$fragment" -- prlimit --as=$((500 << 20)) -- timeout 10 "$@"
  cd - >/dev/null || return
  if [ -n "$(ls -A "$work/cwd")" ]; then
    echo "FAIL $name: wrote $(ls -A "$work/cwd") in the current folder"; failures=$((failures + 1))
    rm -rf "$work/cwd" && mkdir -p "$work/cwd"
  fi
}
# Motion time: tangential limits, feeds, rapids, dwells and Taylor ramps, before planning.
printf '[tangential]\nacceleration_mm_s2 = 1e-6\n' | cat "$work/line.toml" - > "$work/tacc.toml"
bounded_case 1 tiny-tangential-acceleration "tacc.toml: the path (100 mm) takes at least 5.56 h with [tangential] acceleration_mm_s2 = 1e-06: 2e+07 setpoints at 1 ms, more than the 10 million" -- "$dtis" run "$work/tacc.toml" -o "$work/out.csv"
printf '[tangential]\njerk_mm_s3 = 1e-9\n' | cat "$work/line.toml" - > "$work/tjerk9.toml"
bounded_case 1 tiny-tangential-jerk "with [tangential] jerk_mm_s3 = 1e-09: 1.47e+07 setpoints" -- "$dtis" run "$work/tjerk9.toml" -o "$work/out.csv"
cp "$root/samples/curves/nurbs_circle.toml" "$work/circle_curve.toml"
sed 's|^file = .*|file = "circle_curve.toml"|; s|^machine = .*|machine = "mikron_ucp710_xyz.toml"|; s/^accel_time_s = .*/accel_time_s = 1e9/' \
  "$root/samples/jobs/circle_taylor.toml" > "$work/taylor_ramp.toml"
bounded_case 1 taylor-accel-time "taylor_ramp.toml: the path (314.159 mm) takes at least 5.56e+05 h with [interpolator] accel_time_s = 1e+09, more than the 24 h a job may take" -- "$dtis" run "$work/taylor_ramp.toml" -o "$work/out.csv"
# G-code: the least time of the program's moves, rapids and dwells, naming the block; loops and
# long programs bounded by [path] max_blocks (each repetition of a loop counted).
for reader in dtis rs274; do
  [ $reader = dtis ] && job="$work/gcode_dtis.toml" || job="$work/gcode.toml"
  [ $reader = dtis ] || [ "$rs274" = rs274 ] || continue
  printf 'G0 X0 Y0\nG1 X5 F0.0001\nM2\n' > "$work/bad.ngc"
  bounded_case 1 "crawling-F-$reader" "bad.ngc:2: the program takes at least 833 h up to this block, more than the 24 h a job may take; this block alone takes 833 h: its move of 5 mm at F0.0001 mm/min" -- "$dtis" run "$job" -o "$work/out.csv"
  printf 'rapid_feed_mm_min = 1e-9\n' | cat "$job" - > "$work/rapid_$reader.toml"
  printf 'G0 X0 Y0\nG1 X5 F600\nG0 X10\nM2\n' > "$work/bad.ngc"
  bounded_case 1 "crawling-rapid-$reader" "bad.ngc:3: the program takes at least 8.33e+07 h up to this block, more than the 24 h a job may take; this block alone takes 8.33e+07 h: its rapid of 5 mm at 1e-09 mm/min ([path] rapid_feed_mm_min" -- "$dtis" run "$work/rapid_$reader.toml" -o "$work/out.csv"
  # A whole circle ends where it starts: its sweep, not its chord (0), is what it takes.
  printf 'G17 G0 X-5 Y0\nG2 X-5 Y0 I5 F0.001\nM2\n' > "$work/bad.ngc"
  bounded_case 1 "crawling-circle-$reader" "bad.ngc:2: the program takes at least 524 h up to this block, more than the 24 h a job may take; this block alone takes 524 h: its move of 31.4159 mm at F0.001 mm/min" -- "$dtis" run "$job" -o "$work/out.csv"
done
awk 'BEGIN { print "G0 X0 Y0"; for (i = 0; i < 1000000; i++) printf "G1 X%d Y%d F1000\n", i % 2, (i / 2) % 2; print "M2" }' > "$work/million.ngc"
sed 's/bad.ngc/million.ngc/' "$work/gcode_dtis.toml" > "$work/million.toml"
bounded_case 1 million-blocks "million.ngc:200001: the program runs more than 200000 blocks (each repetition of a loop counted), the most it may run here; max_blocks in the [path] of $work/million.toml raises it" -- "$dtis" run "$work/million.toml" -o "$work/out.csv"
printf 'G0 X0 Y0\no100 while [1]\nG1 X10 F600\nG1 X0\no100 endwhile\nM2\n' > "$work/bad.ngc"
bounded_case 1 while-loop-dtis "bad.ngc:2:1: O-words (subroutines, loops, conditionals) are not read by dtis' reader" -- "$dtis" run "$work/gcode_dtis.toml" -o "$work/out.csv"
if [ "$rs274" = rs274 ]; then
  bounded_case 1 while-loop-moves "the program runs more than 200000 blocks (each repetition of a loop counted)" -- "$dtis" run "$work/gcode.toml" -o "$work/out.csv"
  printf 'G0 X0 Y0\nG1 X10 F600\no100 while [1]\no100 endwhile\nM2\n' > "$work/bad.ngc"
  bounded_case 1 while-loop-still "bad.ngc:3: the program runs more than 200000 blocks (each repetition of a loop counted)" -- "$dtis" run "$work/gcode.toml" -o "$work/out.csv"
  printf 'G0 X0 Y0\nG1 X10 F600\nG4 P100000\nG1 X20\nM2\n' > "$work/bad.ngc"
  bounded_case 1 long-dwell "bad.ngc:4: the program takes at least 27.8 h up to this block, more than the 24 h a job may take; this block alone takes 27.8 h: a dwell (G4) of 100000 s before it" -- "$dtis" run "$work/gcode.toml" -o "$work/out.csv"
fi
# Surfaces: strategy lines bounded before any is traced.
sed 's/^face = 3/face = 1/; s/^stepover_mm = 2/stepover_mm = 0.000001/' "$work/surf.toml" > "$work/finestep.toml"
bounded_case 1 tiny-stepover "finestep.toml:13: key 'strategy.stepover_mm': 1.66e+07 strategy lines, 1e-06 mm apart across [-9.40694, 7.16983] mm along the plane normal, more than the 10000 a face is traced with" -- "$dtis" run "$work/finestep.toml" -o "$work/out.csv"
sed 's/^face = 3/face = 1/; s/^stepover_mm = 2/stepover_mm = 2\nrange = [-1e300, 1e300]/' "$work/surf.toml" > "$work/hugerange.toml"
bounded_case 1 huge-range "hugerange.toml:14: key 'strategy.range': 1e+300 strategy lines, 2 mm apart across the range [-1e+300, 1e+300] mm, more than the 10000 a face is traced with" -- "$dtis" run "$work/hugerange.toml" -o "$work/out.csv"
# Nonsense refused, naming the key and what was expected.
printf '[interpolator]\nend_tolerance_mm = 1e6\n' | cat "$work/line.toml" - > "$work/endtol.toml"
bounded_case 1 end-tolerance "endtol.toml:8: key 'interpolator.end_tolerance_mm': expected a distance up to 0.01 mm, got 1e+06" -- "$dtis" run "$work/endtol.toml" -o "$work/out.csv"
printf '[interpolator]\ncommit_horizon = 1099511627776\n' | cat "$work/line.toml" - > "$work/horizon.toml"
bounded_case 1 commit-horizon "horizon.toml:8: key 'interpolator.commit_horizon': expected 8 to 1073741824 periods (2^30), got 1099511627776" -- "$dtis" run "$work/horizon.toml"
printf 'name = ""\n' | cat - "$work/line.toml" > "$work/noname_job.toml"
bounded_case 1 empty-name "noname_job.toml:1: key 'name': expected a name for the outputs (NAME.csv) inside the current folder" -- "$dtis" run "$work/noname_job.toml"
printf 'degree = 2\nknots = [0, 0, 0, 1, 1, 1]\npoles = [[1, 2], [1, 2], [1, 2]]\n' > "$work/point_curve.toml"
sed 's/knots.toml/point_curve.toml/' "$work/curvejob.toml" > "$work/pointjob.toml"
bounded_case 1 coincident-poles "point_curve.toml:3: key 'poles': all 3 poles coincide at (1, 2, 0): the curve has zero length" -- "$dtis" run "$work/pointjob.toml" -o "$work/out.csv"
bounded_case 1 jerk-time-tiny "mill.ini: jerk time (machine_jerk_time_ms or --jerk-time-ms) 1e-300 ms: expected a time from 0.1 to 10000 ms" -- "$dtis" machine import "$work/mill.ini" --jerk-time-ms 1e-300 -o "$work/out.toml"
bounded_case 2 jerk-time-nan "--jerk-time-ms: expected a finite number > 0, got 'nan'" -- "$dtis" machine import "$work/mill.ini" --jerk-time-ms nan -o "$work/out.toml"
printf 'machine_jerk_time_ms = 1e-300\n' | cat - "$work/ini_job.toml" > "$work/ini_tiny.toml"
bounded_case 1 jerk-time-key "ini_tiny.toml:1: key 'machine_jerk_time_ms': expected a time from 0.1 to 10000 ms, got 1e-300" -- "$dtis" run "$work/ini_tiny.toml" -o "$work/out.csv"
sed 's/^KINEMATICS = trivkins/KINEMATICS = trivkins\nJOINTS = 1000000000/' "$work/mill.ini" > "$work/joints.ini"
bounded_case 1 ini-joints "joints.ini:3: [KINS] JOINTS: expected a whole number of joints from 1 to 16 (LinuxCNC's most), got '1000000000'" -- "$dtis" machine import "$work/joints.ini" --jerk-time-ms 20 -o "$work/out.toml"
printf '[AXIS_X]\nMAX_VELOCITY = 1\n[AXIS_X]\nMAX_VELOCITY = 9\n' | cat "$work/mill.ini" - > "$work/twice.ini"
bounded_case 1 ini-section-twice "twice.ini:23: [AXIS_X] appears a second time (first at $work/twice.ini:21); LinuxCNC reads only the first" -- "$dtis" machine import "$work/twice.ini" --jerk-time-ms 20 -o "$work/out.toml"
# Messages: the file a link loop stands for, the key that makes a period too short, short
# numbers in option errors, what a path given to `dtis faces` is.
ln -s "$work/loop.toml" "$work/loop.toml"
bounded_case 1 job-link-loop "loop.toml: cannot open: too many levels of symbolic links" -- "$dtis" run "$work/loop.toml" -o "$work/out.csv"
sed 's|^machine = .*|machine = "loop.toml"|' "$work/line.toml" > "$work/loop_machine.toml"
bounded_case 1 machine-link-loop "loop.toml: cannot open: too many levels of symbolic links" -- "$dtis" run "$work/loop_machine.toml" -o "$work/out.csv"
sed 's/knots.toml/loop.toml/' "$work/curvejob.toml" > "$work/loop_curve.toml"
bounded_case 1 curve-link-loop "loop.toml: cannot open: too many levels of symbolic links" -- "$dtis" run "$work/loop_curve.toml" -o "$work/out.csv"
printf '[interpolator]\nlimit_fraction = 1e-300\n' | cat "$work/line.toml" - > "$work/fraction.toml"
bounded_case 1 tiny-limit-fraction "fraction.toml: [interpolator] limit_fraction = 1e-300: at period_ms = 1 rounding the written positions of axis X" -- "$dtis" run "$work/fraction.toml" -o "$work/out.csv"
sed 's/acceleration = 2.5$/acceleration = 1e-300/' "$work/mikron_ucp710_xyz.toml" > "$work/tinyacc.toml"
sed 's/mikron_ucp710_xyz.toml/tinyacc.toml/' "$work/line.toml" > "$work/tinyacc_job.toml"
bounded_case 1 tiny-axis-acceleration "tinyacc.toml: axis X's acceleration limit (1e-297 mm/s^2) is too small to plan at any period up to 100 ms" -- "$dtis" run "$work/tinyacc_job.toml" -o "$work/out.csv"
printf 'period_ms = 0.01\n' | cat - "$work/line.toml" > "$work/short_period.toml"
bounded_case 1 period-mikron "short_period.toml: period_ms = 0.01 is shorter than machine 'Mikron UCP 710 XYZ (Beudaert 2012, Table 1)' allows: rounding the written positions of axis X (near 400 mm) would eat more than 0.1 % of its jerk limit (5000 mm/s^3); expected period_ms of at least 0.166" -- "$dtis" run "$work/short_period.toml" -o "$work/out.csv"
checks=$((checks + 1))
err=$("$dtis" run "$work/line.toml" --threads -1 -o "$work/out.csv" 2>&1 >/dev/null)
if [[ "$err" == *"--threads: expected a finite number >= 0, got '-1'"* ]] && [ ${#err} -lt 400 ]; then
  echo "ok option-range-short"
else
  echo "FAIL option-range-short: $err"; failures=$((failures + 1))
fi
bounded_case 1 faces-directory "$work: is a directory, not a file" -- "$dtis" faces "$work"
bounded_case 1 faces-fifo "fifo.toml: is a FIFO, not a file" -- "$dtis" faces "$work/fifo.toml"
bounded_case 1 faces-device "/dev/zero: is a device, not a file" -- "$dtis" faces /dev/zero

# Surface jobs' set-up: a part placed beyond the machine's travel is refused before any pass is
# planned (the sample face's passes reach x = 400.25 mm), naming the pass and the axis; a face is
# chosen among those of one name by "name#N".
sed 's/^face = 3/face = 1\nrotate_deg = [0, 90, 0]\ntranslate_mm = [336, 0, 0]/; s/^stepover_mm = 2/stepover_mm = 0.5/' "$work/surf.toml" > "$work/travel.toml"
expect surface-out-of-travel "travel.toml: pass 152: cannot follow the path at $parts/occt_trj8_c2-db-214_single_bspline_face.stp face 1 ('127'), pass 152" -- timeout 10 "$dtis" run "$work/travel.toml" -o "$work/out.csv"
expect surface-out-of-travel-axis "axis X would have to reach 400.254 mm, 0.254 mm outside its travel [-400, 400] mm (found before planning)" -- timeout 10 "$dtis" run "$work/travel.toml" -o "$work/out.csv"
expect stream-out-of-travel "travel.toml: pass 152: cannot follow the path at" -- timeout 10 "$dtis" stream "$work/travel.toml" --to "$work/out.txt"
expect compare-out-of-travel "travel.toml: pass 152: cannot follow the path at" -- timeout 10 "$dtis" compare "$work/travel.toml" --csv "$work/out.csv"
sed 's/^face = 3/face = "127#2"/' "$work/surf.toml" > "$work/nth.toml"
expect face-name-nth "nth.toml:5: key 'surface.face': $parts/occt_trj8_c2-db-214_single_bspline_face.stp has 1 face named '127' ('127#1' to '127#1', in the file's order); there is no '127#2'" -- "$dtis" run "$work/nth.toml" -o "$work/out.csv"

echo "$((checks - failures)) passed, $failures failed"
[ $failures -eq 0 ]
