"""What the LinuxCNC [DISPLAY] programs of bench/linuxcnc share (driver.py, arm_driver.py).

LinuxCNC starts a [DISPLAY] program as `PROGRAM -ini INI`, with this folder first on its path.
Session holds LinuxCNC's status, command and error channels; wait_for polls the status until a
condition holds, raising LinuxCNC's errors and a timeout; on_and_homed takes the machine out of
E-stop, turns it on and homes it where it stands.
"""
import os
import sys
import time

import linuxcnc


class Session:
    def __init__(self, name):
        self.name = name
        self.s = linuxcnc.stat()
        self.c = linuxcnc.command()
        self.errors = linuxcnc.error_channel()

    def wait_for(self, what, condition, timeout):
        deadline = time.time() + timeout
        while time.time() < deadline:
            self.s.poll()
            error = self.errors.poll()
            if error:
                kind, text = error
                if kind in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR):
                    raise RuntimeError(f"LinuxCNC error while waiting for {what}: {text}")
                print(f"{self.name}: LinuxCNC says: {text}", file=sys.stderr)
            if condition():
                return
            time.sleep(0.01)
        raise RuntimeError(f"timeout after {timeout} s waiting for {what}")

    def on_and_homed(self):
        s, c = self.s, self.c
        self.wait_for("the task to start", lambda: s.task_state == linuxcnc.STATE_ESTOP, 30)
        c.state(linuxcnc.STATE_ESTOP_RESET)
        c.state(linuxcnc.STATE_ON)
        self.wait_for("machine on", lambda: s.task_state == linuxcnc.STATE_ON, 10)
        c.mode(linuxcnc.MODE_MANUAL)
        c.home(-1)
        self.wait_for("homing", lambda: all(s.homed[: s.joints]), 30)


def run_main(main, name, capture_variable):
    """Runs a driver's main; on any error says so, writes the reason to the capture file's
    `.failed` beside it (where the host script looks) and exits 1, which shuts LinuxCNC down."""
    try:
        main()
    except Exception as e:  # noqa: BLE001 - reported, then LinuxCNC shuts down
        print(f"{name}: {e}", file=sys.stderr)
        with open(os.environ[capture_variable] + ".failed", "w") as f:
            f.write(str(e) + "\n")
        sys.exit(1)
