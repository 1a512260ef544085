#!/usr/bin/env python3
"""Where along the path a planner loses motion time against the minimum.

    python3 bench/gap.py --dtis build/cli/dtis --min-time build/tools/min_time/dtis_min_time \\
        samples/jobs/trident.toml --feed-mm-min 5000

`dtis_min_time` (tools/min_time, built where IPOPT is installed) solves the job's minimum-time
problem; each planner plans the same job with `dtis run --limiters`, which writes the arc length of
every setpoint. The path is cut at the peaks of the minimum's feed between its valleys (its local
minima from which it rises by --rise on both sides: turns, a slow stretch, rest at the ends), and
for each piece the table gives the minimum's least feed there, the planner's least
feed there, and the time each spends on the piece: the gap of a motion time, placed on the path.

With --draws N the planners also plan the job at N limit fractions from 1 down to 0.996 (those of
`bench/spread.py --draws N`), and a table per planner gives each draw's motion time and, per piece,
the time it loses there against the minimum at the job's own limits (which the lowered limits
lengthen by at most 0.14 %) and its least feed there: which piece decides a draw. Below each such
table: the draws' median, least, largest and mean with its standard error (bench/spread.py says
why the mean: draws fall unevenly, and the median jumps with one draw).
"""

import argparse
import bisect
import concurrent.futures
import csv
import os
import statistics
import subprocess
import sys
import tempfile

from spread import fractions_for, mean_and_error, staged, with_fraction

PLANNERS = ("vpop", "lookahead")


def read_motion(times, arcs):
    """The motion as rows of (t, s), from equally long lists."""
    if len(times) != len(arcs) or len(times) < 3:
        sys.exit(f"gap.py: {len(times)} times against {len(arcs)} arc lengths")
    return list(zip(times, arcs))


def time_at(motion, s):
    """The time at which the motion reaches arc length s (linear between its rows)."""
    arcs = [r[1] for r in motion]
    i = bisect.bisect_left(arcs, s)
    if i <= 0:
        return motion[0][0]
    if i >= len(motion):
        return motion[-1][0]
    (t0, s0), (t1, s1) = motion[i - 1], motion[i]
    return t0 + (t1 - t0) * (s - s0) / (s1 - s0) if s1 > s0 else t1


def feeds(motion):
    """The feed between consecutive rows, at the arc length midway: [(s, feed)]."""
    return [(0.5 * (s0 + s1), (s1 - s0) / (t1 - t0))
            for (t0, s0), (t1, s1) in zip(motion, motion[1:]) if t1 > t0]


def least_feed(feed, s0, s1):
    inside = [f for s, f in feed if s0 <= s <= s1]
    return min(inside) if inside else float("nan")


def pieces(feed, length, rise):
    """Cuts [0, length] at the highest feed between consecutive valleys of `feed`: its local
    minima from which the feed rises by the factor `rise` on both sides before it falls lower
    (rest at either end counts as one)."""
    f = [x for _, x in feed]
    lows = [0]
    for i in range(1, len(f) - 1):
        if not (f[i] <= f[i - 1] and f[i] < f[i + 1]):
            continue
        sides = []
        for step in (-1, 1):
            j, high = i + step, f[i]
            while 0 <= j < len(f) and f[j] >= f[i]:
                high = max(high, f[j])
                j += step
            sides.append(high)
        if min(sides) >= rise * f[i]:
            lows.append(i)
    lows.append(len(f) - 1)
    cuts = [0.0]
    for a, b in zip(lows, lows[1:]):
        if b - a > 1:
            cuts.append(feed[max(range(a + 1, b), key=lambda k: f[k])][0])
    cuts.append(length)
    return sorted(set(cuts))


def run(cmd):
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"gap.py: {' '.join(cmd)} failed ({r.returncode}):\n{r.stderr}")
    return r.stderr


def plan(dtis, job, text, planner):
    """The motion `dtis run --planner planner` makes of the job text (staged beside the job)."""
    with tempfile.TemporaryDirectory() as tmp:
        name = staged(job, text, tmp)
        limiters = os.path.join(tmp, "limiters.csv")
        run([dtis, "run", name, "-q", "--planner", planner, "-o",
             os.path.join(tmp, "setpoints.csv"), "--limiters", limiters])
        with open(limiters) as f:
            rows = list(csv.DictReader(f))
    return read_motion([float(r["t"]) for r in rows], [float(r["s"]) for r in rows])


def lost_on(motion, minimum, s0, s1):
    """The time the motion spends on [s0, s1] beyond the minimum's, s."""
    return (time_at(motion, s1) - time_at(motion, s0)) - (time_at(minimum, s1) -
                                                          time_at(minimum, s0))


