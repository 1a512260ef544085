#!/usr/bin/env bash
# `dtis serve` against random requests while it streams a job: valid ones (status, pause, resume,
# submits of a good job and of missing files), malformed JSON, random bytes, bytes that are not
# UTF-8, duplicate keys, deep nesting, and lines over the 64 KiB bound. Every request line gets
# one reply line of valid JSON, an error for each bad one; the daemon never ends; every job it
# streamed verifies (`dtis verify`) and ends at rest; it still answers, and shuts down cleanly.
# DTIS_SOAK_COUNT requests (10000 by default), from seed DTIS_SOAK_SEED (printed).
set -euo pipefail
dtis=$1
root=$2
count=${DTIS_SOAK_COUNT:-10000}
seed=${DTIS_SOAK_SEED:-$RANDOM}
out=$(mktemp -d)
daemon=
trap '[ -n "$daemon" ] && kill "$daemon" 2>/dev/null; rm -rf "$out"' EXIT
machine=$root/samples/machines/mikron_ucp710_xyz.toml
sock=$out/soak.sock
printf '%s\n' "machine = \"$machine\"" 'feed_mm_min = 3000' '[path]' 'kind = "line"' \
  'from = [0, 0, 0]' 'to = [10, 0, 0]' >"$out/line.toml"

"$dtis" serve --socket "$sock" --machine "$machine" --to /dev/null --pace realtime \
  --record-dir "$out/rec" 2>"$out/serve.log" &
daemon=$!
for _ in $(seq 100); do [ -S "$sock" ] && break; sleep 0.05; done
"$dtis" send --socket "$sock" "{\"cmd\":\"submit\",\"job\":\"$root/samples/jobs/lock.toml\"}" >/dev/null

echo "serve_soak: $count requests, seed $seed"
python3 - "$sock" "$count" "$seed" "$out/line.toml" <<'PY'
import json, random, socket, sys, time

path, count, seed, good_job = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
rng = random.Random(seed)

def status_ok(r):
    return r.get("ok") is True and "state" in r

def valid():
    k = rng.random()
    if k < 0.80:
        return b'{"cmd":"status"}', status_ok
    if k < 0.88:
        return b'{"cmd":"pause"}', lambda r: r == {"ok": True}
    if k < 0.96:
        return b'{"cmd":"resume"}', lambda r: r == {"ok": True}
    if k < 0.999:
        return (json.dumps({"cmd": "submit", "job": f"/nonexistent/{rng.randrange(10**6)}.toml"}).encode(),
                lambda r: r.get("ok") is False and "/nonexistent/" in r.get("error", ""))
    return json.dumps({"cmd": "submit", "job": good_job}).encode(), lambda r: r.get("ok") is True

def error(text=""):
    return lambda r: r.get("ok") is False and text in r.get("error", "")

MALFORMED = [b"", b"{", b"}", b"[]", b"null", b"42", b'"status"', b'{"cmd":1}', b'{"cmd":null}',
             b'{"cmd":["status"]}', b'{"cmd":"status"', b'{"cmd":"fly"}', b'{"cmd":"submit"}',
             b'{"cmd":"submit","job":7}', b'{"job":"x"}', b"{'cmd':'status'}", b'{"cmd":"STATUS"}',
             b'{"cmd":"status",}', b'{"cmd":"status"}{"cmd":"status"}', b'{"cmd":"\\ud800"}',
             b'{"cmd":"submit","job":"a\\u0000b"}', b'\t{"cmd" : "status" , "cmd2":1 ,}']

def malformed():
    if rng.random() < 0.5:
        return rng.choice(MALFORMED), error()
    text = bytearray(rng.choice([b'{"cmd":"status"}', b'{"cmd":"submit","job":"/x.toml"}']))
    for _ in range(rng.randint(1, 3)):  # truncated, or bytes swapped in
        if rng.random() < 0.5 and len(text) > 1:
            del text[rng.randrange(1, len(text)) :]
        else:
            text[rng.randrange(len(text))] = rng.choice(b'{}[]":,\\ x0')
    return bytes(text), lambda r: "ok" in r  # may still be valid: anything but a crash

def binary():
    data = bytes(rng.randrange(256) for _ in range(rng.randint(1, 200))).replace(b"\n", b"")
    return data, error()

def not_utf8():
    bad = rng.choice([b"\xff", b"\xc3\x28", b"\xed\xa0\x80", b"\xf8\x88\x80\x80\x80", b"\xc0\xaf"])
    return rng.choice([b'{"cmd":"' + bad + b'"}', b'{"cmd":"status","x":"' + bad + b'"}',
                       b'{"' + bad + b'":1,"cmd":"status"}']), error("malformed request")

