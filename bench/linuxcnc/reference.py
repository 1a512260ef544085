#!/usr/bin/python3
"""LinuxCNC's own trajectory planner as a reference for dtis.

Runs G-code programs through LinuxCNC 2.9's planner headless (a [DISPLAY] program, driver.py,
drives the `linuxcnc` Python module; a sampler records the joint positions every 1 ms servo
period) on the axis limits of a dtis machine file, and prints its motion time beside dtis' own:
dtis with the machine's jerk limits, and dtis with every jerk limit x1000 (LinuxCNC 2.9 has no jerk
limit, so that is the like-for-like figure). LinuxCNC's recorded motion is checked against the
velocity and acceleration limits with `dtis verify` (its jerk is unbounded by design).

Usage (as root or a user who may run LinuxCNC; needs linuxcnc-uspace and the system python):
  /usr/bin/python3 bench/linuxcnc/reference.py --dtis build/cli/dtis [--out DIR] [--markdown F]
Cases: the lock sample (samples/jobs/lock.toml) and the G1 exports at 10 and 1 um of the 3-axis
plane_cl surface job (dtis compare --exports). Every program runs with G64 P<the job's contour
tolerance>, LinuxCNC's blend tolerance, as dtis smooths corners within it.
"""
import argparse
import csv
import fcntl
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parent.parent
JERK_FACTOR = 1000.0
# mm/s, mm/s^2 per unit of a dtis machine file (kinematics/src/machine_file.cpp).
VELOCITY = {"mm/s": 1.0, "mm/min": 1.0 / 60.0, "m/s": 1000.0, "m/min": 1000.0 / 60.0}
ACCELERATION = {"mm/s^2": 1.0, "m/s^2": 1000.0}


def fail(message):
    print(f"reference: {message}", file=sys.stderr)
    sys.exit(1)


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        fail(f"{' '.join(map(str, cmd))} failed ({r.returncode}):\n{r.stdout}{r.stderr}")
    return r


class Machine:
    def __init__(self, path):
        self.path = pathlib.Path(path).resolve()
        self.text = self.path.read_text()
        t = tomllib.loads(self.text)
        if t.get("kinematics") != "xyz":
            fail(f"{path}: only Cartesian xyz machines are set up in LinuxCNC here (trivkins)")
        units = t["units"]
        if units.get("length", "mm") != "mm":
            fail(f"{path}: length unit {units.get('length')}; this script speaks mm")
        v = VELOCITY[units["linear_velocity"]]
        a = ACCELERATION[units["linear_acceleration"]]
        self.axes = []
        for name in "XYZ":
            ax = t["axes"][name]
            self.axes.append({"name": name, "min": ax["travel"][0], "max": ax["travel"][1],
                              "v": ax["velocity"] * v, "a": ax["acceleration"] * a})

    def with_high_jerk(self, path):
        """The same machine with every jerk limit times JERK_FACTOR."""
        def times(m):
            return f"{m.group(1)}{float(m.group(2)) * JERK_FACTOR:g}"
        text = re.sub(r"^(\s*jerk\s*=\s*)([0-9.eE+-]+)", times, self.text, flags=re.M)
        path.write_text(f"# {self.path.name} with every jerk limit x{JERK_FACTOR:g}\n" + text)
        return path


BLEND_RAPIDS = True  # --stop-at-rapids: dtis stops at every G0 vertex (blend_rapids = false)


def dtis_run(dtis, machine, program, tol, out_csv, job_path):
    job_path.write_text(f'machine = "{machine}"\nperiod_ms = 1.0\n\n[path]\nkind = "gcode"\n'
                        f'file = "{program}"\ncontour_tol_mm = {tol}\n'
                        + ("" if BLEND_RAPIDS else "blend_rapids = false\n"))
    # The paper's planner: the table in docs/benchmarks.md was made with it.
    r = run([dtis, "run", job_path, "--planner", "vpop", "-o", out_csv])
    return float(re.search(r"motion time\s+([0-9.]+) s", r.stderr).group(1))


def job_with_machine(job, machine, path):
    """A copy of `job` on `machine`, its other file references made absolute."""
    def absolute(m):
        target = machine if m.group(2) == "machine" else (job.parent / m.group(3)).resolve()
        return f'{m.group(1)}{target}"'
    text = re.sub(r'^(\s*(machine|file)\s*=\s*")([^"]+)"', absolute, job.read_text(), flags=re.M)
    path.write_text(text)
    return path


def compare_pass_times(dtis, job, folder, exports=None):
    """dtis compare's time on the passes alone (feed moves, no links), per variant."""
    table = folder / "compare.csv"
    cmd = [dtis, "compare", job, "--csv", table, "-q"]
    if exports:
        cmd += ["--exports", exports]
    run(cmd)
    with open(table) as f:
        return {r["variant"]: float(r["pass_time_s"]) for r in csv.DictReader(f)}


