#!/usr/bin/env python3
"""The tables of docs/benchmarks.md, from one run of dtis_bench.

    python3 bench/tables.py --bench build/bench/dtis_bench --update docs/benchmarks.md
    python3 bench/tables.py --json run.json            # print the tables of a saved run

Runs the benchmarks the tables need (about five minutes on two cores), or reads a run saved with
`dtis_bench --benchmark_format=json --benchmark_out=run.json`, and prints Markdown. With
--update, the text between the `<!-- tables:begin -->` and `<!-- tables:end -->` lines of the
given file is replaced by the new tables, the machine and the command that made them.
"""

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile

from markdown_block import replace_block

FILTER = ("Plan/|GcodePlanSample/|SurfacePlanner/|SurfacePlannerHoles/|Surface/|SurfacePlan/|"
          "Streamed/|"
          "SurfaceD2|CurvePoint|"
          "CurveD3|GcodeRead|GcodeLoad1M|Export")

# (benchmark family, sample name) in the order the planner table lists them.
PLANNED = [
    ("Plan", "line"), ("Plan", "trident"), ("Plan", "circle"), ("Plan", "circle_300"),
    ("Plan", "open_pocket_bottom"), ("Plan", "open_pocket_xyzac"),
    ("GcodePlanSample", "lock"), ("GcodePlanSample", "fine_wave"),
    ("GcodePlanSample", "five_axis_g1"),
    ("SurfacePlanner", "tilt10_xyzac"), ("SurfacePlanner", "tilt10_singular"),
    ("SurfacePlanner", "plane_cl_3axis"), ("SurfacePlanner", "trimmed_face"),
    ("SurfacePlannerHoles", "holes"),
]
PLANNERS = ("vpop", "lookahead")
# The samples the streamed table lists (Streamed/NAME_PLANNER), in its order.
STREAMED = ["trident", "circle_300", "open_pocket_xyzac", "lock", "fine_wave", "five_axis_g1",
            "tilt10_head_table", "plane_cl_3axis", "leading_line_3axis", "tilt10_singular"]


def run_bench(bench, save=None):
    with tempfile.TemporaryDirectory() as tmp:
        out = save or os.path.join(tmp, "run.json")
        subprocess.run([bench, f"--benchmark_filter={FILTER}", "--benchmark_format=console",
                        "--benchmark_out_format=json", f"--benchmark_out={out}"],
                       check=True, stdout=sys.stderr)
        with open(out) as f:
            return json.load(f)


def dtis_build_type(bench):
    """The CMAKE_BUILD_TYPE of the build the benchmark binary belongs to."""
    folder = os.path.dirname(os.path.abspath(bench))
    for _ in range(3):
        cache = os.path.join(folder, "CMakeCache.txt")
        if os.path.exists(cache):
            with open(cache) as f:
                for line in f:
                    if line.startswith("CMAKE_BUILD_TYPE:"):
                        return line.split("=", 1)[1].strip()
        folder = os.path.dirname(folder)
    return "unknown"


def count(x):
    return f"{x:,.0f}".replace(",", " ") if x >= 100 else f"{x:.3g}"


def by_name(run):
    return {b["name"]: b for b in run["benchmarks"] if b.get("run_type", "iteration") == "iteration"}


def factor(x):
    return f"{x:,.0f}×".replace(",", " ") if x >= 100 else f"{x:.2g}×" if x < 1 else f"{x:.1f}×"


def time_of(b):
    unit = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]]
    return b["real_time"] * unit


def duration(seconds):
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("µs", 1e-6), ("ns", 1e-9)):
        if seconds >= scale or unit == "ns":
            v = seconds / scale
            return f"{v:.3g} {unit}" if v < 100 else f"{v:.0f} {unit}"
    return ""


def planner_table(b):
    rows = ["| sample | motion, vpop (s) | motion, lookahead (s) | real time, vpop | "
            "real time, lookahead | evaluations per setpoint, vpop / lookahead | back-offs, vpop "
            "/ lookahead | look-ahead repairs |",
            "|---|---:|---:|---:|---:|---|---|---:|"]
    for family, sample in PLANNED:
        runs = {p: b.get(f"{family}/{sample}_{p}") for p in PLANNERS}
        if not all(runs.values()):
            continue
        v, l = runs["vpop"], runs["lookahead"]
        rows.append(
            f"| `{family}/{sample}` | {v['motion_s']:.3f} | {l['motion_s']:.3f} | "
            f"{factor(v['real_time_factor'])} | {factor(l['real_time_factor'])} | "
            f"{count(v['evals_per_setpoint'])} / {count(l['evals_per_setpoint'])} | "
            f"{count(v['back_offs'])} / {count(l['back_offs'])} | {count(l['repairs'])} |")
    return "\n".join(rows)


def streamed_table(b):
    rows = ["| sample | motion, vpop (s) | motion, lookahead (s) | real time, vpop | "
            "real time, lookahead | back-offs, vpop / lookahead |",
            "|---|---:|---:|---:|---:|---|"]
    for sample in STREAMED:
        runs = {p: b.get(f"Streamed/{sample}_{p}") for p in PLANNERS}
        if not runs["lookahead"]:
            continue
        v, l = runs["vpop"], runs["lookahead"]
        dash = "-"
        rows.append(
            f"| `Streamed/{sample}` | {format(v['motion_s'], '.3f') if v else dash} | "
            f"{l['motion_s']:.3f} | {factor(v['real_time_factor']) if v else dash} | "
            f"{factor(l['real_time_factor'])} | "
            f"{count(v['back_offs']) if v else dash} / {count(l['back_offs'])} |")
    return "\n".join(rows)


