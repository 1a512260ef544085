#!/usr/bin/env bash
# dtis stream through real LinuxCNC HAL. A headless HAL session runs a 1 ms servo thread
# with streamer.0 -> sampler.0; `dtis stream` feeds halstreamer in real time and halsampler records
# every period. Checks, on a 5-axis sample job:
#   - every period from the first streamed row on holds the next row, none skipped or repeated
#     until the end (the u32 index column), and its positions are the planned ones to halsampler's
#     6 printed decimals;
#   - what was planned for the stream is byte for byte what `dtis run --horizon` plans;
#   - the stream passes `dtis verify`; so does a stream killed (SIGTERM) mid-pass, which ends with
#     the stop to rest, and one whose planner is made too slow (an underrun), read back from HAL.
# With HAL_CAPTURE (the native sink is built), also through `--to hal:0`, dtis writing into the
# streamer's FIFO itself: HAL's samples, read at full precision, equal the plan exactly and pass
# `dtis verify` themselves, for a whole job and for one killed mid-pass.
# Usage: linuxcnc_stream.sh DTIS ROOT [OUTDIR [HAL_CAPTURE]]  (OUTDIR keeps the recordings; "" or
# none: a temp dir). STREAM_JOB and STREAM_MACHINE name another job and its machine (the serial
# arm's open pocket: six joints streamed), STREAM_BUFFER the periods kept ahead (default 200; the
# arm's planner runs at a few times real time only, and backs off in bursts).
set -euo pipefail
dtis=$1
root=$2
keep=${3:-}
out=${3:-$(mktemp -d)}
capture=${4:-}
mkdir -p "$out"
job=${STREAM_JOB:-$root/samples/jobs/surface_tilt10_xyzac.toml}
machine=${STREAM_MACHINE:-$root/samples/machines/mikron_ucp710_xyzac.toml}
horizon=256

# LinuxCNC 2.9 from Debian, without the RT kernel and GUIs it recommends.
if ! command -v halcmd >/dev/null || ! command -v halstreamer >/dev/null; then
  if [ "$(id -u)" != 0 ]; then
    echo "linuxcnc_stream: halcmd missing and not root: install linuxcnc-uspace" >&2
    exit 1
  fi
  echo "installing linuxcnc-uspace ..."
  install() {
    DEBIAN_FRONTEND=noninteractive timeout 600 apt-get install -y -q --no-install-recommends \
      linuxcnc-uspace >>"$out/apt.log" 2>&1
  }
  # The package lists may be missing or stale on a fresh machine: update once and retry.
  install || { timeout 600 apt-get update -qq >>"$out/apt.log" 2>&1 && install; } ||
    { tail -20 "$out/apt.log" >&2; exit 1; }
fi

# rtapi_app refuses plain root: it runs as RTAPI_UID, with its socket where that user can write.
if [ "$(id -u)" = 0 ]; then
  id dtis-hal >/dev/null 2>&1 || useradd --system --no-create-home --shell /usr/sbin/nologin dtis-hal
  export RTAPI_UID
  RTAPI_UID=$(id -u dtis-hal)
  hal_user=dtis-hal
else
  hal_user=$(id -un)
fi
rtdir=$(mktemp -d /tmp/dtis-rtapi.XXXXXX)
chown "$hal_user" "$rtdir"
chmod 700 "$rtdir"
export RTAPI_FIFO_PATH=$rtdir/rtapi

# Only one HAL session per host: serialize with any other test that starts one.
exec 9>/tmp/dtis-hal.lock
timeout 600 flock 9

stop_hal() {
  timeout 20 halcmd stop >/dev/null 2>&1 || true
  timeout 20 halcmd unload all >/dev/null 2>&1 || true
  timeout 20 halrun -U >/dev/null 2>&1 || true
}
cleanup() {
  stop_hal
  rm -rf "$rtdir"
  [ -n "$keep" ] || rm -rf "$out"
}
trap cleanup EXIT
stop_hal

axes=$(sed -n 's/^\[axes\.\(.*\)\]/\1/p' "$machine" | tr '\n' ' ')
naxes=$(echo "$axes" | wc -w)
cfg=$(printf 'f%.0s' $(seq "$naxes"))u