def draws_table(name, fractions, motions, minimum, cuts):
    """One row per draw: its motion time, and per piece the time lost and the least feed."""
    head = "| limit_fraction | motion (s) |" + "".join(
        f" {s0:.2f} – {s1:.2f} |" for s0, s1 in zip(cuts, cuts[1:]))
    rule = "|---:|---:|" + "---:|" * (len(cuts) - 1)
    rows = [f"{name}, time lost (ms) and least feed (mm/s) per piece:", "", head, rule]
    totals = []
    for fraction, motion in zip(fractions, motions):
        feed = feeds(motion)
        total = time_at(motion, motion[-1][1])
        totals.append(total)
        row = f"| {fraction:g} | {total:.3f} |"
        for s0, s1 in zip(cuts, cuts[1:]):
            row += (f" {1000 * lost_on(motion, minimum, s0, s1):+.1f} "
                    f"({least_feed(feed, s0, s1):.2f}) |")
        rows.append(row)
    rows.append("")
    mean, error = mean_and_error(totals)
    rows.append(f"median {statistics.median(totals):.3f} s, least {min(totals):.3f} s, "
                f"largest {max(totals):.3f} s, mean {mean:.4f} ± {error:.4f} s (standard error)")
    return "\n".join(rows)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("job")
    p.add_argument("--dtis", required=True, help="the dtis command line tool")
    p.add_argument("--min-time", required=True, help="dtis_min_time (tools/min_time)")
    p.add_argument("--feed-mm-min", type=float, help="the programmed feed instead of the job's")
    p.add_argument("--planner", action="append", choices=PLANNERS,
                   help="planners to place (default: both)")
    p.add_argument("--rise", type=float, default=1.5,
                   help="a valley of the minimum's feed rises by this factor on both sides")
    p.add_argument("--draws", type=int, default=0,
                   help="also plan at this many limit fractions (bench/spread.py --draws)")
    p.add_argument("--workers", type=int, default=2, help="draws planned at once")
    args = p.parse_args()
    planners = args.planner or list(PLANNERS)
    with tempfile.TemporaryDirectory() as tmp:
        text = open(args.job).read()
        if args.feed_mm_min is not None:
            text = with_fraction(text, 1.0, args.feed_mm_min)
        job = staged(args.job, text, tmp)
        setpoints, arcs = os.path.join(tmp, "minimum.csv"), os.path.join(tmp, "minimum.s")
        run([args.min_time, job, "-o", setpoints, "--arc-length", arcs])
        with open(setpoints) as f:
            times = [float(r["t"]) for r in csv.DictReader(f)]
        with open(arcs) as f:
            minimum = read_motion(times, [float(x) for x in f if x.strip()])
    plans = {planner: plan(args.dtis, args.job, text, planner) for planner in planners}
    length = minimum[-1][1]
    feed_min = feeds(minimum)
    cuts = pieces(feed_min, length, args.rise)
    feed = {name: feeds(m) for name, m in plans.items()}
    # Motion times: when each motion reaches the end of the path (rows at rest follow).
    end = {name: time_at(m, m[-1][1]) for name, m in plans.items()}
    end_min = time_at(minimum, length)
    feed_note = f" --feed-mm-min {args.feed_mm_min:g}" if args.feed_mm_min is not None else ""
    print(f"`{os.path.basename(args.job)}`{feed_note}: minimum {end_min:.4f} s, "
          + ", ".join(f"{n} {t:.4f} s (+{100 * (t / end_min - 1):.1f} %)" for n, t in end.items()))
    print()
    head = "| arc length (mm) | least feed, minimum (mm/s) |"
    rule = "|---|---:|"
    for name in plans:
        head += f" least feed, {name} | time lost, {name} (ms) |"
        rule += "---:|---:|"
    print(head)
    print(rule)
    for s0, s1 in zip(cuts, cuts[1:]):
        row = f"| {s0:.2f} – {s1:.2f} | {least_feed(feed_min, s0, s1):.2f} |"
        for name, m in plans.items():
            lost = lost_on(m, minimum, s0, s1)
            row += f" {least_feed(feed[name], s0, s1):.2f} | {1000 * lost:+.1f} |"
        print(row)
    if args.draws:
        fractions = fractions_for(args.draws)
        tasks = [(planner, f) for planner in planners for f in fractions]
        with concurrent.futures.ThreadPoolExecutor(max_workers=args.workers) as pool:
            motions = dict(zip(tasks, pool.map(
                lambda t: plan(args.dtis, args.job, with_fraction(text, t[1]), t[0]), tasks)))
        for planner in planners:
            print()
            print(draws_table(planner, fractions, [motions[(planner, f)] for f in fractions],
                              minimum, cuts))


if __name__ == "__main__":
    main()
