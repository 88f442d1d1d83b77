"""The ``cnctwin`` commands of the guides: found in their pages, and run as a user runs them.

A page's commands are those of its fenced shell blocks (``sh``, ``bash``, ``console``): lines
joined at a trailing backslash, split at ``&&``, ``;``, ``|`` and ``&``, comments dropped,
``$NAME`` expanded from a ``NAME=value`` line before it, ``NAME=value`` before a command
dropped. ``> FILE`` after a command is where its output goes, a trailing ``&`` runs it in the
background, and ``printf ... |`` or ``echo ... |`` before it is its input.

:func:`run_page` runs the commands of one page in page order, in a working directory laid out
like the repository (``examples/`` and ``src/cnctwin/examples/`` copied, ``../shared`` linked
where the shared data is present), with the installed ``cnctwin`` entry point and a home, data
and log folder of its own, so nothing is written to the repository or the user's historian.
"""

from __future__ import annotations

import fcntl
import json
import os
import re
import shlex
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SHARED = REPO.parent / "shared"
PAGES = sorted([REPO / "README.md", *(REPO / "docs").glob("*.md"), REPO / "examples/README.md"])
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
SHELLS = {"sh", "bash", "console", "shell"}
PROGRAM = re.compile(r"^(?:\S*/)?cnctwin$")
ASSIGNMENT = re.compile(r"^([A-Z_][A-Z0-9_]*)=(\S+)$")
SEPARATOR = re.compile(r"(&&|;|\||&)")
#: Suffixes of the files commands read.
READS = re.compile(r"\.(toml|ngc|nc|mpf|tap|csv|json|txt|camotics|pem|der)$")
#: Options whose value is a file or folder the command writes.
WRITES = {"--out", "--plot", "--report", "--db", "--modes-out", "--signals", "--export"}
#: Commands with an argument that is a file they write: its index in the words.
WRITES_AT = {("runs", "export"): 4}
#: Programs whose lines on a page prepare the files a later ``cnctwin`` command reads (``cat
#: x.toml y.toml > tool.toml``): those lines run too, with ``bash``, in the working directory.
PREPARE = {"cat", "echo", "tail", "head", "{", "mkdir", "cp"}
#: The parts of the repository the pages' commands read, copied into the working directory.
SHIPPED = ("examples", "src/cnctwin/examples")


@dataclass(frozen=True)
class Command:
    page: str
    argv: tuple[str, ...]
    #: Files written by the commands before this one on its page.
    written: frozenset[str]
    #: ``> FILE``: the file its standard output goes to.
    stdout_to: str | None = None
    #: A trailing ``&``: it runs in the background while the page goes on.
    background: bool = False
    #: The words of a ``printf``/``echo`` piped into it.
    stdin_from: tuple[str, ...] = ()

    def __str__(self) -> str:
        return f"{self.page}: cnctwin {shlex.join(self.argv)}"

    @property
    def line(self) -> str:
        """The command as the tables below name it: ``cnctwin`` and its words."""
        return f"cnctwin {shlex.join(self.argv)}"


@dataclass(frozen=True)
class Shell:
    """A line of a page that prepares files with ordinary shell tools (:data:`PREPARE`)."""

    page: str
    line: str
    #: The ``NAME=value`` lines before it.
    variables: tuple[tuple[str, str], ...]


def outputs(words: list[str]) -> set[str]:
    """The files and folders a command line (``cnctwin`` first) writes."""
    out = {words[i + 1] for i, w in enumerate(words[:-1]) if w in WRITES or w == ">"}
    at = WRITES_AT.get((words[1], words[2]) if len(words) > 2 else ("", ""))
    if at is not None and len(words) > at:
        out.add(words[at])
    return out


def commands(text: str, page: str) -> list[Command]:
    """The ``cnctwin`` commands of the shell blocks of a page, in order."""
    return [step for step in steps(text, page) if isinstance(step, Command)]


