"""Benchmark: the jobs the NC interpreter feeds, on a long program, end to end.

Three consumers of the interpreter, each a fresh process on the same generated programs
(``_common.write_program`` with a box: a random CAM-style walk kept inside the stock of the
shipped ``demo.toml``, X 5-75 Y 5-55 Z -1 to -2 mm, so that the 10 mm tool cuts the
80 x 60 x 20 mm block and no rapid meets material):

``simulate``
    ``cnctwin simulate PROGRAM -c demo.toml --json`` (tri-dexel stock at the config's 10 per mm
    and 12.5 ms cycle; outputs not written).
``signals``
    ``cnctwin signals PROGRAM -c demo.toml --json`` (the same cut, then forces and spindle).
``twin load``
    the twin's program loading: :func:`cnctwin.twin.build_twin` with the program on the
    shipped ``demo_twin.toml`` (what ``cnctwin run --program`` does before its first cycle;
    the program is read by the twin's per-line tool offset map). The child builds the twin
    once without a program first (imports, physics warm-up), then times the build with it:
    its lines/s is over that build's CPU time alone.

For each: CPU time (user + system of the child, ``os.wait4``), lines per CPU second (for the
two commands over the whole process, start-up included) and peak RSS, at two program sizes
(the large one and a tenth of it): the same peak at both means memory flat in the program's
length. CPU time, not wall time, because the benchmark machine is shared and loaded. A
command that refuses the program (exit 2: e.g. the predicted signals of 1,000,000 lines at
12.5 ms estimated over the 4 GB work limit, :mod:`cnctwin.memory`) gets its message in the
table; ``--memory-limit-gb`` raises the limit.

Usage::

    python benchmarks/bench_nc_consumers.py [--quick] [--lines N] [--only NAME ...]
        [--memory-limit-gb GB]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

from _common import cnctwin_command, run_measured, write_program

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "src" / "cnctwin" / "examples"
#: Where the generated walk stays (mm, program coordinates): demo.toml's 80 x 60 mm stock
#: less the 5 mm radius of its T1.
BOX = (5.0, 75.0, 5.0, 55.0)
CONSUMERS = ("simulate", "signals", "twin load")


def _twin_child(program: str) -> None:
    """Print the CPU seconds of ``build_twin`` with ``program`` (after one without)."""
    from cnctwin.twin import LocalConnection, build_twin, load_run_config

    class Idle:
        """A machine never read: building the twin does not touch it."""

        def snapshot(self) -> dict[str, float]:
            raise RuntimeError("not read while the twin is built")

        def command(self, name: str, value: float) -> None:
            raise RuntimeError("not commanded while the twin is built")

        def step(self, dt_s: float) -> None:
            raise RuntimeError("not stepped while the twin is built")

    config = load_run_config(EXAMPLES / "demo_twin.toml")
    build_twin(config, LocalConnection(Idle()), program=None)
    start = time.process_time()
    build_twin(config, LocalConnection(Idle()), program=program)
    print(time.process_time() - start)


def count_lines(path: Path) -> int:
    with path.open("rb") as stream:
        return sum(1 for _ in stream)


def measure(
    name: str, program: Path, work: Path, limit_gb: float | None
) -> tuple[float, float, float] | str:
    """(CPU seconds counted for lines/s, whole child's CPU seconds, peak RSS MiB), or the
    last line of the child's error where it exits with 2 (a refusal, e.g. the memory limit).
    ``limit_gb``: the children's work limit (``CNCTWIN_MEMORY_LIMIT_GB``), else the default."""
    env = dict(os.environ, PYTHONPATH=str(REPO / "src"))
    if limit_gb is not None:
        env["CNCTWIN_MEMORY_LIMIT_GB"] = f"{limit_gb:g}"
    config = str(EXAMPLES / "demo.toml")
    if name == "twin load":
        command = [sys.executable, __file__, "--twin-child", str(program)]
    else:
        command = [*cnctwin_command(), name, str(program), "-c", config, "--json"]
    answer, error = work / "answer.txt", work / "error.txt"
    seconds, peak, code = run_measured(command, work, env, stdout_to=answer, stderr_to=error)
    if code == 2:
        return error.read_text().strip().splitlines()[-1]
    if code != 0:
        raise SystemExit(f"{' '.join(command)} exited with {code}")
    counted = float(answer.read_text()) if name == "twin load" else seconds
    return counted, seconds, peak


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="50,000 and 5,000 lines")
    parser.add_argument("--lines", type=int, default=None, help="lines of the large program")
    parser.add_argument(
        "--only", nargs="+", choices=CONSUMERS, default=CONSUMERS, help="consumers to run"
    )
    parser.add_argument(
        "--memory-limit-gb",
        type=float,
        default=None,
        help="CNCTWIN_MEMORY_LIMIT_GB of the children (default: the library's, 4 GB)",
    )
    parser.add_argument("--twin-child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.twin_child:
        _twin_child(args.twin_child)
        return
    large = args.lines or (50_000 if args.quick else 1_000_000)
    sizes = (max(large // 10, 100), large)
    load = os.getloadavg()
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}, load average {load[0]:.2f} {load[1]:.2f} "
        f"{load[2]:.2f}; CPU time; memory limit "
        f"{args.memory_limit_gb or 'default'} GB"
    )
    print("| consumer | lines | lines/s | CPU s (process) | peak RSS (MiB) |")
    print("|---|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for n in sizes:
            program = work / f"generated_{n}.ngc"
            write_program(program, n, box=BOX)
            lines = count_lines(program)
            for name in args.only:
                result = measure(name, program, work, args.memory_limit_gb)
                if isinstance(result, str):
                    print(f"| {name} | {lines:,} | refused: {result} | | |", flush=True)
                    continue
                counted, seconds, peak = result
                print(
                    f"| {name} | {lines:,} | {lines / counted:,.0f} | {seconds:.1f} | {peak:.0f} |",
                    flush=True,
                )
    load = os.getloadavg()
    print(f"load average at the end: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


if __name__ == "__main__":
    main()
