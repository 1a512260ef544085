#!/usr/bin/env bash
# `dtis serve`: bad requests are answered with an error and change nothing; jobs run one
# after the other, the next linked from where the previous left the machine, so that everything
# the CNC received verifies as ONE sequence; an abort ends the job at rest and holds the queue
# until "resume"; a pause holds at rest at the end of the current segment. A second daemon on a
# live socket is refused; SIGTERM, SIGINT and SIGHUP mid-job end it at rest with its recording
# complete, at three moments each, and so does every other signal whose default would end it
# (SIGQUIT, SIGUSR1, ... the real-time ones), for serve and for stream; a SIGINT is kept from the
# launcher's first instructions on (`dtis` next to DTIS, which is dtis-main); a stream whose parent
# ignores SIGINT still stops on it, and one whose reader dies records what it sent. Bad jobs are
# refused at submit, whole, an endless program within 5 s while status answers; a validation
# under way never delays control, and shutdown cancels it. Requests that are not UTF-8 or give a
# key twice are answered with an error while the daemon streams on. Abort is answered at once
# while a client floods requests.
set -euo pipefail
dtis=$1
root=$2
out=$(mktemp -d)
pids=()
trap 'for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; rm -rf "$out"' EXIT
machine=$root/samples/machines/mikron_ucp710_xyz.toml
jobs=$root/samples/jobs

send() { "$dtis" send --socket "$sock" "$1"; }
# Waits until the status JSON matches a regular expression (10 s at most... or $2 s).
wait_for() {
  for _ in $(seq $((${2:-10} * 20))); do
    if send '{"cmd":"status"}' | grep -Eq "$1"; then return 0; fi
    sleep 0.05
  done
  echo "timed out waiting for $1; status: $(send '{"cmd":"status"}')" >&2
  return 1
}
start_daemon() {  # socket, extra arguments
  sock=$1
  shift
  "$dtis" serve --socket "$sock" --machine "$machine" "$@" 2>>"$out/serve.log" &
  daemon=$!
  pids+=("$daemon")
  for _ in $(seq 100); do [ -S "$sock" ] && return 0; sleep 0.05; done
  echo "dtis serve did not start" >&2
  cat "$out/serve.log" >&2
  return 1
}
job() {  # name, then the job's lines
  local name=$1
  shift
  printf '%s\n' "machine = \"$machine\"" "$@" >"$out/$name.toml"
  echo "$out/$name.toml"
}
at_rest() {  # csv: the last three rows hold the same position
  test "$(tail -3 "$1" | cut -d, -f2- | sort -u | wc -l)" = 1
}
expect_error() {  # request, text the error must contain
  local reply rc=0
  reply=$(send "$1") || rc=$?
  test "$rc" = 1 || { echo "expected exit 1 (bad input) for $1, got $rc: $reply" >&2; return 1; }
  echo "$reply" | grep -q '"ok":false' || { echo "not an error: $reply" >&2; return 1; }
  echo "$reply" | grep -qF "$2" || { echo "error without '$2': $reply" >&2; return 1; }
}

# ---- bad requests
start_daemon "$out/a.sock" --to "$out/a.txt" --pace none --record-dir "$out/a"
test "$(stat -c %a "$out/a.sock")" = 600
expect_error 'not json' "malformed request"
expect_error '{"job":"x"}' 'string \"cmd\"'
expect_error '{"cmd":"fly"}' "unknown command 'fly'"
expect_error '{"cmd":"submit"}' "submit needs"
expect_error '{"cmd":"submit","job":"/nonexistent/job.toml"}' "/nonexistent/job.toml"
expect_error "{\"cmd\":\"submit\",\"job\":\"$jobs/surface_tilt10_xyzac.toml\"}" "this CNC is"
send '{"cmd":"status"}' | grep -q '"state":"idle".*"queue":\[\].*"done":\[\]'
echo "serve: malformed requests answered with errors, nothing changed"