def steps(text: str, page: str) -> list[Command | Shell]:
    """The ``cnctwin`` commands and the preparing lines of a page, in order."""
    found: list[Command | Shell] = []
    written: set[str] = set()
    variables: dict[str, str] = {}
    for lang, body in FENCE.findall(text):
        if lang not in SHELLS:
            continue
        for line in body.replace("\\\n", " ").splitlines():
            line = line.strip().removeprefix("$ ")
            first = shlex.split(line, comments=True)[:1]
            if first and first[0] in PREPARE and " cnctwin " not in f" {line} ":
                found.append(Shell(page, line, tuple(variables.items())))
            pieces = SEPARATOR.split(line)
            parts, separators = pieces[0::2], [*pieces[1::2], ""]
            previous: list[str] = []
            for part, after in zip(parts, separators, strict=True):
                words = shlex.split(part, comments=True)
                if len(words) == 1 and (assigned := ASSIGNMENT.match(words[0])):
                    variables[assigned[1]] = assigned[2]
                    previous = words
                    continue
                words = [re.sub(r"\$(\w+)", lambda m: variables.get(m[1], m[0]), w) for w in words]
                while len(words) > 1 and ASSIGNMENT.match(words[0]):
                    words.pop(0)  # an environment variable for this command only
                if words and PROGRAM.match(words[0]):
                    redirected = ">" in words
                    argv = words[1 : words.index(">")] if redirected else words[1:]
                    piped = previous and previous[0] in ("printf", "echo")
                    found.append(
                        Command(
                            page,
                            tuple(argv),
                            frozenset(written),
                            stdout_to=words[words.index(">") + 1] if redirected else None,
                            background=after == "&",
                            stdin_from=tuple(previous) if piped else (),
                        )
                    )
                written |= outputs(words)
                previous = words
    return found


def page_steps(page: Path) -> list[Command | Shell]:
    return steps(page.read_text("utf-8"), str(page.relative_to(REPO)))


# --- running -------------------------------------------------------------------------------


@dataclass(frozen=True)
class Special:
    """How a command that cannot simply run to its end here is checked, and why."""

    #: ``server``: started, checked that it listens on 127.0.0.1:``port``, then ended with
    #: Ctrl-C (SIGINT): at once, or with ``keep`` at the end of the page (it serves the page's
    #: later commands); it must end with exit 0 or 130 and no traceback on stderr.
    #: ``unreachable``: a machine or database that is not here (a documented remote address):
    #: it must fail with one line on stderr and exit 2, no traceback. ``long``: minutes; not
    #: run here: ``quick``, a command of the same page, runs the same code quick.
    #: ``elsewhere`` (the whole page, command ``""``): run by the test named in ``reason``.
    kind: str
    reason: str
    port: int = 0
    #: A server: what it prints once it serves (besides listening on ``port``).
    ready: str = ""
    keep: bool = True
    quick: str = ""
    #: Unreachable: what its one-line error must name.
    expect: str = ""


def workspace(root: Path) -> tuple[Path, dict[str, str]]:
    """A working directory laid out like the repository under ``root``, and its environment."""
    work = root / "work"
    for shipped in SHIPPED:
        shutil.copytree(REPO / shipped, work / shipped, ignore=shutil.ignore_patterns("__py*"))
    if (SHARED / "data").is_dir():
        (root / "shared").symlink_to(SHARED.resolve(), target_is_directory=True)
    home = root / "home"
    env = {
        **os.environ,
        "HOME": str(home),
        "XDG_DATA_HOME": str(home / "data"),
        "XDG_STATE_HOME": str(home / "state"),
        "XDG_CACHE_HOME": str(home / "cache"),
        "XDG_CONFIG_HOME": str(home / "config"),
        "PYTHONDONTWRITEBYTECODE": "1",
        "MPLBACKEND": "Agg",
        "COLUMNS": "100",
    }
    return work, env


def program() -> list[str]:
    """The installed ``cnctwin`` entry point of this interpreter, else ``python -m cnctwin``."""
    entry = Path(sys.executable).with_name("cnctwin")
    return [str(entry)] if entry.exists() else [sys.executable, "-m", "cnctwin"]


def listening(port: int) -> bool:
    with socket.socket() as probe:
        probe.settimeout(0.5)
        return probe.connect_ex(("127.0.0.1", port)) == 0


