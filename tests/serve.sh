#!/usr/bin/env bash
# `dtis serve`: bad requests are answered with an error and change nothing; jobs run one
# after the other, the next linked from where the previous left the machine, so that everything
# the CNC received verifies as ONE sequence; an abort ends the job at rest and holds the queue
# until "resume"; a pause holds at rest at the end of the current segment.
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
  pids+=($!)
  for _ in $(seq 100); do [ -S "$sock" ] && return 0; sleep 0.05; done
  echo "dtis serve did not start" >&2
  cat "$out/serve.log" >&2
  return 1
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
wait "${pids[0]}"
test ! -e "$out/a.sock"

# ---- abort, held queue, pause (real time)
start_daemon "$out/b.sock" --to /dev/null --pace realtime --record-dir "$out/b"
send "{\"cmd\":\"submit\",\"job\":\"$jobs/lock.toml\"}" >/dev/null
wait_for '"state":"streaming".*"rows":[1-9][0-9][0-9]'
send '{"cmd":"abort"}' | grep -q '"aborted":true'
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
wait "${pids[1]}"
echo "serve: ok"
