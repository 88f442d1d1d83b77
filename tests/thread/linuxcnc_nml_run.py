"""Run one program on LinuxCNC through LinuxCNC's own Python interface, report its lines.

Not a test: :meth:`linuxcnc_sim.LinuxCncSim.run_through_nml` runs this file with Debian's
``python3`` (where the ``linuxcnc`` module of linuxcnc-uspace lives) as the user LinuxCNC runs
as (the status channel's tool table is shared memory of that user). It talks NML, not
linuxcncrsh, so a test can watch a program while the twin holds the only linuxcncrsh session:
linuxcncrsh 2.9 serves each session in a thread over shared state, and a second session
polling beside the twin's has made LinuxCNC exit.

Usage: ``python3 linuxcnc_nml_run.py PROGRAM TIMEOUT_S``. It switches to auto mode, opens and
starts PROGRAM, then polls the status every 5 ms and prints one JSON object per line:
``{"t": s, "line": n}`` whenever the line that motion executes changes (``t`` is
``time.monotonic()``, s), ``{"t": s, "feed_override_pct": p}`` whenever the feed override
changes (for a failing test's message), and last
``{"t": s, "end": "idle", "feed_override_pct": p}`` when the interpreter is idle again, or
``{"t": s, "end": "timeout"}`` after TIMEOUT_S (exit 1).
"""

from __future__ import annotations

import json
import sys
import time

import linuxcnc  # type: ignore[import-not-found]  # Debian's python3 only


def _say(**fields: object) -> None:
    print(json.dumps({"t": time.monotonic(), **fields}), flush=True)


def main(program: str, timeout_s: float) -> int:
    stat = linuxcnc.stat()
    command = linuxcnc.command()
    command.mode(linuxcnc.MODE_AUTO)
    command.wait_complete()
    command.program_open(program)
    command.wait_complete()
    command.auto(linuxcnc.AUTO_RUN, 0)
    deadline = time.monotonic() + timeout_s
    started = False
    last = None
    override = None
    while time.monotonic() < deadline:
        stat.poll()
        if stat.feedrate != override:
            override = stat.feedrate
            _say(feed_override_pct=round(override * 100.0, 3))
        if stat.interp_state != linuxcnc.INTERP_IDLE:
            started = True
        elif started:
            _say(end="idle", feed_override_pct=round(stat.feedrate * 100.0, 3))
            return 0
        if started and stat.motion_line != last:
            last = stat.motion_line
            _say(line=last)
        time.sleep(0.005)
    _say(end="timeout")
    return 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], float(sys.argv[2])))
