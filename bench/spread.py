#!/usr/bin/env python3
"""How much a sample's motion time depends on chance: each job planned with both planners (or one)
against slightly lowered limits.

    python3 bench/spread.py --dtis build/cli/dtis samples/jobs/trident.toml
    python3 bench/spread.py --dtis build/cli/dtis --update docs/planner.md samples/jobs/*.toml

Lowering every axis limit by a few hundredths of a percent (the job key `[interpolator]
limit_fraction`, from 1 down to 0.996) can only lengthen the minimum motion time, by at most
0.14 % at 0.996 (a jerk-limited time grows as the limits' cube root). A planner whose motion
time moves by more than that is deciding something by chance: which steps back off or repair,
and where. The table gives, per job and planner, the motion time at the job's own limits and the
least, median, largest and mean over the lowered ones, with the mean's standard error. Where
the draws fall into two groups (the trident's tips are passed fast or slowly), the median sits
between them and jumps with a single draw: compare two builds by their means, over many draws
(--draws). With --update, the text between the
`<!-- spread:begin -->` and `<!-- spread:end -->` lines of the given file is replaced.
"""

import argparse
import concurrent.futures
import os
import re
import statistics
import subprocess
import sys
import tempfile

from markdown_block import replace_block

FRACTIONS = (1.0, 0.9999, 0.9995, 0.999, 0.9985, 0.998, 0.997, 0.996)
PLANNERS = ("vpop", "lookahead")


def with_fraction(text, fraction, feed_mm_min=None):
    """The job text with [interpolator] limit_fraction set to `fraction` (and its top-level
    feed_mm_min to `feed_mm_min`, if given)."""
    lines = text.splitlines()
    if feed_mm_min is not None:
        top = next((i for i, l in enumerate(lines) if l.lstrip().startswith("[")), len(lines))
        lines = [l for i, l in enumerate(lines)
                 if i >= top or not re.match(r"\s*feed_mm_min\s*=", l)]
        lines.insert(0, f"feed_mm_min = {feed_mm_min!r}")
    header = next((i for i, l in enumerate(lines) if l.strip() == "[interpolator]"), None)
    if header is None:
        return "\n".join(lines) + f"\n\n[interpolator]\nlimit_fraction = {fraction!r}\n"
    end = next((i for i in range(header + 1, len(lines)) if lines[i].lstrip().startswith("[")),
               len(lines))
    body = [l for l in lines[header + 1:end] if not re.match(r"\s*limit_fraction\s*=", l)]
    return "\n".join(lines[:header + 1] + [f"limit_fraction = {fraction!r}"] + body +
                     lines[end:]) + "\n"


def staged(job, text, tmp, levels=2):
    """Writes `text` as a copy of `job` under `tmp`, beside links to everything next to the job
    and next to each of its `levels` nearest ancestor folders, so that the job's relative paths
    (../machines/..., ../../samples/..., a program beside it) still reach the same files; the
    job's own folder is never written to."""
    folder = os.path.dirname(os.path.abspath(job))
    # The ancestors to mirror, nearest first, and the staged folder at the same depth under tmp.
    chain = [folder]
    while len(chain) <= levels and os.path.dirname(chain[-1]) != chain[-1]:
        chain.append(os.path.dirname(chain[-1]))
    stage = os.path.join(tmp, "stage", *[os.path.basename(f) for f in reversed(chain[:-1])])
    os.makedirs(stage)
    for entry in os.listdir(folder):
        os.symlink(os.path.join(folder, entry), os.path.join(stage, entry))
    # Each ancestor's other entries, beside the staged copy of the folder on the way down to it.
    mirror = stage
    for inner, outer in zip(chain, chain[1:]):
        mirror = os.path.dirname(mirror)
        for entry in os.listdir(outer):
            if entry != os.path.basename(inner):
                os.symlink(os.path.join(outer, entry), os.path.join(mirror, entry))
    name = os.path.join(stage, "spread_" + os.path.basename(job))
    with open(name, "w") as f:
        f.write(text)
    return name