def motion_window(rows):
    """First and last period of motion: the last row at rest before the first move, the first
    row of the final rest."""
    first = next((i for i in range(1, len(rows)) if rows[i] != rows[0]), None)
    if first is None:
        return None
    last = next(i for i in range(len(rows) - 1, 0, -1) if rows[i - 1] != rows[-1])
    return first - 1, last


def read_csv_positions(path):
    with open(path) as f:
        next(f)
        return [tuple(float(x) for x in line.split(",")[1:]) for line in f]


def linuxcnc_program(program, tol, path):
    """The program with LinuxCNC's blend tolerance G64 P<tol> (Q: same, its default)."""
    lines = pathlib.Path(program).read_text().splitlines()
    at = 1 if lines and lines[0].strip() == "%" else 0
    lines.insert(at, f"G64 P{tol}")
    path.write_text("\n".join(lines) + "\n")
    return path


# A joint's homing keys when it is homed where it stands (no search, no latch, all at once).
HOMED_WHERE_IT_STANDS = """HOME_OFFSET = 0
HOME_SEARCH_VEL = 0
HOME_LATCH_VEL = 0
HOME_SEQUENCE = 0
"""


def ini_head(machine, display, folder, halfiles):
    """The sections of a headless configuration's INI that do not depend on the machine, up to
    [TRAJ]: its [DISPLAY] program, one task and motion cycle of 1 ms, and its HAL files in order."""
    hal = "".join(f"HALFILE = {f}\n" for f in halfiles)
    return f"""[EMC]
VERSION = 1.1
MACHINE = {machine}
[DISPLAY]
DISPLAY = {display}
[TASK]
TASK = milltask
CYCLE_TIME = 0.001
[RS274NGC]
PARAMETER_FILE = {folder}/sim.var
[EMCIO]
EMCIO = io
CYCLE_TIME = 0.100
TOOL_TABLE = {folder}/tool.tbl
[EMCMOT]
EMCMOT = motmod
COMM_TIMEOUT = 1.0
SERVO_PERIOD = 1000000
[HAL]
{hal}"""


