#!/usr/bin/env python3
"""Where a planner's compute goes: instructions per setpoint, by part of the planner.

    python3 bench/cost.py --dtis build/cli/dtis samples/jobs/trident.toml samples/jobs/circle.toml

Each job is planned once by `dtis run` under callgrind (valgrind), with both planners unless
--planner names one. The instructions of each part (inclusive: with all it calls) are read from
`callgrind_annotate --inclusive=yes` and divided by the setpoints the run wrote:

    planning      dtis::interp::PlanVpop, the whole planner (the exact step, the path's
                  evaluations and, for the look-ahead, the profile)
    flows         ViableFeeds::Flow, the look-ahead's backward pass (each grid point's viable
                  set from the next one's)
    profile cap   Planner::ProfileCap, the exact step's search for the largest step the profile
                  holds viable
    release       ViableFeeds::ReleaseFeed, the walks that check a deceleration can be released
                  in time (called by both of the above: not to be added to them)
    back-offs     Planner::BackOff, the dichotomy that replaces steps from which no stop exists

Instruction counts hardly change from run to run or machine to machine (a build with other
compiler flags changes them); a real-time factor is instructions per setpoint against the
instructions per second the machine plans at, which docs/benchmarks.md's real-time factors give.
callgrind runs the planner about 50 times slower than it runs alone: the 5-axis G1 program takes
about a minute with the look-ahead, and `vpop`, slower than real time on the circle at 300 mm/s
and the singular pass, most of an hour on those (--planner lookahead). Needs valgrind (Debian:
valgrind) and a dtis whose symbols are not stripped.

--update FILE replaces the block between `<!-- cost:begin -->` and `<!-- cost:end -->` in FILE.
"""

import argparse
import concurrent.futures
import os
import re
import shutil
import subprocess
import sys
import tempfile

from markdown_block import replace_block
from tables import count

PLANNERS = ("vpop", "lookahead")

# (column, the function's qualified name as callgrind_annotate prints it, up to its parameters)
PARTS = (
    ("planning", "dtis::interp::PlanVpop("),
    ("flows", "dtis::interp::ViableFeeds::Flow("),
    ("profile cap", "::Planner::ProfileCap("),
    ("release", "dtis::interp::ViableFeeds::ReleaseFeed("),
    ("back-offs", "::Planner::BackOff("),
)

# A line of `callgrind_annotate --inclusive=yes`: the count, its share, then file:function and,
# for some, the object in brackets.
LINE = re.compile(r"^\s*([0-9,]+)\s+\([ 0-9.]+%\)\s+(\S.*?)(?:\s+\[[^\]]*\])?\s*$")


def inclusive(annotated, name):
    """The inclusive instruction count of the function `name` (0 if it never ran). A function is
    listed once per file it was attributed to and once per recursion depth; its lambdas and
    recursive copies ('2) are other entries, and the count of the function itself is the
    largest of its own entries."""
    best = 0
    for line in annotated.splitlines():
        m = LINE.match(line)
        if not m:
            continue
        symbol = m.group(2)
        at = symbol.find(name)
        if at < 0 or "{lambda" in symbol or "'" in symbol[at:]:
            continue
        best = max(best, int(m.group(1).replace(",", "")))
    return best


def setpoints(csv_path):
    """The setpoint rows of a `dtis run` CSV: the lines that start with a number (not its header,
    nor a blank line)."""
    with open(csv_path) as f:
        return sum(1 for line in f if line.lstrip()[:1] in tuple("0123456789+-."))


def measure(dtis, job, planner):
    """{part: instructions per setpoint} and the setpoints of one callgrind run of the job."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        csv_path = os.path.join(tmp, "setpoints.csv")
        r = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", dtis,
                            "run", job, "--planner", planner, "-o", csv_path, "-q"],
                           capture_output=True, text=True)
        if r.returncode != 0 or not os.path.exists(out):
            sys.exit(f"{job}: dtis run --planner {planner} under callgrind failed:\n{r.stderr}")
        a = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", out],
                           capture_output=True, text=True)
        if a.returncode != 0:
            sys.exit(f"{job}: callgrind_annotate failed:\n{a.stderr}")
        n = setpoints(csv_path)
    if n == 0:
        sys.exit(f"{job}: dtis run --planner {planner} wrote no setpoints")
    counts = {part: inclusive(a.stdout, name) for part, name in PARTS}
    if counts["planning"] == 0:
        sys.exit(f"{job}: no dtis::interp::PlanVpop in the callgrind profile: "
                 f"is {dtis} stripped of its symbols?")
    return {part: c / n for part, c in counts.items()}, n


def render(rows, command):
    lines = [f"Instructions per setpoint (callgrind), made with\n`{command}`:", "",
             "| job | planner | setpoints | planning | flows | profile cap | release | back-offs |",
             "|---|---|---:|---:|---:|---:|---:|---:|"]
    for job, planner, per, n in rows:
        cells = " | ".join(count(per[p]) for p, _ in PARTS)
        lines.append(f"| `{os.path.basename(job)}` | {planner} | {n} | {cells} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("jobs", nargs="+")
    ap.add_argument("--dtis", default="build/cli/dtis")
    ap.add_argument("--planner", choices=PLANNERS, help="only this planner (default: both)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--update", metavar="FILE",
                    help="replace the cost block of this Markdown file with the table")
    args = ap.parse_args()
    for tool in ("valgrind", "callgrind_annotate"):
        if not shutil.which(tool):
            sys.exit(f"cost.py: {tool} not found (Debian: apt install valgrind)")
    if not os.path.exists(args.dtis):
        sys.exit(f"cost.py: {args.dtis} not found (build dtis first)")
    # `dtis` is a launcher that runs dtis-main next to it (cli/launcher.cpp), which callgrind would
    # not follow: profile dtis-main itself.
    shown = args.dtis
    program = os.path.join(os.path.dirname(args.dtis) or ".", "dtis-main")
    if os.path.basename(args.dtis) == "dtis" and os.path.isfile(program):
        args.dtis = program
    for job in args.jobs:
        if not os.path.exists(job):
            sys.exit(f"cost.py: {job} not found")
    planners = (args.planner,) if args.planner else PLANNERS
    tasks = [(job, planner) for job in args.jobs for planner in planners]
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, args.workers)) as pool:
        results = list(pool.map(lambda t: measure(args.dtis, *t), tasks))
    rows = [(job, planner, per, n) for (job, planner), (per, n) in zip(tasks, results)]
    command = "python3 bench/cost.py --dtis " + " ".join(
        [shown] + (["--planner", args.planner] if args.planner else []) + args.jobs)
    text = render(rows, command)
    print(text, end="")
    if args.update:
        replace_block(args.update, "cost", text)


if __name__ == "__main__":
    main()
