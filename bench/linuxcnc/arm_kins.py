#!/usr/bin/python3
"""LinuxCNC's own arm kinematics as a reference for dtis' serial arms.

Runs LinuxCNC 2.9 headless with genserkins and the DH pins of its PUMA 560 simulation as it ships
(sample-configs/sim/axis/vismach/puma/puma560_dh.hal, inch, deg) and the joint limits of its
puma560.ini; a [DISPLAY] program, arm_driver.py, jogs the joints to a few postures and records the
world pose genserkins puts each at. The lines (six joints in deg, then X Y Z in inch and A B C in
deg) are written to --out; tests/serial_arm_test.cpp checks dtis' arm, imported from puma560.ini,
against the committed copy (tests/data/linuxcnc_arm/puma560_genserkins.txt): the same pose from the
same joints, and the same joints from the pose.

Usage (as root or a user who may run LinuxCNC; needs linuxcnc-uspace and the system python):
  /usr/bin/python3 bench/linuxcnc/arm_kins.py [--out FILE] [--check FILE]
--check compares a fresh run with FILE instead of writing one: the jogs stop within 1e-6 deg of
their goal, so the joints, and the poses with them, agree to 1e-5.
"""
import argparse
import pathlib
import sys
import tempfile

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from reference import (  # noqa: E402
    HOMED_WHERE_IT_STANDS, fail, hal_environment, ini_head, run_linuxcnc)

PUMA = pathlib.Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/puma")
# Postures away from the singularities, within puma560.ini's joint limits (deg).
POSTURES = [
    [10, -30, -60, 20, 45, 0],
    [-35, 20, -120, -40, 70, 15],
    [60, -50, -20, 90, -30, -25],
    [0, 40, -150, 10, 100, 5],
]
# puma560.ini's joint limits (MIN, MAX, HOME).
JOINTS = [(-180, 180, 0), (-360, 360, 0), (-215, 35, 0), (-360, 360, 0), (-360, 360, 0.1),
          (-360, 360, 0)]


def write_config(folder):
    hal = [
        "loadrt [KINS]KINEMATICS",
        "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS",
        "addf motion-command-handler servo-thread",
        "addf motion-controller servo-thread",
        "net estop-loop iocontrol.0.user-enable-out iocontrol.0.emc-enable-in",
        "net tool-prep-loop iocontrol.0.tool-prepare iocontrol.0.tool-prepared",
        "net tool-change-loop iocontrol.0.tool-change iocontrol.0.tool-changed",
    ]
    for j in range(6):
        hal.append(f"net j{j} joint.{j}.motor-pos-cmd => joint.{j}.motor-pos-fb")
    (folder / "arm.hal").write_text("\n".join(hal) + "\n")
    (folder / "tool.tbl").write_text("T1 P1 D0 Z0 ;dtis reference\n")
    (folder / "sim.var").write_text("")
    ini = ini_head("dtis-arm-reference", HERE / "arm_driver.py", folder,
                   [folder / "arm.hal", PUMA / "puma560_dh.hal"]) + f"""[TRAJ]
COORDINATES = X Y Z A B C
LINEAR_UNITS = inch
ANGULAR_UNITS = deg
MAX_LINEAR_VELOCITY = 10.0
MAX_ANGULAR_VELOCITY = 100
POSITION_FILE = {folder}/position.txt
[KINS]
KINEMATICS = genserkins
JOINTS = 6
"""
    for letter in "XYZABC":
        lim = 100 if letter in "XYZ" else 360
        ini += f"""[AXIS_{letter}]
MAX_VELOCITY = 30.0
MAX_ACCELERATION = 200.0
MIN_LIMIT = -{lim}
MAX_LIMIT = {lim}
"""
    for j, (lo, hi, home) in enumerate(JOINTS):
        ini += f"""[JOINT_{j}]
TYPE = ANGULAR
MAX_VELOCITY = 30.0
MAX_ACCELERATION = 200.0
MIN_LIMIT = {lo}
MAX_LIMIT = {hi}
HOME = {home}
{HOMED_WHERE_IT_STANDS}"""
    (folder / "arm.ini").write_text(ini)
    return folder / "arm.ini"


def run(folder):
    ini = write_config(folder)
    capture = folder / "capture.txt"
    env = hal_environment(folder)
    env.update(DTIS_ARM_JOINTS=";".join(",".join(str(v) for v in p) for p in POSTURES),
               DTIS_ARM_CAPTURE=str(capture))
    run_linuxcnc(ini, folder, env, capture, 600)
    rows = [[float(v) for v in line.split()] for line in capture.read_text().splitlines()]
    if len(rows) != len(POSTURES) or any(len(r) != 12 for r in rows):
        fail(f"unexpected capture {capture}")
    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", help="write the recorded lines here")
    p.add_argument("--check", help="compare a fresh run with this recording")
    args = p.parse_args()
    if not PUMA.exists():
        fail(f"{PUMA} is missing: install linuxcnc-uspace")
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        folder.chmod(0o755)
        rows = run(folder)
    text = "".join(" ".join(repr(v) for v in r) + "\n" for r in rows)
    if args.check:
        kept = [[float(v) for v in line.split()]
                for line in pathlib.Path(args.check).read_text().splitlines()
                if line.strip() and not line.startswith("#")]
        worst = max(abs(a - b) for r, k in zip(rows, kept) for a, b in zip(r, k))
        if len(kept) != len(rows) or worst > 1e-5:
            fail(f"LinuxCNC's genserkins now gives other poses than {args.check} "
                 f"(largest difference {worst:g})")
        print(f"arm_kins: {len(rows)} postures agree with {args.check} (largest difference "
              f"{worst:g})")
    if args.out:
        header = ("# LinuxCNC 2.9 genserkins, puma560_dh.hal: joints J1..J6 (deg), then X Y Z "
                  "(inch) and A B C (deg); bench/linuxcnc/arm_kins.py\n")
        pathlib.Path(args.out).write_text(header + text)
    if not args.out and not args.check:
        sys.stdout.write(text)


if __name__ == "__main__":
    main()