def _traceback(err: str) -> bool:
    return "Traceback (most recent call last)" in err


@dataclass
class Outcome:
    command: Command
    seconds: float
    problem: str = ""


class Process:
    """One command running, its standard output and error going to files (a server that
    writes a lot never blocks on a full pipe)."""

    def __init__(self, argv: list[str], command: Command, work: Path, env: dict[str, str]):
        self.command = command
        logs = work.parent / "logs"
        logs.mkdir(exist_ok=True)
        n = len(list(logs.iterdir()))
        self.out_path = work / command.stdout_to if command.stdout_to else logs / f"{n}.out"
        self.err_path = logs / f"{n}.err"
        stdin = None
        if command.stdin_from:
            made = subprocess.run(list(command.stdin_from), capture_output=True, text=True)
            stdin = made.stdout
        with open(self.out_path, "w") as out, open(self.err_path, "w") as err:
            self.proc = subprocess.Popen(
                argv,
                cwd=work,
                env=env,
                text=True,
                stdin=subprocess.DEVNULL if stdin is None else subprocess.PIPE,
                stdout=out,
                stderr=err,
                start_new_session=True,
            )
        if stdin is not None:
            assert self.proc.stdin is not None
            self.proc.stdin.write(stdin)
            self.proc.stdin.close()

    def output(self) -> tuple[str, str]:
        return self.out_path.read_text(errors="replace"), self.err_path.read_text(errors="replace")

    def finish(self, timeout_s: float) -> tuple[int, str, str]:
        """Wait for the end (killed after ``timeout_s``): exit code, stdout, stderr."""
        try:
            code = self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
            out, err = self.output()
            return -9, out, err + f"\n(killed after {timeout_s:g} s)"
        return (code, *self.output())

    def wait_ready(self, how: Special, timeout_s: float) -> bool:
        """Wait until the server listens on its port and has printed ``how.ready``."""
        deadline = time.monotonic() + timeout_s
        while self.proc.poll() is None and time.monotonic() < deadline:
            if listening(how.port) and how.ready in "".join(self.output()):
                return True
            time.sleep(0.2)
        return False

    def interrupt(self, timeout_s: float) -> str:
        """Ctrl-C to a server: what is wrong with how it ends ('' if nothing)."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
        code, _, err = self.finish(timeout_s)
        if code not in (0, 130, -signal.SIGINT) or _traceback(err):
            return f"after Ctrl-C: exit {code}:\n{_tail(err)}"
        return ""


def _tail(err: str, lines: int = 12) -> str:
    return "\n".join(err.strip().splitlines()[-lines:])


def _check(command: Command, code: int, out: str, err: str) -> str:
    """What is wrong with a command's run that should have succeeded ('' if nothing)."""
    if code != 0:
        return f"exit {code}:\n{_tail(err)}"
    if _traceback(err):
        return f"a traceback on stderr:\n{_tail(err, 30)}"
    if "--json" in command.argv:
        try:
            json.loads(out)
        except ValueError as error:
            return f"--json printed no valid JSON ({error}): {out[:200]!r}"
    return ""


def _unreachable(how: Special, code: int, err: str) -> str:
    """What is wrong with a command that must fail on an address that is not here."""
    last = err.strip().splitlines()[-1:] or [""]
    if code != 2 or _traceback(err) or how.expect not in last[0]:
        return f"not one line naming {how.expect!r} and exit 2: exit {code}:\n{_tail(err)}"
    return ""


