#!/usr/bin/env python3
"""The planners against each other over random machines as well as random paths.

    python3 bench/machines.py --dtis build/cli/dtis --count 40 --seed 1
    python3 bench/machines.py --dtis build/cli/dtis --count 40 --keep /tmp/cases --markdown out.md
    python3 bench/machines.py --dtis build/cli/dtis --count 20 --planner least-time --timeout 900

Each case draws a 3-axis machine and a path and plans the job with two planners (`dtis run
--planner vpop` and `--planner lookahead`, or the one --planner names; one thread, 1 ms). The machine's per-axis limits range
from LinuxCNC-like ones (acceleration-limited: velocity 50-500 mm/s, acceleration 500-10 000
mm/s^2, jerk 1e5-1e8 mm/s^3, which its trajectory planner leaves unbounded) to jerk-limited ones
(jerk 2 000-50 000 mm/s^3, the Mikron's range), half of the cases each. The path is either a
cubic B-spline curve (5-12 random poles in a 100 mm box, 2-D or 3-D) or a G1 program (5-40 random
blocks of 1-30 mm, corners within G64 P 0.005-0.05 mm); the feed is 1-10 m/min.

For each case the table gives both motion times, their ratio (look-ahead over vpop) and both
compute times as real-time factors; below it, how many cases the look-ahead is more than 1 % (and
0.5 %) slower or faster, and the worst. A run that fails (an error, the verifier, or --timeout)
is listed as such. --keep DIR writes every case's machine, path and job there, named by case, so
that a case can be run again with `dtis run DIR/case_NN.toml`.
"""

import argparse
import math
import os
import random
import re
import resource
import statistics
import subprocess
import sys
import tempfile


def machine_text(rng, linuxcnc_like):
    lines = [
        'name = "random {} machine"'.format("LinuxCNC-like" if linuxcnc_like else "jerk-limited"),
        'kinematics = "xyz"',
        "",
        "[units]",
        'length = "mm"',
        'linear_velocity = "mm/s"',
        'linear_acceleration = "mm/s^2"',
        'linear_jerk = "mm/s^3"',
    ]
    limits = {}
    for axis in "XYZ":
        velocity = 10 ** rng.uniform(1.7, 2.7)
        acceleration = 10 ** rng.uniform(2.7, 4.0)
        jerk = 10 ** (rng.uniform(5.0, 8.0) if linuxcnc_like else rng.uniform(3.3, 4.7))
        limits[axis] = (velocity, acceleration, jerk)
        lines += [
            "",
            "[axes.{}]".format(axis),
            "travel = [-1000, 1000]",
            "velocity = {:.6g}".format(velocity),
            "acceleration = {:.6g}".format(acceleration),
            "jerk = {:.6g}".format(jerk),
        ]
    return "\n".join(lines) + "\n", limits


def curve_text(rng):
    n = rng.randint(5, 12)
    three_d = rng.random() < 0.5
    poles = []
    for _ in range(n):
        p = [rng.uniform(0, 100), rng.uniform(0, 100)]
        if three_d:
            p.append(rng.uniform(0, 30))
        poles.append(p)
    inner = n - 4
    knots = [0.0] * 4 + [(i + 1) / (inner + 1) for i in range(inner)] + [1.0] * 4
    return (
        'units = "mm"\ndegree = 3\nknots = [{}]\npoles = [{}]\n'.format(
            ", ".join("{:.6g}".format(k) for k in knots),
            ", ".join("[" + ", ".join("{:.6g}".format(c) for c in p) + "]" for p in poles),
        ),
        "{}-D curve, {} poles".format(3 if three_d else 2, n),
    )


def gcode_text(rng, feed_mm_min):
    blocks = rng.randint(5, 40)
    tol = rng.uniform(0.005, 0.05)
    x = y = z = 0.0
    out = ["G21 G90 G17 G94", "G64 P{:.4f}".format(tol)]
    first = True
    for _ in range(blocks):
        length = rng.uniform(1, 30)
        heading = rng.uniform(0, 6.283185307179586)
        x += length * math.cos(heading)
        y += length * math.sin(heading)
        if rng.random() < 0.3:
            z = rng.uniform(-5, 5)
        out.append(
            "G1 X{:.4f} Y{:.4f} Z{:.4f}{}".format(x, y, z, " F{:.0f}".format(feed_mm_min) if first else "")
        )
        first = False
    out.append("M2")
    return "\n".join(out) + "\n", "G1, {} blocks, P {:.3f}".format(blocks, tol)