def surface_table(b):
    rows = ["| benchmark | threads | time per job | real time | evaluations per setpoint | "
            "Newton iterations per setpoint |", "|---|---:|---:|---:|---:|---:|"]
    for family in ("Surface", "SurfacePlan"):
        for sample in ("tilt10_xyzac", "plane_cl_3axis", "trimmed_face"):
            for threads in (1, 2):
                name = next((n for n in b if n.startswith(f"{family}/{sample}/{threads}")), None)
                if not name:
                    continue
                r = b[name]
                rows.append(f"| `{family}/{sample}` | {threads} | {duration(time_of(r))} | "
                            f"{factor(r['real_time_factor'])} | {r['evals_per_setpoint']:.3g} | "
                            f"{r['newton_per_setpoint']:.3g} |")
    return "\n".join(rows)


def kernel_table(b):
    rows = ["| benchmark | time | what |", "|---|---:|---|"]
    described = [
        ("CurvePointDtis", "a point of the trident, dtis' kernel"),
        ("CurvePointOcct", "the same, OpenCASCADE's `Geom_BSplineCurve::Value`"),
        ("CurveD3Dtis", "point and three derivatives, dtis"),
        ("CurveD3Occt", "the same, OpenCASCADE's `D3`"),
    ]
    for name, what in described:
        if name in b:
            rows.append(f"| `{name}` | {duration(time_of(b[name]))} | {what} |")
    faces = {"0": "trj8 (degree 5 × 3, 21 × 4 poles)", "1": "a rational WorkNC face"}
    walks = {"0": "walking along the face", "1": "at random (u, v)"}
    for name in sorted(n for n in b if n.startswith("SurfaceD2")):
        kernel = "dtis" if "Dtis" in name else "OpenCASCADE `GeomAdaptor_Surface::D2`"
        rational = name.split("rational:")[1][0]
        random = name.split("random:")[1][0]
        rows.append(f"| `{name}` | {duration(time_of(b[name]))} | point and derivatives to order 2 "
                    f"on {faces[rational]}, {walks[random]}: {kernel} |")
    if "GcodeRead" in b:
        r = b["GcodeRead"]
        rows.append(f"| `GcodeRead` | {duration(time_of(r))} | 100 000 blocks read: "
                    f"{r['blocks_per_s'] / 1e6:.1f} million blocks/s |")
    if "GcodeLoad1M" in b:
        r = b["GcodeLoad1M"]
        rows.append(f"| `GcodeLoad1M` | {duration(time_of(r))} | 1 000 000 G1 blocks read and "
                    f"smoothed, {r['corners']:.0f} corners, peak {r['peak_rss_mb']:.0f} MB |")
    for name, what in (("ExportChordalCircle1um", "G1 export of a NURBS circle at 1 µm"),
                       ("ExportFitCircle1um", "B-spline fit of the same circle at 1 µm")):
        if name in b:
            extra = f", {b[name]['poles']:.0f} poles" if "poles" in b[name] else ""
            rows.append(f"| `{name}` | {duration(time_of(b[name]))} | {what}{extra} |")
    return "\n".join(rows)


def tables(run, build_type):
    b = {}
    for name, r in by_name(run).items():
        # Strip the fixed-iteration suffix Google Benchmark adds to the name.
        b[name.replace("/iterations:1", "").replace("/real_time", "")] = r
    ctx = run.get("context", {})
    machine = (f"{ctx.get('num_cpus', '?')} CPUs at {ctx.get('mhz_per_cpu', '?')} MHz, "
               f"{platform.system()} {platform.release()}, dtis built {build_type}")
    return f"""Measured on {machine}, {ctx.get('date', '')}, with
`python3 bench/tables.py --bench build/bench/dtis_bench --update docs/benchmarks.md`.

**Planners** (one core, Δt = 1 ms; real time: seconds of motion planned per second of compute):

{planner_table(b)}

**Streamed** (the same, planned under the 256-period commit horizon of `dtis stream`: what a
stream's planner thread does; `vpop` is not run on the singular pass, where it takes minutes):

{streamed_table(b)}

**Surface jobs** with the default planner (`lookahead`; `Surface/`: end to end, STEP read,
passes built, traced and planned; `SurfacePlan/`: the planning alone with the part loaded, what a
CNC running the job inline pays):

{surface_table(b)}

**Kernels and readers:**

{kernel_table(b)}
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--bench", help="the dtis_bench binary to run")
    src.add_argument("--json", help="a saved dtis_bench JSON run")
    ap.add_argument("--update", help="replace the tables in this Markdown file")
    ap.add_argument("--save", help="with --bench: also keep the run's JSON here")
    a = ap.parse_args()
    if a.json:
        with open(a.json) as f:
            run = json.load(f)
    else:
        run = run_bench(a.bench, a.save)
    text = tables(run, dtis_build_type(a.bench) if a.bench else "(see the run's build)")
    if not a.update:
        print(text)
        return
    replace_block(a.update, "tables", text)


if __name__ == "__main__":
    main()
