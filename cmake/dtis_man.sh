#!/bin/sh
# Writes the dtis(1) manual page from the program's own --help texts, so the two never disagree.
# Usage: dtis_man.sh DTIS VERSION OUTPUT
set -eu
dtis=$1
version=$2
out=$3
# --help text as man(7) body: literal lines, backslashes and leading dots or quotes escaped, the
# build path of the binary shown as plain "dtis".
literal() {
  "$dtis" "$@" --help | sed -e 's/\\/\\e/g' -e "s|$dtis|dtis|g" -e 's/^\([.'"'"']\)/\\\&\1/' \
    -e '/^Exit status:/d'
}
{
  printf '.TH DTIS 1 "" "dtis %s" "User Commands"\n' "$version"
  printf '.SH NAME\ndtis \\- axis setpoints straight from the exact CAD surface\n'
  printf '.SH SYNOPSIS\n.B dtis\n\\fICOMMAND\\fR [\\fIOPTIONS\\fR] [\\fIARGUMENTS\\fR]\n'
  printf '.SH DESCRIPTION\n.nf\n'
  literal
  printf '.fi\n.SH COMMANDS\n'
  for command in run verify faces compare stream serve send report figures; do
    printf '.SS %s\n.nf\n' "$command"
    literal "$command"
    printf '.fi\n'
  done
  printf '.SS machine import\n.nf\n'
  literal machine import
  printf '.fi\n'
  cat <<'MAN'
.SH EXIT STATUS
The same for every command:
.TP
.B 0
ok
.TP
.B 1
bad input: a file, option value or request; one message names the file, line and key
.TP
.B 2
usage: the command line itself
.TP
.B 3
the setpoints fail the verifier
.TP
.B 4
internal error (please report it with the job)
.TP
.B 5
a stream ended early, at rest
.SH ENVIRONMENT
.TP
.B DTIS_PLOTLY_JS
the plotly.min.js that HTML reports embed (default: the one installed with dtis)
.TP
.B DTIS_CHROMIUM
the browser dtis figures draws with (default: chromium on PATH)
.TP
.B DTIS_RS274
the dtis-rs274 program that runs LinuxCNC's G-code interpreter for G-code jobs (default: the
one installed next to dtis)
.SH FILES
.TP
.I PREFIX/share/dtis/samples/
sample jobs, machines, curves, G-code programs and STEP parts
.TP
.I PREFIX/share/doc/dtis/
the documentation: jobs.md and machines.md list every key
.SH SEE ALSO
.BR halstreamer (1),
.BR halcmd (1)
MAN
} >"$out.tmp"
mv "$out.tmp" "$out"
