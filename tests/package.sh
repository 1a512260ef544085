#!/usr/bin/env bash
# The installed package: `cmake --install` into a fresh prefix, then
# - the example in examples/plan (docs/library.md) configures with find_package(dtis), builds
#   against the installed headers and libraries only, and runs on an installed sample;
# - the installed dtis runs an installed sample, writes a report with the plotly.js installed
#   beside it, has its manual page, and reads G-code with the dtis-rs274 installed beside it.
set -euo pipefail
trap 'echo "package: failed at line $LINENO: $BASH_COMMAND" >&2' ERR
build=$1
root=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix

cmake --install "$build" --prefix "$prefix" >"$work/install.log"
test -x "$prefix/bin/dtis"
test -s "$prefix/share/man/man1/dtis.1"
test -s "$prefix/share/dtis/samples/jobs/line.toml"
test -s "$prefix/share/doc/dtis/jobs.md"
test -s "$prefix/include/dtis/dtis.hpp"
# Only the public headers: none of those that serve the command and the tests alone.
for internal in io/report.hpp io/serve.hpp core/toml_reader.hpp geometry/occt_convert.hpp; do
  test ! -e "$prefix/include/dtis/$internal" || { echo "package: installs dtis/$internal" >&2; exit 1; }
done
# No absolute library path and no build-tree folder in the exported targets.
if grep -nE '"/[^"]*\.(so|a)"|/usr/lib/[^ ;"]*\.so|'"$build" "$prefix"/lib*/cmake/dtis/*.cmake; then
  echo "package: the exported targets name a library by absolute path or the build tree" >&2
  exit 1
fi

samples=$prefix/share/dtis/samples
if [ -s "$prefix/share/dtis/plotly.min.js" ]; then  # not when npm was out of reach at bootstrap
  (cd "$work" && env -u DTIS_PLOTLY_JS "$prefix/bin/dtis" run "$samples/jobs/line.toml" \
    -o line.csv --report line.html -q)
  test -s "$work/line.html"
else
  (cd "$work" && "$prefix/bin/dtis" run "$samples/jobs/line.toml" -o line.csv -q)
fi
# Whole outputs are captured before grep: `cmd | grep -q` under pipefail fails whenever grep quits
# before cmd has written its last line (cmd dies of SIGPIPE).
version=$("$prefix/bin/dtis" --version)
grep -q "^dtis [0-9]" <<<"$version"
# LinuxCNC's interpreter, installed next to dtis (which looks there first), reads the G-code sample.
if [ -x "$build/cli/dtis-rs274" ]; then
  test -x "$prefix/bin/dtis-rs274"
  summary=$(cd "$work" && env -u DTIS_RS274 "$prefix/bin/dtis" run "$samples/jobs/lock.toml" \
    -o lock.csv 2>&1)
  grep -q "^interpreter *rs274ngc" <<<"$summary"
fi

cmake -S "$root/examples/plan" -B "$work/example" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" \
  >"$work/example.log" 2>&1 || { cat "$work/example.log" >&2; exit 1; }
cmake --build "$work/example" >>"$work/example.log" 2>&1 || { cat "$work/example.log" >&2; exit 1; }
"$work/example/plan" "$samples/jobs/trident.toml" "$samples/machines/mikron_ucp710_xyz.toml"
echo "package: ok"
