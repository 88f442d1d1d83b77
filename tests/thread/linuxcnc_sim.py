"""LinuxCNC's simulator for the tests: started headless with linuxcncrsh, always shut down.

:class:`LinuxCncSim` writes a simulation configuration (INI with LinuxCNC's own
``basic_sim.tcl`` HAL, a tool table) into a fresh folder, starts ``linuxcnc`` there as an
unprivileged user (LinuxCNC refuses root; as root the user ``cnctwin-lcnc`` is created once,
idempotently) in its own process group, and waits until linuxcncrsh listens. Only one LinuxCNC
runs on a machine at a time (its HAL shared memory): a file lock serializes the processes
that use it. :meth:`LinuxCncSim.run_through_nml` runs a program through LinuxCNC's own Python
interface (:mod:`linuxcnc_nml_run`), so that a test can watch it without a second linuxcncrsh
session beside the twin's. :meth:`LinuxCncSim.stop` sends TERM to the process group
(linuxcncrsh ends, and the ``linuxcnc`` script's own clean-up ends its servers and
``rtapi_app``, which run in sessions of their own), KILL after 60 s, and unloads what HAL left
(``halrun -U``).

:class:`Operator` is the person at the machine: its own linuxcncrsh session, written here
from the protocol (``man linuxcncrsh``) and independent of :mod:`cnctwin.thread.linuxcnc`, that
brings the machine up, runs a program and watches the machine's own answers.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import pwd
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import pytest
from skips import missing

USER = "cnctwin-lcnc"
LOCK = Path(tempfile.gettempdir()) / "cnctwin-linuxcnc.lock"
#: Debian's interpreter, where linuxcnc-uspace puts the ``linuxcnc`` module.
SYSTEM_PYTHON = "/usr/bin/python3"
NML_RUN = Path(__file__).with_name("linuxcnc_nml_run.py")
LIMITS = {"X": (-50.0, 100.0), "Y": (-50.0, 100.0), "Z": (-50.0, 50.0)}

INI = """\
[EMC]
VERSION = 1.1
MACHINE = cnctwin-test-sim
[DISPLAY]
DISPLAY = linuxcncrsh -p {port}
[TASK]
TASK = milltask
CYCLE_TIME = 0.001
[RS274NGC]
PARAMETER_FILE = sim.var
[EMCIO]
EMCIO = io
CYCLE_TIME = 0.100
TOOL_TABLE = sim.tbl
[EMCMOT]
EMCMOT = motmod
SERVO_PERIOD = 1000000
[HAL]
HALFILE = LIB:basic_sim.tcl -no_use_hal_manualtoolchange
[TRAJ]
COORDINATES = XYZ
LINEAR_UNITS = mm
ANGULAR_UNITS = degree
MAX_LINEAR_VELOCITY = 50
[KINS]
JOINTS = 3
KINEMATICS = trivkins coordinates=XYZ
{axes}"""

AXIS = """\
[AXIS_{axis}]
MIN_LIMIT = {low}
MAX_LIMIT = {high}
MAX_VELOCITY = 50
MAX_ACCELERATION = 500
[JOINT_{joint}]
TYPE = LINEAR
MIN_LIMIT = {low}
MAX_LIMIT = {high}
MAX_VELOCITY = 50
MAX_ACCELERATION = 500
HOME_SEQUENCE = 0
"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _ensure_user() -> str | None:
    """The user to run LinuxCNC as: ``None`` (this one) unless root, then :data:`USER`."""
    if os.geteuid() != 0:
        return None
    try:
        pwd.getpwnam(USER)
    except KeyError:
        subprocess.run(
            [
                "useradd",
                "--system",
                "--create-home",
                "--home-dir",
                f"/var/lib/{USER}",
                "--shell",
                "/usr/sbin/nologin",
                USER,
            ],
            check=False,
            capture_output=True,
        )
        pwd.getpwnam(USER)  # raises if useradd failed for a reason other than a race
    return USER