def duplicate():
    return rng.choice([b'{"cmd":"status","cmd":"shutdown"}', b'{"cmd":"shutdown","cmd":"status"}',
                       b'{"cmd":"abort","cmd":"abort"}', b'{"cmd":"status","x":{"y":1,"y":2}}',
                       b'{"job":"/a","cmd":"submit","job":"/b"}']), error("duplicate key")

def deep():
    n = rng.randint(9, 5000)
    return b'{"cmd":"status","x":' + b"[" * n + b"]" * n + b"}", error("nested deeper")

KINDS = [(valid, 40), (malformed, 20), (binary, 15), (not_utf8, 10), (duplicate, 10), (deep, 5)]
population = [k for k, w in KINDS for _ in range(w)]

def connect():
    s = socket.socket(socket.AF_UNIX)
    s.settimeout(60)
    s.connect(path)
    return s, s.makefile("rb")

def oversized():
    # Over the 64 KiB bound without a newline: an error, then the connection is closed.
    s, lines = connect()
    s.sendall(b'{"cmd":"status","x":"' + b"a" * (70 * 1024))
    reply = json.loads(lines.readline().decode("utf-8"))
    assert reply.get("ok") is False and "64 KiB" in reply["error"], reply
    assert lines.readline() == b"", "the connection stayed open after an oversized line"
    s.close()

t0 = time.monotonic()
s, lines = connect()
sent = 0
kinds = {}
rows_seen = []
while sent < count:
    if rng.random() < 0.02:  # about one request in 1600
        oversized()
        sent += 1
        kinds["oversized"] = kinds.get("oversized", 0) + 1
        continue
    batch = []
    for _ in range(min(rng.randint(1, 64), count - sent)):
        make = rng.choice(population)
        raw, check = make()
        batch.append((raw, check, make.__name__))
    s.sendall(b"".join(raw + b"\n" for raw, _, _ in batch))
    for raw, check, name in batch:
        line = lines.readline()
        assert line.endswith(b"\n"), f"no reply to {raw[:80]!r} (seed {seed})"
        reply = json.loads(line.decode("utf-8"))  # valid UTF-8 JSON, whatever was sent
        assert isinstance(reply, dict) and check(reply), f"{name} {raw[:80]!r} -> {line[:200]!r}"
        if name == "valid" and reply.get("current"):
            rows_seen.append(reply["current"]["rows"])
        kinds[name] = kinds.get(name, 0) + 1
    sent += len(batch)
    if rng.random() < 0.01:  # now and then a new connection
        s.close()
        s, lines = connect()
s.sendall(b'{"cmd":"resume"}\n{"cmd":"status"}\n')
assert json.loads(lines.readline()) == {"ok": True}
assert status_ok(json.loads(lines.readline()))
s.close()
elapsed = time.monotonic() - t0
print(f"serve_soak: {sent} requests in {elapsed:.1f} s ({sent / elapsed:.0f}/s), "
      + ", ".join(f"{k} {v}" for k, v in sorted(kinds.items()))
      + f"; the job streamed meanwhile up to row {max(rows_seen, default=0)}")
PY

# Every job queued runs to its end (a pause at the end of the soak was resumed), at rest.
send() { "$dtis" send --socket "$sock" "$1"; }
for _ in $(seq 1200); do
  status=$(send '{"cmd":"status"}')
  if grep -q '"state":"idle","queue":\[\],"validating":0' <<<"$status"; then break; fi
  grep -q '"state":"held"' <<<"$status" && send '{"cmd":"resume"}' >/dev/null
  sleep 0.05
done
grep -q '"state":"idle","queue":\[\],"validating":0' <<<"$status" || { echo "serve_soak: jobs left: $status" >&2; exit 1; }
send '{"cmd":"shutdown"}' | grep -q '"ok":true'
wait "$daemon"
daemon=
test ! -e "$sock"
n=0
for csv in "$out"/rec/job-*.csv; do
  "$dtis" verify "$csv" "$machine" >"$out/verify.txt" || { cat "$out/verify.txt" >&2; exit 1; }
  grep -q "ends at rest: yes" "$out/verify.txt" || { echo "serve_soak: $csv does not end at rest" >&2; exit 1; }
  n=$((n + 1))
done
[ "$n" -ge 1 ]
grep -o '"end":"[a-z]*"' <<<"$status" | sort | uniq -c | tr '\n' ' '
echo
echo "serve_soak: $n recordings verify and end at rest; the daemon answered throughout and shut down cleanly"