def motion_time(dtis, job, planner, fraction, feed_mm_min=None):
    """The motion time `dtis run` prints for the job planned at `fraction` of every limit."""
    with open(job) as f:
        text = with_fraction(f.read(), fraction, feed_mm_min)
    with tempfile.TemporaryDirectory() as tmp:
        name = staged(job, text, tmp)
        r = subprocess.run([dtis, "run", name, "--planner", planner, "-o",
                            os.path.join(tmp, "out.csv")], capture_output=True, text=True)
    m = re.search(r"motion time\s+([0-9.]+) s", r.stderr)
    if r.returncode != 0 or not m:
        sys.exit(f"{job}: dtis run --planner {planner} at limit_fraction {fraction} failed:\n"
                 f"{r.stderr}")
    return float(m.group(1))


def mean_and_error(x):
    """The mean of the motion times x and its standard error (0 for a single time)."""
    error = statistics.stdev(x) / len(x) ** 0.5 if len(x) > 1 else 0.0
    return statistics.mean(x), error


def fractions_for(draws):
    """FRACTIONS, or `draws` fractions evenly spaced from 1 down to the same 0.996."""
    if not draws:
        return FRACTIONS
    if draws < 2:
        sys.exit(f"--draws {draws}: at least 2 (1 and {FRACTIONS[-1]:g})")
    low = FRACTIONS[-1]
    return tuple(round(1.0 - k * (1.0 - low) / (draws - 1), 12) for k in range(draws))


def table(dtis, jobs, workers, feed_mm_min=None, planners=PLANNERS, fractions=FRACTIONS):
    tasks = [(job, planner, fraction) for job in jobs for planner in planners
             for fraction in fractions]
    with concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool:
        times = dict(zip(tasks, pool.map(lambda t: motion_time(dtis, *t, feed_mm_min), tasks)))
    rows = ["| job | planner | at its limits (s) | least (s) | median (s) | largest (s) | "
            "spread | mean ± standard error (s) |", "|---|---|---:|---:|---:|---:|---:|---:|"]
    for job in jobs:
        for planner in planners:
            x = [times[(job, planner, f)] for f in fractions]
            mean, error = mean_and_error(x)
            rows.append(f"| `{os.path.basename(job)}` | {planner} | {x[0]:.3f} | {min(x):.3f} | "
                        f"{statistics.median(x):.3f} | {max(x):.3f} | "
                        f"{100.0 * (max(x) / min(x) - 1.0):.1f} % | "
                        f"{mean:.4f} ± {error:.4f} |")
    return "\n".join(rows)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("jobs", nargs="+", help="job files")
    p.add_argument("--dtis", default="build/cli/dtis", help="the dtis binary")
    p.add_argument("--feed-mm-min", type=float,
                   help="plan every job at this feed instead of its own feed_mm_min")
    p.add_argument("--planner", choices=PLANNERS, action="append",
                   help="plan with this planner only (repeat for both; default: both)")
    p.add_argument("--update", help="replace the spread table in this Markdown file")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1,
                   help="plans run at once (default: one per core)")
    p.add_argument("--draws", type=int,
                   help="plan at this many fractions evenly from 1 down to "
                   f"{FRACTIONS[-1]:g} (default: the {len(FRACTIONS)} of the table in "
                   "docs/planner.md): more draws, a steadier median")
    a = p.parse_args()
    fractions = fractions_for(a.draws)
    listed = (", ".join(f"{f:g}" for f in fractions) if not a.draws else
              f"1 down to {fractions[-1]:g} in {a.draws} even steps")
    planners = tuple(a.planner) if a.planner else PLANNERS
    options = f" --feed-mm-min {a.feed_mm_min:g}" if a.feed_mm_min else ""
    options += "".join(f" --planner {p}" for p in a.planner or [])
    options += f" --draws {a.draws}" if a.draws else ""
    text = (f"Motion times at `limit_fraction` {listed}, made with\n`python3 bench/spread.py "
            f"--dtis build/cli/dtis{options} {' '.join(a.jobs)}`:\n\n" +
            table(a.dtis, a.jobs, a.workers, a.feed_mm_min, planners, fractions))
    if not a.update:
        print(text)
        return
    replace_block(a.update, "spread", text + "\n")


if __name__ == "__main__":
    main()