# Starts a HAL session: streamer (depth chosen not to divide typical lengths) then sampler, in
# that order on one 1 ms thread, and halsampler (or the command in RECORDER) recording into $1.
start_hal() {
  local hal=$out/stream.hal
  {
    echo "loadrt threads name1=servo period1=1000000"
    echo "loadrt streamer depth=1021 cfg=$cfg"
    echo "loadrt sampler depth=8191 cfg=$cfg"
    echo "addf streamer.0 servo"
    echo "addf sampler.0 servo"
    for i in $(seq 0 "$naxes"); do echo "net p$i streamer.0.pin.$i sampler.0.pin.$i"; done
    echo "start"
  } >"$hal"
  timeout 60 halcmd -f "$hal" >"$out/halcmd.log" 2>&1
  ${RECORDER:-halsampler} >"$1" 2>"$out/recorder.err" &
  sampler_pid=$!
}
# Waits for the streamer to drain, then stops the recording.
stop_recording() {
  for _ in $(seq 200); do
    [ "$(timeout 5 halcmd getp streamer.0.curr-depth)" = 0 ] && break
    sleep 0.05
  done
  sleep 0.2
  kill -INT "$sampler_pid"
  timeout 20 tail --pid="$sampler_pid" -f /dev/null
  stop_hal
}

# The HAL recording as a setpoint CSV (from the first streamed period on, one row per period),
# after checking that period k holds streamed row k: every index once, in order, then the last
# row held.
hal_to_csv() {  # recording, expected rows, output csv
  awk -v n="$naxes" -v rows="$2" -v axes="$axes" '
    BEGIN { split(axes, name, " "); printf "t"; for (i = 1; i <= n; i++) printf ",%s", name[i]; print "" }
    { idx = $(n + 1) }
    idx == 0 { if (k > 0) { print "index 0 after the stream started" > "/dev/stderr"; exit 1 } next }
    k == rows && idx == rows { next }  # the end, held
    {
      if (idx <= rows) {
        if (idx != k + 1) { printf "period %d holds row %d, expected %d\n", k, idx, k + 1 > "/dev/stderr"; exit 1 }
        printf "%.3f", k * 0.001; for (i = 1; i <= n; i++) printf ",%s", $i; print ""
        k++
      } else { print "row index beyond the stream: " idx > "/dev/stderr"; exit 1 }
    }
    END { if (k != rows) { printf "%d periods recorded, %d rows streamed\n", k, rows > "/dev/stderr"; exit 1 } }
  ' "$1" >"$3"
}
# Positions of the HAL recording against the stream's own record (full precision): within TOL
# plus the rounding of the number itself (halsampler's 6 printed decimals: 5.000001e-7), or, with
# TOL 0 (a full-precision capture), equal as doubles.
same_positions() {  # hal csv, record csv, tol
  paste -d, "$1" "$2" | awk -F, -v n="$naxes" -v tol="$3" '
    NR == 1 { next }
    {
      for (i = 2; i <= n + 1; i++) {
        d = $i - $(i + n + 1); if (d < 0) d = -d
        if (d > (tol > 0 ? tol + 1e-12 * ($i < 0 ? -$i : $i) : 0)) { printf "row %d axis %d: HAL %s, planned %s\n", NR - 1, i - 1, $i, $(i + n + 1) > "/dev/stderr"; bad = 1; exit 1 }
        if (d > worst) worst = d
      }
    }
    END {
      if (bad) exit 1
      if (tol > 0) printf "largest |HAL - planned| %.3g (6 printed decimals)\n", worst
      else printf "HAL = planned, exactly, on %d rows\n", NR - 1
    }'
}

# Streams the job into halstreamer through a FIFO, or with NATIVE=1 straight into streamer.0
# (--to hal:0); extra arguments go to dtis stream. Sets `rc`. With KILL_AFTER set, sends SIGTERM
# to dtis that many seconds after it starts.
stream_job() {  # name, dtis stream arguments...
  local name=$1
  shift
  local to=hal:0 streamer=
  if [ -z "${NATIVE:-}" ]; then
    rm -f "$out/fifo"
    mkfifo "$out/fifo"
    timeout 120 halstreamer <"$out/fifo" &
    streamer=$!
    to=$out/fifo
  fi
  local buffer=(--buffer "${STREAM_BUFFER:-200}")
  [[ " $* " != *" --buffer "* ]] || buffer=()
  timeout 120 "$dtis" stream "$job" --horizon $horizon --index --pace realtime --to "$to" \
    --record "$out/$name.csv" "${buffer[@]}" "$@" 2>"$out/$name.log" &
  local pid=$!
  if [ -n "${KILL_AFTER:-}" ]; then
    sleep "$KILL_AFTER"
    kill -TERM "$pid"
  fi
  rc=0
  wait "$pid" || rc=$?
  [ -z "$streamer" ] || wait "$streamer"
  cat "$out/$name.log"
}