def run(dtis, job, planner, timeout):
    # The child's CPU time, not the wall clock: on a loaded machine the wall clock measures the
    # load. It includes reading the job and the machine, a few milliseconds.
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    try:
        p = subprocess.run(
            [dtis, "run", job, "--planner", planner, "-j", "1", "-o", os.devnull],
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired:
        return None, None, "timeout"
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    compute = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        last = (p.stderr.strip().splitlines() or ["exit {}".format(p.returncode)])[-1]
        return None, compute, "error: " + last[:120]
    m = re.search(r"^motion time\s+([0-9.]+) s$", p.stderr, re.M)
    if not m:
        return None, compute, "no motion time"
    return float(m.group(1)), compute, ""


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dtis", default="build/cli/dtis")
    ap.add_argument("--count", type=int, default=40)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds per planner run")
    ap.add_argument("--keep", help="write every case's files here")
    ap.add_argument("--markdown", help="also write the table as Markdown here")
    ap.add_argument("--planner", default="lookahead", choices=["lookahead", "least-time"],
                    help="the planner measured against vpop")
    args = ap.parse_args()
    other = args.planner
    rng = random.Random(args.seed)
    folder = args.keep or tempfile.mkdtemp(prefix="dtis_machines_")
    os.makedirs(folder, exist_ok=True)
    rows = []
    for case in range(1, args.count + 1):
        linuxcnc_like = case % 2 == 1
        machine, _ = machine_text(rng, linuxcnc_like)
        feed = rng.uniform(1000, 10000)
        stem = os.path.join(folder, "case_{:02d}".format(case))
        with open(stem + "_machine.toml", "w") as f:
            f.write(machine)
        if rng.random() < 0.5:
            path, what = curve_text(rng)
            with open(stem + "_curve.toml", "w") as f:
                f.write(path)
            job = 'machine = "{0}_machine.toml"\nperiod_ms = 1.0\nfeed_mm_min = {1:.0f}\n\n[path]\nkind = "curve"\nfile = "{0}_curve.toml"\n'.format(
                os.path.basename(stem), feed
            )
        else:
            path, what = gcode_text(rng, feed)
            with open(stem + ".ngc", "w") as f:
                f.write(path)
            job = 'machine = "{0}_machine.toml"\nperiod_ms = 1.0\n\n[path]\nkind = "gcode"\nfile = "{0}.ngc"\nfrom = [0, 0, 0]\n'.format(
                os.path.basename(stem)
            )
        with open(stem + ".toml", "w") as f:
            f.write(job)
        result = {"case": case, "machine": "LinuxCNC-like" if linuxcnc_like else "jerk-limited", "path": what, "feed": feed}
        for planner in ("vpop", other):
            motion, compute, error = run(args.dtis, stem + ".toml", planner, args.timeout)
            result[planner] = (motion, compute, error)
        rows.append(result)
        v, la = result["vpop"], result[other]
        ratio = la[0] / v[0] if v[0] and la[0] else None
        result["ratio"] = ratio
        print(
            "case {:2d} {:13s} {:28s} F {:5.0f}: vpop {} {} {} ratio {}".format(
                case,
                result["machine"],
                what,
                feed,
                "{:.3f} s".format(v[0]) if v[0] else v[2],
                other,
                "{:.3f} s".format(la[0]) if la[0] else la[2],
                "{:.4f}".format(ratio) if ratio else "-",
            ),
            flush=True,
        )

    def fmt_run(r):
        motion, compute, error = r
        if motion is None:
            return error, "-"
        return "{:.3f}".format(motion), "{:.3g}x".format(motion / compute) if compute else "-"

    table = [
        "| case | machine | path | F (mm/min) | vpop (s) | {0} (s) | {0} / vpop | real time (CPU), vpop | real time (CPU), {0} |".format(other),
        "|---:|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        vm, vr = fmt_run(r["vpop"])
        lm, lr = fmt_run(r[other])
        table.append(
            "| {} | {} | {} | {:.0f} | {} | {} | {} | {} | {} |".format(
                r["case"], r["machine"], r["path"], r["feed"], vm, lm,
                "{:.4f}".format(r["ratio"]) if r["ratio"] else "-", vr, lr,
            )
        )
    ratios = [r["ratio"] for r in rows if r["ratio"]]
    lines = ["", "{} cases (seed {}), {} planned by both:".format(len(rows), args.seed, len(ratios))]
    if ratios:
        worst = max(rows, key=lambda r: r["ratio"] or 0)
        for label, pick in (("LinuxCNC-like", "LinuxCNC-like"), ("jerk-limited", "jerk-limited"), ("all", None)):
            rs = [r["ratio"] for r in rows if r["ratio"] and (pick is None or r["machine"] == pick)]
            if not rs:
                continue
            lines.append(
                "- {}: {} cases, {} over 1 % slower in {}, over 0.5 % in {}, over 1 % faster in {}; "
                "median ratio {:.4f}, worst {:.4f}".format(
                    label, len(rs), other, sum(x > 1.01 for x in rs), sum(x > 1.005 for x in rs),
                    sum(x < 0.99 for x in rs), statistics.median(rs), max(rs),
                )
            )
        lines.append("- worst: case {} ({}, {}), {:.4f}".format(worst["case"], worst["machine"], worst["path"], worst["ratio"]))
    failed = [r for r in rows if not r["ratio"]]
    if failed:
        lines.append("- not planned by both: " + ", ".join(
            "case {} ({}: {}; {})".format(r["case"], r["machine"], r["vpop"][2] or "ok", r[other][2] or "ok")
            for r in failed))
    text = "\n".join(table + lines) + "\n"
    print(text)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(text)
    if not args.keep:
        print("cases written to {} (pass --keep DIR to choose)".format(folder), file=sys.stderr)


if __name__ == "__main__":
    main()