# ---- two jobs, one after the other, linked
send "{\"cmd\":\"submit\",\"job\":\"$jobs/lock.toml\"}" | grep -q '"id":1'
send "{\"cmd\":\"submit\",\"job\":\"$jobs/trident.toml\"}" | grep -q '"id":2'
wait_for '"id":2,"job":"[^"]*","end":"complete"' 60
send '{"cmd":"status"}' | grep -q '"end":"complete".*"verified":true.*"end":"complete".*"verified":true'
# Everything streamed, as one sequence: job 2 starts with the link from where job 1 stopped.
{
  head -1 "$out/a/job-1.csv"
  tail -n +2 "$out/a/job-1.csv" | cut -d, -f2-
  tail -n +2 "$out/a/job-2.csv" | cut -d, -f2-
} | awk -F, 'NR == 1 { print; next } { printf "%.3f,%s\n", (NR - 2) * 0.001, $0 }' >"$out/all.csv"
"$dtis" verify "$out/all.csv" "$machine" | tail -4
test "$(wc -l <"$out/a.txt")" -eq "$(($(wc -l <"$out/all.csv") + 1))"  # + the repeated last line
echo "serve: two jobs streamed back to back, linked, verified as one sequence"
send '{"cmd":"shutdown"}' >/dev/null
wait "$daemon"
test ! -e "$out/a.sock"

# ---- abort, held queue, pause (real time)
start_daemon "$out/b.sock" --to /dev/null --pace realtime --record-dir "$out/b"
send "{\"cmd\":\"submit\",\"job\":\"$jobs/lock.toml\"}" >/dev/null
wait_for '"state":"streaming".*"rows":[1-9][0-9][0-9]'
reply=$(send '{"cmd":"abort"}'); echo "$reply" | grep -q '"aborted":true' || { echo "abort: $reply; $(send '{"cmd":"status"}')" >&2; exit 1; }
wait_for '"state":"held".*"end":"aborted"'
"$dtis" verify "$out/b/job-1.csv" "$machine" | tail -3
send "{\"cmd\":\"submit\",\"job\":\"$jobs/surface_plane_cl_3axis.toml\"}" >/dev/null
sleep 0.3
send '{"cmd":"status"}' | grep -q '"state":"held".*"queue":\[{"id":2'
echo "serve: aborted job ended at rest and verified; the queue waits"
send '{"cmd":"pause"}' >/dev/null
send '{"cmd":"resume"}' >/dev/null
wait_for '"state":"streaming".*"pass":2' 30
send '{"cmd":"pause"}' >/dev/null
wait_for '"state":"pausing".*"held_rows":[1-9]' 30
echo "serve: paused at rest at the end of a segment"
send '{"cmd":"abort"}' >/dev/null
wait_for '"id":2,"job":"[^"]*","end":"(aborted|complete)"' 30
"$dtis" verify "$out/b/job-2.csv" "$machine" | tail -3
send '{"cmd":"shutdown"}' >/dev/null
wait "$daemon"

# ---- requests the daemon cannot read, mid-job: an error each, the stream goes on. Bytes that are
# not UTF-8 once ended the daemon (std::terminate) at full feed; a key given twice acted on the
# last ({"cmd":"status","cmd":"shutdown"} shut it down).
start_daemon "$out/u.sock" --to /dev/null --pace realtime --record-dir "$out/u"
send "{\"cmd\":\"submit\",\"job\":\"$jobs/lock.toml\"}" >/dev/null
wait_for '"state":"streaming".*"rows":[1-9][0-9][0-9]'
python3 - "$out/u.sock" <<'PY'
import json, socket, sys, time
s = socket.socket(socket.AF_UNIX)
s.connect(sys.argv[1])
lines = s.makefile("rb")
def ask(raw, want_ok, text=""):
    s.sendall(raw + b"\n")
    reply = lines.readline()
    r = json.loads(reply.decode("utf-8"))  # one line of valid UTF-8 JSON, whatever was sent
    assert r["ok"] is want_ok, (raw, reply)
    assert text in r.get("error", ""), (raw, reply)
    return r