class LinuxCncSim:
    """One LinuxCNC simulator (see the module docstring)."""

    def __init__(self, program: Path) -> None:
        if shutil.which("linuxcnc") is None or shutil.which("linuxcncrsh") is None:
            missing(
                "LinuxCNC is not installed (Debian package linuxcnc-uspace)",
                "CNCTWIN_REQUIRE_SERVICES",
            )
        self.program_source = program
        self.port = 0
        self.folder = Path()
        self.program = Path()
        self._proc: subprocess.Popen[bytes] | None = None
        self._lock: int | None = None
        self._user: str | None = None

    def start(self) -> None:
        """Write the configuration, start LinuxCNC, wait until linuxcncrsh answers."""
        if self._lock is None:
            self._lock = os.open(LOCK, os.O_RDWR | os.O_CREAT, 0o666)
            fcntl.flock(self._lock, fcntl.LOCK_EX)
        self._user = _ensure_user()
        self.folder = Path(tempfile.mkdtemp(prefix="cnctwin-lcnc-"))
        self.port = free_port()
        axes = "".join(
            AXIS.format(axis=axis, joint=i, low=low, high=high)
            for i, (axis, (low, high)) in enumerate(LIMITS.items())
        )
        (self.folder / "sim.ini").write_text(INI.format(port=self.port, axes=axes))
        (self.folder / "sim.tbl").write_text("T1 P1 D1.4 Z0 ;1.4 mm flat end mill\n")
        self.program = self.folder / "program.ngc"
        shutil.copyfile(self.program_source, self.program)
        if self._user is not None:
            shutil.chown(self.folder, self._user)
            for path in self.folder.iterdir():
                shutil.chown(path, self._user)
        self._launch()

    @property
    def alive(self) -> bool:
        """Whether the ``linuxcnc`` script started here still runs."""
        return self._proc is not None and self._proc.poll() is None

    def log_tail(self, n_chars: int = 3000) -> str:
        """The end of LinuxCNC's own output (its log in the folder), for a failure message."""
        try:
            return (self.folder / "linuxcnc.log").read_text(errors="replace")[-n_chars:]
        except OSError as exc:
            return f"(no LinuxCNC log: {exc})"

    def ensure_running(self) -> None:
        """Start LinuxCNC again if an earlier test's LinuxCNC died, so one crash fails one
        test, not every later one."""
        if not self.alive:
            self._end(signal.SIGTERM)
            self._launch()

    def run_through_nml(self, program: Path, timeout_s: float) -> subprocess.Popen[str]:
        """Start :mod:`linuxcnc_nml_run` on ``program``: its JSON lines come on stdout."""
        probe = subprocess.run(
            [SYSTEM_PYTHON, "-c", "import linuxcnc"], capture_output=True, check=False
        )
        if probe.returncode != 0:
            missing(
                f"{SYSTEM_PYTHON} has no linuxcnc module (Debian package linuxcnc-uspace)",
                "CNCTWIN_REQUIRE_SERVICES",
            )
        return subprocess.Popen(
            [*self._as_user(), SYSTEM_PYTHON, str(NML_RUN), str(program), str(timeout_s)],
            cwd=self.folder,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )

    def _as_user(self) -> list[str]:
        return ["runuser", "-u", self._user, "--"] if self._user else []

    def _launch(self) -> None:
        prefix = self._as_user()
        home = pwd.getpwnam(self._user).pw_dir if self._user else os.environ.get("HOME", "/tmp")
        self._proc = subprocess.Popen(
            [*prefix, "env", f"HOME={home}", "linuxcnc", "sim.ini"],
            cwd=self.folder,
            stdin=subprocess.DEVNULL,
            stdout=open(self.folder / "linuxcnc.log", "wb"),  # noqa: SIM115 (kept for the run)
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        deadline = time.monotonic() + 90.0
        while time.monotonic() < deadline:
            if self._proc.poll() is not None:
                log = (self.folder / "linuxcnc.log").read_text(errors="replace")[-2000:]
                pytest.fail(f"LinuxCNC exited with {self._proc.returncode} at start:\n{log}")
            with (
                contextlib.suppress(OSError),
                socket.create_connection(("127.0.0.1", self.port), timeout=1.0),
            ):
                return
            time.sleep(0.2)
        pytest.fail("linuxcncrsh did not listen within 90 s")

    def kill(self) -> None:
        """End LinuxCNC as Ctrl-C does: TERM to its process group (linuxcncrsh goes at once,
        the ``linuxcnc`` script then unloads HAL and ends its servers)."""
        self._end(signal.SIGTERM)

    def restart(self) -> None:
        """Start LinuxCNC again in the same folder, on the same port."""
        self._launch()

    def stop(self) -> None:
        """End LinuxCNC (TERM, then KILL), unload HAL, release the lock, remove the folder."""
        try:
            self._end(signal.SIGTERM)
        finally:
            shutil.rmtree(self.folder, ignore_errors=True)
            if self._lock is not None:
                fcntl.flock(self._lock, fcntl.LOCK_UN)
                os.close(self._lock)
                self._lock = None

    def _end(self, first: signal.Signals) -> None:
        proc = self._proc
        if proc is None:
            return
        self._proc = None
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, first)
        try:
            proc.wait(timeout=60.0)  # the script's clean-up is slow on a loaded machine
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10.0)
        with contextlib.suppress(ProcessLookupError):  # what the clean-up left in the group
            os.killpg(proc.pid, signal.SIGKILL)
        prefix = self._as_user()
        with contextlib.suppress(OSError, subprocess.TimeoutExpired):
            subprocess.run(
                [*prefix, "halrun", "-U"], cwd=self.folder, capture_output=True, timeout=20.0
            )