# ---- 1. the whole job, streamed = planned
"$dtis" run "$job" --horizon $horizon -o "$out/planned.csv" -q
start_hal "$out/hal_full.txt"
stream_job streamed
stop_recording
test "$rc" = 0
cmp "$out/planned.csv" "$out/streamed.csv"
echo "stream: the rows streamed are the rows dtis run plans (byte-identical)"
rows=$(($(wc -l <"$out/streamed.csv") - 1))
hal_to_csv "$out/hal_full.txt" "$rows" "$out/hal_full.csv"
same_positions "$out/hal_full.csv" "$out/streamed.csv" 5.000001e-7
echo "stream: HAL held row k at period k for all $rows rows"
"$dtis" verify "$out/streamed.csv" "$machine" | tail -1

# ---- 2. killed mid-pass: ends with the stop to rest, within every limit
start_hal "$out/hal_abort.txt"
KILL_AFTER=0.8 stream_job aborted
stop_recording
test "$rc" = 5
grep -q "stream           aborted" "$out/aborted.log"
rows=$(($(wc -l <"$out/aborted.csv") - 1))
test "$rows" -lt "$(($(wc -l <"$out/planned.csv") - 1))"
hal_to_csv "$out/hal_abort.txt" "$rows" "$out/hal_abort.csv"
same_positions "$out/hal_abort.csv" "$out/aborted.csv" 5.000001e-7
"$dtis" verify "$out/aborted.csv" "$machine"
echo "stream: aborted mid-pass after $rows periods, at rest, verified"

# ---- 3. a planner too slow for the machine: underrun, stop, verified
start_hal "$out/hal_starved.txt"
stream_job starved --buffer 100 --slow-planner-us 2500
stop_recording
test "$rc" = 5
grep -q "stream           underrun" "$out/starved.log"
rows=$(($(wc -l <"$out/starved.csv") - 1))
hal_to_csv "$out/hal_starved.txt" "$rows" "$out/hal_starved.csv"
same_positions "$out/hal_starved.csv" "$out/starved.csv" 5.000001e-7
"$dtis" verify "$out/starved.csv" "$machine"
echo "stream: starved planner ended with the stop after $rows periods, verified"

# ---- 4. the native sink: dtis writes into streamer.0's FIFO itself (no text, no halstreamer)
if [ -z "$capture" ]; then
  echo "stream: native HAL sink not built (no linuxcnc-uspace-dev): hal:N not tested"
  exit 0
fi
set +e
"$dtis" stream "$job" --index --to hal:0 2>"$out/no_hal.log"
rc=$?
set -e
test "$rc" = 1
grep -q "no streamer.0 to attach to" "$out/no_hal.log"
echo "stream: --to hal:0 without a streamer: $(cat "$out/no_hal.log")"

RECORDER="$capture 0" start_hal "$out/hal_native.txt"
NATIVE=1 stream_job native
stop_recording
test "$rc" = 0
grep -q "pace real time" "$out/native.log"
cmp "$out/planned.csv" "$out/native.csv"
rows=$(($(wc -l <"$out/native.csv") - 1))
hal_to_csv "$out/hal_native.txt" "$rows" "$out/hal_native.csv"
same_positions "$out/hal_native.csv" "$out/native.csv" 0
"$dtis" verify "$out/hal_native.csv" "$machine" | tail -1
echo "stream: native hal:0 played the plan, period for period, exactly; HAL's own samples verified"

RECORDER="$capture 0" start_hal "$out/hal_native_abort.txt"
NATIVE=1 KILL_AFTER=0.8 stream_job native_aborted
stop_recording
test "$rc" = 5
rows=$(($(wc -l <"$out/native_aborted.csv") - 1))
hal_to_csv "$out/hal_native_abort.txt" "$rows" "$out/hal_native_abort.csv"
same_positions "$out/hal_native_abort.csv" "$out/native_aborted.csv" 0
"$dtis" verify "$out/hal_native_abort.csv" "$machine" | tail -1
echo "stream: native hal:0 killed mid-pass after $rows periods: HAL's own samples end at rest, verified"