before = ask(b'{"cmd":"status"}', True)["current"]["rows"]
ask(b'{"cmd":"\xff"}', False, "malformed request")
ask(b'{"cmd":"status","job":"\xc3\x28"}', False, "malformed request")
ask(b'\xfe\xff\x00{"cmd":"abort"}', False, "malformed request")
ask(b'{"cmd":"status","cmd":"shutdown"}', False, 'duplicate key "cmd"')
ask(b'{"cmd":"abort","x":{"a":1,"a":2}}', False, 'duplicate key "a"')
ask(b'{"cmd":"status","cmd":"status"}', False, "duplicate key")
ask(b'{"cmd":"status","x":' + b'[' * 100 + b']' * 100 + b'}', False, "nested deeper")
time.sleep(0.2)
after = ask(b'{"cmd":"status"}', True)
assert after["state"] == "streaming" and after["current"]["rows"] > before, after
print("serve: bytes that are not UTF-8 and duplicate keys answered with an error, still streaming")
PY
reply=$(send '{"cmd":"abort"}'); echo "$reply" | grep -q '"aborted":true' || { echo "abort: $reply; $(send '{"cmd":"status"}')" >&2; exit 1; }
wait_for '"state":"held".*"id":1,"job":"[^"]*","end":"aborted"'
"$dtis" verify "$out/u/job-1.csv" "$machine" >/dev/null
at_rest "$out/u/job-1.csv"

# ---- a program that never ends is refused at submit (its moves pass the 24 h a job may take),
# status answering meanwhile; one that loops without a move is read until shutdown, which cancels
# it at once; neither delays another job's submit. The bounds tell bounded from stuck, with room
# for a loaded machine (idle: 0.5 s to refuse, a few ms to shut down; under a load of 8 on 2
# cores the refusal took 5.9 s).
printf '%s\n' 'G21 G90 G94' 'G0 X0 Y0 Z5' 'G1 Z0 F1000' 'o100 while [1]' 'G1 X10 F1000' 'G1 X0' \
  'o100 endwhile' 'M2' >"$out/endless.ngc"
printf '%s\n' 'G21 G90 G94' 'G0 X0 Y0 Z5' '#1 = 0' 'o100 while [1]' '#1 = [#1 + 1]' 'o100 endwhile' \
  'M2' >"$out/idle_loop.ngc"
endless=$(job endless '[path]' 'kind = "gcode"' "file = \"$out/endless.ngc\"")
idle_loop=$(job idle_loop '[path]' 'kind = "gcode"' "file = \"$out/idle_loop.ngc\"")
line=$(job line 'feed_mm_min = 3000' '[path]' 'kind = "line"' 'from = [0, 0, 0]' 'to = [10, 0, 0]')
send '{"cmd":"abort"}' >/dev/null  # hold the queue: nothing streams, the jobs stay listed
t0=$(date +%s%N)
rc=0
send "{\"cmd\":\"submit\",\"job\":\"$endless\"}" >"$out/endless.reply" &
endless_send=$!
pids+=("$endless_send")
status_ms=()
while kill -0 "$endless_send" 2>/dev/null; do
  t1=$(date +%s%N)
  send '{"cmd":"status"}' | grep -q '"ok":true'
  status_ms+=($((($(date +%s%N) - t1) / 1000000)))
  sleep 0.05