def run_linuxcnc(ini, folder, env, capture, timeout_s):
    """Runs LinuxCNC on `ini` headless, alone on this host (one HAL session per host), its output
    in folder/linuxcnc.log; fails unless its [DISPLAY] program wrote `capture` (it writes
    capture.failed with the reason when it cannot)."""
    with open("/tmp/dtis-hal.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        subprocess.run(["halrun", "-U"], capture_output=True, env=env)
        with open(folder / "linuxcnc.log", "w") as log:
            r = subprocess.run(["timeout", str(timeout_s), "linuxcnc", str(ini)], stdout=log,
                               stderr=subprocess.STDOUT, env=env)
        subprocess.run(["halrun", "-U"], capture_output=True, env=env)
    failed = pathlib.Path(str(capture) + ".failed")
    if failed.exists() or not capture.exists():
        fail(f"LinuxCNC run failed (exit {r.returncode}); see {folder}/linuxcnc.log: "
             f"{failed.read_text().strip() if failed.exists() else 'no capture'}")


def write_config(machine, folder, driver):
    ax = machine.axes
    hal = [
        "loadrt [KINS]KINEMATICS",
        "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS",
        "loadrt sampler depth=16384 cfg=fffs",
        "addf motion-command-handler servo-thread",
        "addf motion-controller servo-thread",
        "addf sampler.0 servo-thread",
        "setp sampler.0.enable 0",  # driver.py enables it when the program starts
    ]
    for j in range(3):
        hal.append(f"net j{j} joint.{j}.motor-pos-cmd => joint.{j}.motor-pos-fb sampler.0.pin.{j}")
    hal += [
        "net mtype motion.motion-type => sampler.0.pin.3",
        "net estop-loop iocontrol.0.user-enable-out iocontrol.0.emc-enable-in",
        "net tool-prep-loop iocontrol.0.tool-prepare iocontrol.0.tool-prepared",
        "net tool-change-loop iocontrol.0.tool-change iocontrol.0.tool-changed",
    ]
    (folder / "machine.hal").write_text("\n".join(hal) + "\n")
    (folder / "tool.tbl").write_text("T1 P1 D6 Z0 ;dtis reference\n")
    (folder / "sim.var").write_text("")
    vmax = max(a["v"] for a in ax)
    amax = sum(a["a"] for a in ax)
    ini = ini_head("dtis-reference", driver, folder, [folder / "machine.hal"]) + f"""[TRAJ]
COORDINATES = XYZ
LINEAR_UNITS = mm
ANGULAR_UNITS = degree
MAX_LINEAR_VELOCITY = {2 * vmax}
MAX_LINEAR_ACCELERATION = {amax}
POSITION_FILE = {folder}/position.txt
[KINS]
KINEMATICS = trivkins coordinates=XYZ
JOINTS = 3
"""
    for j, a in enumerate(ax):
        ini += f"""[AXIS_{a['name']}]
MIN_LIMIT = {a['min']}
MAX_LIMIT = {a['max']}
MAX_VELOCITY = {a['v']}
MAX_ACCELERATION = {a['a']}
[JOINT_{j}]
TYPE = LINEAR
MIN_LIMIT = {a['min']}
MAX_LIMIT = {a['max']}
MAX_VELOCITY = {a['v']}
MAX_ACCELERATION = {a['a']}
HOME = 0
{HOMED_WHERE_IT_STANDS}"""
    (folder / "machine.ini").write_text(ini)
    return folder / "machine.ini"


def hal_environment(folder):
    """rtapi_app refuses plain root: it runs as RTAPI_UID with its socket in a folder it owns."""
    env = dict(os.environ)
    if os.geteuid() == 0:
        if subprocess.run(["id", "dtis-hal"], capture_output=True).returncode != 0:
            run(["useradd", "--system", "--no-create-home", "--shell", "/usr/sbin/nologin",
                 "dtis-hal"])
        env["RTAPI_UID"] = run(["id", "-u", "dtis-hal"]).stdout.strip()
        rt = folder / "rtapi"
        rt.mkdir(exist_ok=True)
        shutil.chown(rt, user="dtis-hal")
        rt.chmod(0o700)
        env["RTAPI_FIFO_PATH"] = str(rt / "rtapi")
    return env


def linuxcnc_run(machine, program, start, folder, recorder):
    """Runs the program through LinuxCNC; returns the recorded rows (x, y, z, motion type)."""
    folder.mkdir(parents=True, exist_ok=True)
    ini = write_config(machine, folder, HERE / "driver.py")
    capture = folder / "capture.txt"
    env = hal_environment(folder)
    env.update(DTIS_TP_PROGRAM=str(program), DTIS_TP_START=start, DTIS_TP_CAPTURE=str(capture),
               DTIS_TP_RECORDER=recorder)
    run_linuxcnc(ini, folder, env, capture, 3600)
    rows = []
    for line in capture.read_text().split("\n"):
        f = line.split()
        if len(f) == 5:  # halsampler: sample number, then the pins
            f = f[1:]
        if len(f) == 4:
            rows.append((float(f[0]), float(f[1]), float(f[2]), int(f[3])))
    return rows


def verify(dtis, positions, machine, path):
    with open(path, "w") as f:
        f.write("t,X,Y,Z\n")
        for k, p in enumerate(positions):
            f.write(f"{k * 0.001:.3f},{p[0]!r},{p[1]!r},{p[2]!r}\n")
    r = subprocess.run([dtis, "verify", path, machine], capture_output=True, text=True)
    worst_v = worst_a = 0.0
    for line in r.stdout.splitlines():
        f = line.split()
        if len(f) == 4 and f[0] in "XYZ" and len(f[0]) == 1:
            worst_v = max(worst_v, float(f[1]))
            worst_a = max(worst_a, float(f[2]))
    return worst_v, worst_a


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--dtis", default=str(ROOT / "build/cli/dtis"))
    p.add_argument("--out", help="keep the runs here (default: a temporary folder)")
    p.add_argument("--markdown", help="also write the table here")
    p.add_argument("--cases", default="lock,plane_cl",
                   help="comma-separated: lock, plane_cl (its G1 exports at 10 and 1 um)")
    p.add_argument("--capture", default=str(ROOT / "build/tests/hal_capture"),
                   help="full-precision sampler reader (tests/hal_capture.cpp); halsampler (6 "
                        "decimals) when it is not built")
    p.add_argument("--stop-at-rapids", action="store_true",
                   help="dtis jobs with blend_rapids = false (a stop at every G0 vertex)")
    a = p.parse_args()
    global BLEND_RAPIDS
    BLEND_RAPIDS = not a.stop_at_rapids
    capture = pathlib.Path(a.capture)
    recorder = f"{capture.resolve()} 0" if capture.exists() else "halsampler -c 0"
    print(f"recording with {recorder}", file=sys.stderr)
    if shutil.which("linuxcnc") is None:
        fail("linuxcnc not found: apt install linuxcnc-uspace")
    dtis = str(pathlib.Path(a.dtis).resolve())
    out = pathlib.Path(a.out or tempfile.mkdtemp(prefix="dtis-tp-")).resolve()
    out.mkdir(parents=True, exist_ok=True)
    out.chmod(0o755)  # rtapi_app's user must reach its socket folder inside

    # The cases: (name, program, machine file, contour tolerance, dtis' feed-move time with jerk
    # x1000 when dtis compare times it apart from the links, else None).
    lock = tomllib.loads((ROOT / "samples/jobs/lock.toml").read_text())
    cases = [("lock", ROOT / "samples/gcode/lock.ngc", ROOT / "samples/machines" /
              pathlib.Path(lock["machine"]).name, lock["path"]["contour_tol_mm"], None)]
    wanted = set(a.cases.split(","))
    if not wanted <= {"lock", "plane_cl"}:
        fail(f"--cases {a.cases}: expected lock and/or plane_cl")
    if "lock" not in wanted:
        cases = []
    exact_passes = None
    if "plane_cl" in wanted:
        job = ROOT / "samples/jobs/surface_plane_cl_3axis.toml"
        t = tomllib.loads(job.read_text())
        machine_file = (job.parent / t["machine"]).resolve()
        folder = out / "compare"
        folder.mkdir(exist_ok=True)
        exports = out / "exports"
        compare_pass_times(dtis, job, folder, exports)
        fast = Machine(machine_file).with_high_jerk(folder / "machine_jerk_x1000.toml")
        passes = compare_pass_times(
            dtis, job_with_machine(job, fast, folder / "job_jerk_x1000.toml"), folder)
        exact_passes = passes["DTIS (exact surface)"]
        tol = t.get("compare", {}).get("contour_tol_mm", 0.02)
        for um in (10, 1):
            cases.append((f"plane_cl G1 {um} um", exports / f"{job.stem}_g1_{um}um.ngc",
                          machine_file, tol, passes[f"G1 {um} um"]))

    table = []
    for name, program, machine_file, tol, dtis_passes in cases:
        slug = re.sub(r"[^a-z0-9]+", "_", name.lower())
        folder = out / slug
        folder.mkdir(exist_ok=True)
        machine = Machine(machine_file)
        fast = machine.with_high_jerk(folder / "machine_jerk_x1000.toml")
        t_dtis = dtis_run(dtis, machine.path, program, tol, folder / "dtis.csv", folder / "job.toml")
        t_fast = dtis_run(dtis, fast, program, tol, folder / "dtis_jerk_x1000.csv",
                          folder / "job_jerk_x1000.toml")
        first = read_csv_positions(folder / "dtis.csv")[0]
        start = "G0 " + " ".join(f"{ax['name']}{v:.6f}" for ax, v in zip(machine.axes, first))
        wall = time.time()
        rows = linuxcnc_run(machine, linuxcnc_program(program, tol, folder / "program.ngc"),
                            start, folder / "linuxcnc", recorder)
        wall = time.time() - wall
        positions = [r[:3] for r in rows]
        window = motion_window(positions)
        if window is None:
            fail(f"{name}: LinuxCNC did not move")
        t_lcnc = (window[1] - window[0]) * 0.001
        # Feed moves: the periods whose motion LinuxCNC labels feed (motion.motion-type 2).
        feed_lcnc = 0.001 * sum(1 for k in range(window[0] + 1, window[1] + 1)
                                if rows[k][3] == 2 and rows[k][:3] != rows[k - 1][:3])
        worst_v, worst_a = verify(dtis, positions[window[0]:window[1] + 1], str(fast),
                                  folder / "linuxcnc.csv")
        # The same window measure on dtis' own setpoints.
        wd = motion_window(read_csv_positions(folder / "dtis_jerk_x1000.csv"))
        t_window = (wd[1] - wd[0]) * 0.001
        table.append((name, t_dtis, t_fast, t_window, t_lcnc, dtis_passes, feed_lcnc, worst_v,
                      worst_a))
        print(f"{name}: dtis {t_dtis:.3f} s, dtis jerk x1000 {t_fast:.3f} s, LinuxCNC {t_lcnc:.3f} s "
              f"(run {wall:.0f} s)", file=sys.stderr)

    head = ("| program | dtis, machine jerk (s) | dtis, jerk x1000 (s) | first to last move (s) | "
            "LinuxCNC 2.9 TP (s) | feed moves: dtis, jerk x1000 (s) | feed moves: LinuxCNC (s) | "
            "LinuxCNC worst v ratio | LinuxCNC worst a ratio |\n"
            "|---|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    body = "".join(f"| {n} | {a:.3f} | {b:.3f} | {c:.3f} | {d:.3f} | "
                   f"{'-' if e is None else f'{e:.3f}'} | {f:.3f} | {v:.4f} | {acc:.4f} |\n"
                   for n, a, b, c, d, e, f, v, acc in table)
    if exact_passes is not None:
        body += (f"\nplane_cl on the exact surface (dtis compare, jerk x1000): feed moves "
                 f"{exact_passes:.3f} s\n")
    print(head + body, end="")
    if a.markdown:
        pathlib.Path(a.markdown).write_text(head + body)
    if not a.out:
        shutil.rmtree(out)


if __name__ == "__main__":
    main()
