#!/usr/bin/env bash
# The memory of `dtis stream` does not grow with the job's length: a G1 raster of 6 rows
# (about 1 minute at F600) and one of 60 rows (about 10 minutes, 600 000 setpoints) are streamed
# as fast as the output takes them; their peak resident memory (max RSS) must differ by less than
# 8 MB, where keeping the setpoints would take 50 MB more (`dtis run` holds 314 MB for the long one).
# Nor with the program's length: 5 000 and 50 000 blocks of 0.2 mm whose feed alternates
# (one chain, rest to rest, per block) on a machine fast enough to run a block in a few periods:
# holding the program took 50 MB more for the long one (1 KB per block). Nor with one chain's
# length: 5 000 and 50 000 blocks at one feed, rows joined by a step in Y, form a single chain
# (as a CAM finishing program does); chains longer than window_blocks are smoothed as they are
# planned and dropped behind (30.8 and 84.8 MB when held whole, window_blocks = 0).
set -euo pipefail
dtis=$1
root=$2
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

raster() {  # rows, file
  {
    echo "G21 G90 G17"
    echo "G0 X0 Y0 Z5"
    echo "G1 Z0 F600"
    for ((k = 0; k < $1; k++)); do
      x=$((k % 2 == 0 ? 100 : 0))
      echo "G1 X$x Y$k"
      echo "G1 X$x Y$((k + 1))"
    done
    echo "G0 Z5"
    echo "M2"
  } >"$2"
}
peak_kb() {  # job: streams it, prints the peak resident memory in kB (the kernel's count at exit:
  # sampling /proc while it ran missed the peak of short jobs)
  /usr/bin/time -f %M -o "$out/peak.txt" "$dtis" stream "$1" --to /dev/null --pace none -q
  cat "$out/peak.txt"
}
gcode_job() {  # name, machine file, period in ms: $out/name.toml, for $out/name.ngc
  cat >"$out/$1.toml" <<EOF
machine = "$2"
period_ms = $3
[path]
kind = "gcode"
file = "$1.ngc"
contour_tol_mm = 0.02
EOF
}
flat() {  # short job, long job, what each is: their peaks differ by less than 8 MB
  local short long
  short=$(peak_kb "$out/$1.toml")
  long=$(peak_kb "$out/$2.toml")
  echo "stream memory: peak $short kB for $3, $long kB for $4"
  test "$short" -gt 0
  test "$((long - short))" -lt 8192
}

for rows in 6 60; do
  raster "$rows" "$out/raster$rows.ngc"
  gcode_job "raster$rows" "$root/samples/machines/mikron_ucp710_xyz.toml" 1.0
done
flat raster6 raster60 "~1 min of motion" "~10 min"

sed -e 's/^velocity = .*/velocity = 60/' -e 's/^acceleration = .*/acceleration = 20/' \
  -e 's/^jerk = .*/jerk = 500/' "$root/samples/machines/mikron_ucp710_xyz.toml" >"$out/fast.toml"
for blocks in 5000 50000; do
  # Rows of 1 000 blocks along X (200 mm), one row per mm of Y, back and forth: within travel.
  awk -v n="$blocks" 'BEGIN {
    print "G21 G90 G17"; print "G0 X0 Y0 Z0"
    for (k = 1; k <= n; k++) {
      row = int(k / 1000); i = k % 1000
      printf "G1 X%.1f Y%d F%d\n", (row % 2 == 0 ? i : 1000 - i) * 0.2, row, (k % 2 == 0 ? 6000 : 5000)
    }
    print "M2"
  }' >"$out/blocks$blocks.ngc"
  gcode_job "blocks$blocks" fast.toml 10.0
done
flat blocks5000 blocks50000 "5 000 blocks" "50 000"

for blocks in 5000 50000; do
  # One chain: rows of 1 000 blocks along X (200 mm), each next row 0.5 mm up in Y, back and forth.
  awk -v n="$blocks" 'BEGIN {
    print "G21 G90 G17"; print "G0 X0 Y0 Z0"; print "G1 X0.2 F6000"
    for (k = 2; k <= n; k++) {
      row = int(k / 1000); i = k % 1000
      printf "G1 X%.1f Y%.1f\n", (row % 2 == 0 ? i : 1000 - i) * 0.2, row * 0.5
    }
    print "M2"
  }' >"$out/chain$blocks.ngc"
  gcode_job "chain$blocks" fast.toml 10.0
done
flat chain5000 chain50000 "one chain of 5 000 blocks" "one of 50 000"