done
wait "$endless_send" || rc=$?
ms=$((($(date +%s%N) - t0) / 1000000))
test "$rc" = 1 || { echo "the endless program's submit exited $rc: $(cat "$out/endless.reply")" >&2; exit 1; }
grep -q '"ok":false' "$out/endless.reply"
grep -qF "$out/endless.ngc" "$out/endless.reply"
((ms <= 30000)) || { echo "refusing the endless program took $ms ms" >&2; exit 1; }
worst=$(printf '%s\n' "${status_ms[@]:-0}" | sort -n | tail -1)
echo "serve: endless program refused at submit in $ms ms, ${#status_ms[@]} status requests answered meanwhile (slowest $worst ms): $(grep -o '"error":"[^"]*' "$out/endless.reply" | cut -c10-)"
send "{\"cmd\":\"submit\",\"job\":\"$idle_loop\"}" >"$out/idle_loop.reply" 2>&1 &
idle_send=$!
pids+=("$idle_send")
wait_for '"validating":1' 20
t0=$SECONDS
send "{\"cmd\":\"submit\",\"job\":\"$line\"}" | grep -q '"ok":true'  # not behind the loop
((SECONDS - t0 <= 10)) || { echo "a submit waited $((SECONDS - t0)) s behind a program being read" >&2; exit 1; }
send '{"cmd":"status"}' | grep -q '"queue":\[{"id":2.*"validating":1'
t0=$(date +%s%N)
send '{"cmd":"shutdown"}' | grep -q '"ok":true'
wait "$daemon"
ms=$((($(date +%s%N) - t0) / 1000000))
((ms <= 10000)) || { echo "shutdown took $ms ms with a program being read" >&2; exit 1; }
test ! -e "$out/u.sock"
wait "$idle_send" || true
grep -q '"ok":false' "$out/idle_loop.reply"
! pgrep -f "dtis-rs274 $out/idle_loop.ngc" >/dev/null || { echo "LinuxCNC's interpreter left running" >&2; exit 1; }
echo "serve: a program looping without a move read until shutdown, which ended it in $ms ms: $(cat "$out/idle_loop.reply")"

# ---- a job is read and checked whole before "ok": bad curves, programs and runaway keys are
# refused at submit, at once, and the daemon goes on serving
start_daemon "$out/v.sock" --to /dev/null --pace none
printf 'degree = 2\nknots = [0, 0, 0, 1, 1, 1]\npoles = [[0, 0], [50, 1e300], [100, 0]]\n' >"$out/far_curve.toml"
printf 'G21 G90 G94\nG1 X10 F1000\nG2 X20 Y0 R2\n' >"$out/bad_arc.ngc"
submit_error() {  # job file, text the error must contain
  local t0=$SECONDS
  expect_error "{\"cmd\":\"submit\",\"job\":\"$1\"}" "$2"
  ((SECONDS - t0 <= 1)) || { echo "refusing $1 took $((SECONDS - t0)) s" >&2; return 1; }
}
submit_error "$(job far 'feed_mm_min = 3000' '[path]' 'kind = "curve"' "file = \"$out/far_curve.toml\"")" \
  "far_curve.toml:3: curve: pole 1 (50, 1e+300, 0) is more than 1e+06 mm"
submit_error "$(job arc '[path]' 'kind = "gcode"' "file = \"$out/bad_arc.ngc\"")" "bad_arc.ngc:3"
submit_error "$(job longdt 'period_ms = 300000' '[path]' 'kind = "line"' 'from = [0, 0, 0]' 'to = [10, 0, 0]')" \
  "expected a period from 0.01 to 100 ms"
submit_error "$(job crawl 'feed_mm_min = 1e-12' '[path]' 'kind = "line"' 'from = [0, 0, 0]' 'to = [10, 0, 0]')" \
  "more than the 24 h a job may take"