class Operator:
    """A linuxcncrsh session of its own: brings the machine up, runs programs, watches."""

    def __init__(self, sim: LinuxCncSim) -> None:
        self.sim = sim
        self.sock = socket.create_connection(("127.0.0.1", sim.port), timeout=10.0)
        self._buffer = b""
        assert self.ask("hello EMC operator 1.1").startswith("HELLO ACK")
        assert self.ask("set verbose on") == "SET VERBOSE ACK"
        assert self.ask("set echo off") == "SET ECHO ACK"
        assert self.ask("set enable EMCTOO") == "SET ENABLE ACK"

    def close(self) -> None:
        self.sock.close()

    def _line(self) -> str:
        while True:
            self._buffer = self._buffer.lstrip(b"\r\n")
            ends = [i for i in (self._buffer.find(b"\r"), self._buffer.find(b"\n")) if i >= 0]
            if ends:
                line, self._buffer = self._buffer[: min(ends)], self._buffer[min(ends) + 1 :]
                return line.decode()
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError(
                    f"linuxcncrsh closed the connection; LinuxCNC's log:\n{self.sim.log_tail()}"
                )
            self._buffer += chunk

    def ask(self, line: str) -> str:
        """Send one request; its answer (the echo, while it is on, skipped)."""
        self.sock.sendall(f"{line}\r\n".encode())
        answer = self._line()
        while answer.lower() == line.lower():
            answer = self._line()
        return answer

    def set(self, what: str) -> None:
        """One command, control taken back first (linuxcncrsh: one session commands)."""
        assert self.ask("set enable EMCTOO") == "SET ENABLE ACK"
        answer = self.ask(f"set {what}")
        assert answer.endswith(" ACK"), f"set {what}: {answer}"

    def get(self, what: str) -> list[str]:
        """The answer's words after the name, e.g. ``get("feed_override") == ["100"]``;
        asked again when linuxcncrsh answers ``GET NAK`` (now and then, on a loaded machine)."""
        for _ in range(20):
            answer = self.ask(f"get {what}")
            if not answer.upper().startswith("GET"):
                return answer.split()[1:]
            time.sleep(0.01)
        raise AssertionError(f"get {what}: {answer}")

    def position(self) -> tuple[float, float, float]:
        x, y, z = (float(v) for v in self.get("abs_act_pos")[:3])
        return x, y, z

    def machine_ready(self) -> None:
        """Out of E-stop, on, homed, tool 1 in the spindle, feed override 100 %."""
        self.set("estop off")
        self.set("machine on")
        self.set("home -1")
        deadline = time.monotonic() + 20.0
        while self.get("joint_homed")[:3] != ["YES"] * 3:
            assert time.monotonic() < deadline, "LinuxCNC did not home"
            time.sleep(0.05)
        self.set("mode mdi")
        self.set("mdi T1 M6")
        while self.get("tool") != ["1"] or self.get("program_status") != ["IDLE"]:
            assert time.monotonic() < deadline, "LinuxCNC did not load tool 1"
            time.sleep(0.05)
        self.set("feed_override 100")
        self.set("spindle_override 0 100")

    def run(self, program: Path) -> None:
        """Open ``program`` in auto mode and start it."""
        self.set("mode auto")
        self.set(f"open {program}")
        self.set("run")

    def wait_status(self, status: str, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while self.get("program_status") != [status]:
            assert time.monotonic() < deadline, f"LinuxCNC not {status} within {timeout_s} s"
            time.sleep(0.02)
