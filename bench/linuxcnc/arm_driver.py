#!/usr/bin/python3
"""LinuxCNC [DISPLAY] program of bench/linuxcnc/arm_kins.py: moves a serial arm's joints, headless.

LinuxCNC starts it as `arm_driver.py -ini INI`. It homes the arm where it stands, switches to joint
mode and, for each joint vector of DTIS_ARM_JOINTS (deg, ";" between vectors, "," between joints),
jogs every joint there by increments, waits until they hold it, and records the joints and the world
pose LinuxCNC's kinematics module puts them at (stat.joint_actual_position, stat.actual_position).
Writes one line per vector to DTIS_ARM_CAPTURE: twelve numbers, the joints then X Y Z A B C.
"""
import os
import time

import linuxcnc
from session import Session, run_main


def main():
    targets = [[float(v) for v in t.split(",")] for t in os.environ["DTIS_ARM_JOINTS"].split(";")]
    capture = os.environ["DTIS_ARM_CAPTURE"]
    session = Session("arm_driver")
    s, c, wait_for = session.s, session.c, session.wait_for
    session.on_and_homed()
    c.teleop_enable(0)
    wait_for("joint mode", lambda: s.motion_mode == linuxcnc.TRAJ_MODE_FREE, 10)
    with open(capture, "w") as out:
        for target in targets:
            s.poll()
            for j, goal in enumerate(target):
                delta = goal - s.joint_actual_position[j]
                if abs(delta) > 0.0:
                    velocity = 30.0 if delta > 0 else -30.0
                    c.jog(linuxcnc.JOG_INCREMENT, 1, j, velocity, abs(delta))
            wait_for("the joints to arrive", lambda: s.inpos and all(
                abs(s.joint_actual_position[j] - g) < 1e-6 for j, g in enumerate(target)), 120)
            time.sleep(0.2)
            s.poll()
            values = list(s.joint_actual_position[:6]) + list(s.actual_position[:6])
            out.write(" ".join(repr(v) for v in values) + "\n")
    c.state(linuxcnc.STATE_OFF)


if __name__ == "__main__":
    run_main(main, "arm_driver", "DTIS_ARM_CAPTURE")