sed 's/^face = 1$/face = 4294967297/; s|"\.\./|"'"$root"'/samples/|' "$jobs/surface_plane_cl_3axis.toml" >"$out/face.toml"
submit_error "$out/face.toml" "face"
sed "s|^machine = .*|machine = \"/dev/zero\"|" "$out/crawl.toml" >"$out/zero.toml"
submit_error "$out/zero.toml" "this CNC is"
send '{"cmd":"status"}' | grep -q '"state":"idle".*"queue":\[\].*"done":\[\]'
echo "serve: bad curves, programs and runaway keys refused at submit, the daemon still serving"
send '{"cmd":"abort"}' >/dev/null  # hold the queue: jobs pile up
line=$(job line 'feed_mm_min = 3000' '[path]' 'kind = "line"' 'from = [0, 0, 0]' 'to = [10, 0, 0]')
for _ in $(seq 64); do send "{\"cmd\":\"submit\",\"job\":\"$line\"}" | grep -q '"ok":true'; done
expect_error "{\"cmd\":\"submit\",\"job\":\"$line\"}" "64 jobs are queued, the most the daemon holds"
send '{"cmd":"shutdown"}' >/dev/null
wait "$daemon"
echo "serve: the queue holds at most 64 jobs"

# ---- control stays answerable: neither a client that floods requests without reading a reply,
# nor a FIFO given as a job, nor a surface job being read delays an abort. The first job is the
# lock (7.5 s of motion): with the circle (3.4 s), a loaded machine took so long to get to the
# abort that the circle had ended and the abort hit the next job.
start_daemon "$out/d.sock" --to /dev/null --pace realtime --record-dir "$out/d"
send "{\"cmd\":\"submit\",\"job\":\"$jobs/lock.toml\"}" >/dev/null
wait_for '"state":"streaming".*"rows":[1-9][0-9][0-9]'
python3 - "$out/d.sock" <<'PY' &
import socket, sys
s = socket.socket(socket.AF_UNIX)
s.connect(sys.argv[1])
while True:
    s.sendall(b'{"cmd":"status"}\n' * 64)
PY
flood=$!
pids+=("$flood")
send "{\"cmd\":\"submit\",\"job\":\"$jobs/surface_plane_cl_3axis.toml\"}" >"$out/d.submit" &
pids+=($!)
mkfifo "$out/job.fifo"
expect_error "{\"cmd\":\"submit\",\"job\":\"$out/job.fifo\"}" "is a FIFO, not a file"
sleep 0.3  # the flood has filled every buffer between it and the daemon
python3 - "$out/d.sock" "$out/abort_row" <<'PY'
import json, socket, sys, time
s = socket.socket(socket.AF_UNIX)
s.connect(sys.argv[1])
t0 = time.monotonic()
s.sendall(b'{"cmd":"abort"}\n')
lines = s.makefile()
reply = lines.readline()
ms = (time.monotonic() - t0) * 1e3
s.sendall(b'{"cmd":"status"}\n')
status = json.loads(lines.readline())
print(f"serve: abort answered in {ms:.1f} ms, a client flooding: {reply.strip()}")
with open(sys.argv[2], "w") as f:
    f.write(str(status.get("current", {}).get("rows", 0)))
sys.exit(0 if '"aborted":true' in reply and ms < 100 else 1)
PY
wait_for '"id":1,"job":"[^"]*","end":"aborted"'
"$dtis" verify "$out/d/job-1.csv" "$machine" >"$out/d.verify"
at_rest "$out/d/job-1.csv"
# What the CNC already holds (--buffer, 200 periods) plays out, then the stop to rest.
echo "serve: the machine at rest $(($(wc -l <"$out/d/job-1.csv") - 1 - $(cat "$out/abort_row"))) periods after the abort"
wait_for '"state":"held".*"queue":\[{"id":2'  # the surface job, read while the circle streamed
kill "$flood"
send '{"cmd":"shutdown"}' >/dev/null
wait "$daemon"
echo "serve: the aborted stream ended at rest, $(grep -o 'worst ratio [0-9.]*' "$out/d.verify")"

