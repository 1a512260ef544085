#!/usr/bin/python3
"""LinuxCNC [DISPLAY] program of bench/linuxcnc/reference.py: runs one G-code program headless.

LinuxCNC starts it as `driver.py -ini INI`. It homes the machine where it stands, moves (MDI G0) to
the program's start, enables sampler.0 (joint positions and motion.motion-type, one line per servo
period, read by halsampler), runs the program in AUTO, waits until motion is done, stops the recording
and exits, which shuts LinuxCNC down. Environment: DTIS_TP_PROGRAM (the .ngc), DTIS_TP_START
("G0 X.. Y.. Z.."), DTIS_TP_CAPTURE (where the recording goes), DTIS_TP_RECORDER (the command
that reads sampler.0, default `halsampler -c 0`). Exit status 0 on success.
"""
import os
import signal
import subprocess
import time

import linuxcnc
from session import Session, run_main


def main():
    program = os.environ["DTIS_TP_PROGRAM"]
    start = os.environ["DTIS_TP_START"]
    capture = os.environ["DTIS_TP_CAPTURE"]
    session = Session("driver")
    s, c, wait_for = session.s, session.c, session.wait_for
    session.on_and_homed()
    c.mode(linuxcnc.MODE_MDI)
    wait_for("MDI mode", lambda: s.task_mode == linuxcnc.MODE_MDI, 10)
    c.mdi(start)
    wait_for("the move to the start", lambda: s.interp_state == linuxcnc.INTERP_IDLE and s.inpos
             and s.queue == 0, 60)

    with open(capture, "w") as out:
        recorder = os.environ.get("DTIS_TP_RECORDER", "halsampler -c 0").split()
        sampler = subprocess.Popen(recorder, stdout=out)
        c.mode(linuxcnc.MODE_AUTO)
        wait_for("AUTO mode", lambda: s.task_mode == linuxcnc.MODE_AUTO, 10)
        c.program_open(program)
        # The recording starts with the program (the HAL file loads the sampler disabled).
        subprocess.run(["halcmd", "setp", "sampler.0.enable", "1"], check=True)
        c.auto(linuxcnc.AUTO_RUN, 0)
        wait_for("the program to start", lambda: s.interp_state != linuxcnc.INTERP_IDLE, 10)
        wait_for("the program to end", lambda: s.interp_state == linuxcnc.INTERP_IDLE and s.inpos
                 and s.queue == 0, 3600)
        time.sleep(0.3)
        sampler.send_signal(signal.SIGINT)
        sampler.wait(timeout=20)
    c.state(linuxcnc.STATE_OFF)


if __name__ == "__main__":
    run_main(main, "driver", "DTIS_TP_CAPTURE")