def run_page(
    page: str,
    special: dict[tuple[str, str], Special],
    root: Path,
    timeout_s: float,
) -> list[Outcome]:
    """Run the steps of ``page`` in order; one outcome per ``cnctwin`` command."""
    if page_how := special.get((page, "")):
        assert page_how.kind == "elsewhere", page_how
        return []
    work, env = workspace(root)
    background: list[tuple[Outcome, Process, Special | None]] = []
    outcomes: list[Outcome] = []
    try:
        for step in page_steps(REPO / page):
            if isinstance(step, Shell):
                done = subprocess.run(
                    ["bash", "-c", step.line],
                    cwd=work,
                    env={**env, **dict(step.variables)},
                    capture_output=True,
                    text=True,
                    timeout=timeout_s,
                )
                assert done.returncode == 0, f"{page}: `{step.line}` failed: {done.stderr}"
                continue
            how = special.get((page, step.line))
            outcome = Outcome(step, 0.0)
            outcomes.append(outcome)
            if how is not None and how.kind == "long":
                continue
            start = time.perf_counter()
            process = Process([*program(), *step.argv], step, work, env)
            if how is not None and how.kind == "server":
                if not process.wait_ready(how, timeout_s):
                    code, _, err = process.finish(1.0)
                    outcome.problem = (
                        f"not ready (127.0.0.1:{how.port}, {how.ready!r}), exit {code}:\n"
                        f"{_tail(err)}"
                    )
                elif how.keep:
                    background.append((outcome, process, how))
                else:
                    outcome.problem = process.interrupt(timeout_s)
            elif step.background:
                background.append((outcome, process, None))
            else:
                code, out, err = process.finish(timeout_s)
                if how is not None and how.kind == "unreachable":
                    outcome.problem = _unreachable(how, code, err)
                else:
                    outcome.problem = _check(step, code, out, err)
            outcome.seconds = time.perf_counter() - start
    finally:
        for outcome, process, server in background:
            if server is not None:
                outcome.problem = process.interrupt(timeout_s)
            else:
                outcome.problem = _check(outcome.command, *process.finish(timeout_s))
        if (root / "shared").is_symlink():
            (root / "shared").unlink()
    return outcomes


# --- a network of its own --------------------------------------------------------------------


def loopback_up() -> None:
    """Bring up ``lo`` in a fresh network namespace (SIOCGIFFLAGS/SIOCSIFFLAGS, IFF_UP)."""
    get_flags, set_flags, up = 0x8913, 0x8914, 0x1
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        request = struct.pack("16sh", b"lo", 0)
        flags = struct.unpack("16sh", fcntl.ioctl(s, get_flags, request))[1]
        fcntl.ioctl(s, set_flags, struct.pack("16sh", b"lo", flags | up))


def isolation() -> list[str]:
    """The prefix that runs a program in a network namespace of its own (``unshare -rn``: its
    own loopback, so the fixed ports of the pages' servers meet nothing else on the machine),
    or ``[]`` where the system does not allow it."""
    unshare = shutil.which("unshare")
    if unshare is None:
        return []
    probe = [unshare, "-rn", sys.executable, __file__, "--loopback"]
    try:
        done = subprocess.run(probe, capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return []
    return [unshare, "-rn"] if done.returncode == 0 else []


@dataclass
class Result:
    """An outcome as it crosses from an isolated run: the command as text."""

    command: str
    seconds: float
    problem: str


def run_page_isolated(
    page: str,
    special: dict[tuple[str, str], Special],
    prefix: list[str],
    root: Path,
    timeout_s: float,
) -> list[Result]:
    """:func:`run_page` in a network namespace of its own (``prefix``, from :func:`isolation`)."""
    table, report = root / "special.json", root / "outcomes.json"
    table.write_text(
        json.dumps([[page, line, asdict(how)] for (page, line), how in special.items()])
    )
    argv = [
        *prefix,
        sys.executable,
        __file__,
        page,
        str(root),
        str(timeout_s),
        str(table),
        str(report),
    ]
    done = subprocess.run(argv, capture_output=True, text=True, timeout=30 * timeout_s)
    assert done.returncode == 0, f"{page}: the isolated run failed:\n{done.stderr[-3000:]}"
    return [Result(**r) for r in json.loads(report.read_text())]


def _main(argv: list[str]) -> None:
    loopback_up()
    if argv == ["--loopback"]:
        assert not listening(4840)
        return
    page, root, timeout_s, table, report = argv
    special = {(p, line): Special(**how) for p, line, how in json.loads(Path(table).read_text())}
    outcomes = run_page(page, special, Path(root), float(timeout_s))
    results = [Result(str(o.command), o.seconds, o.problem) for o in outcomes]
    Path(report).write_text(json.dumps([asdict(r) for r in results]))


if __name__ == "__main__":
    _main(sys.argv[1:])