# ---- one daemon per socket; nothing that is not a socket is ever removed
start_daemon "$out/c.sock" --to /dev/null --pace realtime
rc=0
"$dtis" serve --socket "$out/c.sock" --machine "$machine" --to /dev/null 2>"$out/second.err" || rc=$?
test "$rc" = 1 || { echo "a second daemon on a live socket exited $rc" >&2; exit 1; }
grep -q "another dtis serve is listening there" "$out/second.err"
send "{\"cmd\":\"submit\",\"job\":\"$jobs/circle.toml\"}" >/dev/null
wait_for '"state":"streaming"'
send '{"cmd":"abort"}' | grep -q '"aborted":true'  # the first daemon still answers
send '{"cmd":"shutdown"}' >/dev/null
wait "$daemon"
echo precious >"$out/file.sock"
rc=0
"$dtis" serve --socket "$out/file.sock" --machine "$machine" --to /dev/null 2>"$out/file.err" || rc=$?
test "$rc" = 1 && grep -q "is not a socket; not removing it" "$out/file.err"
test "$(cat "$out/file.sock")" = precious
echo "serve: a live socket and an ordinary file at the path are refused and left alone"

# ---- a signal mid-job: the job's stop to rest, its recording complete, the socket removed
wait_rows() {  # until the current job has streamed at least N rows
  local now
  for _ in $(seq 400); do
    now=$(send '{"cmd":"status"}' | grep -o '"current":{[^}]*"rows":[0-9]*' | grep -o '[0-9]*$' || true)
    [ -n "$now" ] && [ "$now" -ge "$1" ] && return 0
    sleep 0.02
  done
  echo "timed out waiting for $1 rows: $(send '{"cmd":"status"}')" >&2
  return 1
}
# The circle (3 426 rows) plans at about 100x real time: no underrun even on a loaded machine.
# SIGTERM, SIGINT and SIGHUP at three moments; every other signal whose default action would end
# the daemon (SIGKILL cannot be caught; SIGPIPE is ignored: a reader gone is a write error) once.
fatal_signals="QUIT USR1 USR2 ALRM VTALRM PROF XCPU XFSZ IO STKFLT PWR SYS TRAP ABRT BUS FPE ILL SEGV"
fatal_signals="$fatal_signals RTMIN RTMIN+5 RTMAX"
signal_name() { if [ "$1" = IO ]; then echo SIGPOLL; else echo "SIG$1"; fi; }  # as dtis names it
signal_cases=()
for sig in TERM INT HUP; do
  for rows in 50 1200 2400; do signal_cases+=("$sig:$rows"); done
done
for sig in $fatal_signals; do signal_cases+=("$sig:800"); done
for case in "${signal_cases[@]}"; do
  sig=${case%%:*}
  rows=${case#*:}
  sock=$out/sig.sock
  rm -rf "$out/sig"
  "$dtis" serve --socket "$sock" --machine "$machine" --to /dev/null --pace realtime \
    --record-dir "$out/sig" 2>"$out/sig.log" &
  pid=$!
  pids+=("$pid")
  for _ in $(seq 100); do [ -S "$sock" ] && break; sleep 0.05; done
  send "{\"cmd\":\"submit\",\"job\":\"$jobs/circle.toml\"}" >/dev/null
  wait_rows "$rows"
  kill -s "$sig" "$pid"
  rc=0
  wait "$pid" || rc=$?
  problem=""
  test "$rc" = 0 || problem="exit $rc"
  test ! -e "$sock" || problem="$problem; socket left behind"
  test -s "$out/sig/job-1.csv" || problem="$problem; no recording"
  "$dtis" verify "$out/sig/job-1.csv" "$machine" >"$out/sig.verify" || problem="$problem; $(tail -1 "$out/sig.verify")"
  at_rest "$out/sig/job-1.csv" || problem="$problem; not at rest: $(tail -1 "$out/sig/job-1.csv")"
  n=$(($(wc -l <"$out/sig/job-1.csv") - 1))
  [ "$n" -lt 3426 ] || problem="$problem; ran to the end ($n rows), the signal did not stop it"
  if [ -n "$problem" ]; then
    echo "FAIL serve SIG$sig after $rows rows: ${problem#; }" >&2
    cat "$out/sig.log" >&2
    exit 1
  fi
  grep -q "stopped by $(signal_name "$sig")," "$out/sig.log" ||
    { echo "SIG$sig: not named: $(cat "$out/sig.log")" >&2; exit 1; }
  echo "serve: SIG$sig after $rows rows: stopped at rest after $n rows, $(grep -o 'worst ratio [0-9.]*' "$out/sig.verify")"
done

# ---- the same signals stop a stream at rest, its recording complete
for sig in TERM INT HUP $fatal_signals; do
  "$dtis" stream "$jobs/circle.toml" --to /dev/null --pace realtime --record "$out/sig_stream.csv" \
    2>"$out/sig_stream.log" &
  pid=$!
  pids+=("$pid")
  sleep 1
  kill -s "$sig" "$pid"
  rc=0
  wait "$pid" || rc=$?
  problem=""
  test "$rc" = 5 || problem="exit $rc, expected 5"
  # On a loaded machine the signal may come before the first setpoint: nothing moved, nothing to
  # verify.
  if ! grep -q "aborted after 0 setpoints" "$out/sig_stream.log"; then
    "$dtis" verify "$out/sig_stream.csv" "$machine" >"$out/sig.verify" || problem="$problem; $(tail -1 "$out/sig.verify")"
    at_rest "$out/sig_stream.csv" || problem="$problem; not at rest"
  fi
  grep -q "stopped by       $(signal_name "$sig")$" "$out/sig_stream.log" || problem="$problem; the signal not named"
  if [ -n "$problem" ]; then
    echo "FAIL stream SIG$sig: ${problem#; }" >&2
    cat "$out/sig_stream.log" >&2
    exit 1
  fi
  rm -f "$out/sig_stream.csv"
done
echo "serve: a stream stops at rest on each of SIGTERM SIGINT SIGHUP $fatal_signals"

# ---- the signals are caught before any library initialises: a library's constructor (run
# before OCCT's own) already sees SIGINT caught
if command -v cc >/dev/null; then
  cat >"$out/probe.c" <<'C'
#include <signal.h>
#include <stdio.h>
__attribute__((constructor)) static void probe(void) {
  struct sigaction sa;
  sigaction(SIGINT, NULL, &sa);
  fprintf(stderr, "probe: SIGINT %s\n", sa.sa_handler == SIG_DFL ? "default" : "caught");
}
C
  cc -shared -fPIC -o "$out/probe.so" "$out/probe.c"
  LD_PRELOAD=$out/probe.so "$dtis" --version 2>&1 >/dev/null | grep -q "probe: SIGINT caught"
  echo "serve: SIGINT caught before the libraries initialise"
fi

# ---- `dtis` (the launcher) blocks the stop signals before dtis-main's libraries load: a SIGINT at
# any moment after it did is kept and stops the stream at rest (dtis-main alone loses one that
# comes while the loader works: 20 ms idle, 100-200 ms on a busy machine)
python3 - "$dtis" "$jobs/circle.toml" "$out/early.csv" <<'PY'
import os, signal, subprocess, sys, time
dtis, job, record = sys.argv[1:]
launcher = os.path.join(os.path.dirname(dtis), "dtis")
for delay_ms in [0, 0, 1, 2, 5, 10, 20, 50, 100, 200]:
    p = subprocess.Popen([launcher, "stream", job, "--to", "/dev/null", "--pace", "realtime",
                          "--record", record, "-q"])
    # Until the launcher has blocked SIGINT (SigBlk bit 1) or dtis-main has caught it (SigCgt:
    # it unblocks it then, so a poll may never see it blocked), within 10 s.
    deadline = time.monotonic() + 10
    while True:
        assert p.poll() is None, f"dtis ended (exit {p.returncode}) before SIGINT was sent"
        assert time.monotonic() < deadline, "SIGINT was neither blocked nor caught within 10 s"
        with open(f"/proc/{p.pid}/status") as f:
            fields = dict(l.split(":", 1) for l in f if l.startswith(("SigBlk:", "SigCgt:")))
        if (int(fields["SigBlk"], 16) | int(fields["SigCgt"], 16)) & 2:
            break
    time.sleep(delay_ms / 1000)
    p.send_signal(signal.SIGINT)
    rc = p.wait()
    assert rc == 5, f"SIGINT {delay_ms} ms after the launcher blocked it: exit {rc}, expected 5"
print("serve: SIGINT from the launcher's first instructions on stops the stream (exit 5)")
PY

# ---- a stream whose reader dies: exit 1, what was sent recorded, the message says so. The machine
# was not stopped (nothing reads it any more), so the recording does not end at rest: it must be
# the start, row for row, of the whole stream's recording, which verifies.
"$dtis" stream "$jobs/circle.toml" --to /dev/null --pace none --record "$out/whole.csv" -q
"$dtis" verify "$out/whole.csv" "$machine" >/dev/null
mkfifo "$out/reader.fifo"
for how in kill close; do
  if [ "$how" = kill ]; then
    cat "$out/reader.fifo" >/dev/null &
  else
    head -c 50000 "$out/reader.fifo" >/dev/null &
  fi
  reader=$!
  pids+=("$reader")
  disown "$reader"  # its SIGKILL is no news
  "$dtis" stream "$jobs/circle.toml" --to "$out/reader.fifo" --record "$out/reader.csv" \
    2>"$out/reader.log" &
  pid=$!
  pids+=("$pid")
  if [ "$how" = kill ]; then
    sleep 1
    kill -KILL "$reader"
  fi
  rc=0
  wait "$pid" || rc=$?
  test "$rc" = 1 || { echo "stream whose reader died ($how): exit $rc, expected 1" >&2; cat "$out/reader.log" >&2; exit 1; }
  grep -q "setpoints sent until then are recorded in $out/reader.csv" "$out/reader.log" ||
    { echo "stream whose reader died ($how): $(cat "$out/reader.log")" >&2; exit 1; }
  n=$(($(wc -l <"$out/reader.csv") - 1))
  [ "$n" -ge 2 ] && [ "$n" -lt 3426 ] || { echo "reader died ($how): $n rows recorded" >&2; exit 1; }
  cmp "$out/reader.csv" <(head -n $((n + 1)) "$out/whole.csv") ||
    { echo "reader died ($how): the recording is not the start of the whole stream's" >&2; exit 1; }
  echo "serve: a stream whose reader died ($how) recorded the $n rows it sent, the start of a verified stream"
  rm -f "$out/reader.csv"
done

# ---- a stream whose parent ignores SIGINT (a shell's background job) still stops on it, when it
# comes while the job loads (the surface job traces its passes first) and mid-stream
for delay in 0 0.6; do
  (trap '' INT; exec "$dtis" stream "$jobs/surface_plane_cl_3axis.toml" --to /dev/null \
    --pace realtime --record "$out/ignored.csv" -q) &
  pid=$!
  pids+=("$pid")
  # Once dtis catches SIGINT (SigCgt bit 1): before its first line runs, while the dynamic loader
  # works, the signal is still the shell's to ignore.
  for _ in $(seq 400); do
    cgt=$(sed -n 's/^SigCgt:\t//p' "/proc/$pid/status" 2>/dev/null || true)
    [ -n "$cgt" ] && (((0x$cgt & 2) != 0)) && break
    sleep 0.005
  done
  sleep "$delay"
  kill -s INT "$pid"
  rc=0
  wait "$pid" || rc=$?
  test "$rc" = 5 || { echo "stream after SIGINT at ${delay} s with SIGINT ignored: exit $rc, expected 5" >&2; exit 1; }
  if [ "$(wc -l <"$out/ignored.csv")" -gt 2 ]; then  # else stopped before it moved: a header only
    "$dtis" verify "$out/ignored.csv" "$machine" >/dev/null
    at_rest "$out/ignored.csv"
  fi
  rm -f "$out/ignored.csv"
done
echo "serve: a stream whose parent ignores SIGINT stops at rest on it, also while loading"
echo "serve: ok"
