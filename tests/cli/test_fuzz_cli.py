"""Property tests of the commands on hostile input: exit 0 with strict JSON, or 2 with one line.

The command-line side of tests/config/test_fuzz_config.py and tests/nc/test_fuzz_bounds.py:
machining configurations with extreme values (:mod:`hostile_inputs`) through ``cnctwin
simulate --json`` and ``cnctwin signals --json`` on a tiny program, within the work limit (50 MB,
``CNCTWIN_MEMORY_LIMIT_GB``, checked against the peak of traced allocations); hostile NC
programs through ``cnctwin nc inspect --json`` (in process). Never exit 1.
"""

from __future__ import annotations

import json
import math
import tracemalloc
from pathlib import Path
from typing import Any

import pytest
from hostile_inputs import BASE, CONFIG_PROGRAM, FUZZ, MUTATIONS, PROGRAMS, WORK_CAP, mutated, toml
from hypothesis import example, given, settings
from hypothesis import strategies as st

from cnctwin.cli.app import run
from cnctwin.memory import MEMORY_LIMIT_ENV

LIMIT_GB = 0.05
#: Allowance over the limit for what the limit does not count: the program's chunk of
#: samples, the interpreter, numba's dispatch, the JSON output (measured well below this).
SLACK_BYTES = 30e6


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("fuzz")
    program = folder / "p.ngc"
    program.write_text(CONFIG_PROGRAM)
    return folder / "c.toml", program


@pytest.fixture(scope="module")
def warm(files: tuple[Path, Path]) -> None:
    """Run both commands once on the valid configuration: compile or load the kernels (their
    memory is not the examples')."""
    config, program = files
    config.write_text(toml(BASE))
    assert run(["simulate", str(program), "--config", str(config), "--json"]) == 0
    assert run(["signals", str(program), "--config", str(config), "--json"]) == 0


@settings(FUZZ, max_examples=24)
@given(mutations=MUTATIONS, command=st.sampled_from(["simulate", "signals"]))
# The defects found by hand: a huge stock, a fine grid on a large one, flutes 1e308 mm long
# (a segfault), a tiny cycle time, a billion flutes.
@example(mutations=[(("stock", "max_mm"), [1e5, 1e5, 1e5])], command="simulate")
# 1000 x 1000 x 25 mm at 2 /mm: 4.2e6 rays, about 120 MB
@example(mutations=[(("stock", "max_mm"), [1000.0, 1000.0, 20.0])], command="signals")
@example(mutations=[(("tools", 0, "flute_length_mm"), 1e308)], command="simulate")
@example(mutations=[(("simulation", "cycle_ms"), 1e-4)], command="signals")
@example(mutations=[(("tools", 0, "flutes"), 1e9)], command="signals")
def test_commands_exit_0_or_2_within_the_work_limit(
    files: tuple[Path, Path],
    warm: None,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    mutations: list[tuple[tuple[Any, ...], Any]],
    command: str,
) -> None:
    config, program = files
    config.write_text(toml(mutated(mutations)))
    monkeypatch.setenv(MEMORY_LIMIT_ENV, str(LIMIT_GB))
    capsys.readouterr()
    tracemalloc.start()
    try:
        code = run([command, str(program), "--config", str(config), "--json"])
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    out, err = capsys.readouterr()
    assert code in (0, 2), err
    if code == 0:
        json.loads(out, parse_constant=lambda name: pytest.fail(f"{name} in the JSON"))
    else:
        assert len(err.strip().splitlines()) == 1, err
    assert peak <= LIMIT_GB * 1e9 + SLACK_BYTES


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz_cli")


_TOTALS = (
    "motion_blocks",
    "feed_length_mm",
    "rapid_length_mm",
    "machining_time_s",
    "rapid_time_s",
    "dwell_time_s",
    "total_time_s",
)


def _all_finite(report: dict) -> bool:
    """Every total is a finite number (not null) and the bounds are null or finite."""
    numbers = [report[key] for key in _TOTALS]
    for corner in report["bounds_mm"].values():
        if corner is not None:
            numbers.extend(corner)
    return all(isinstance(v, int | float) and math.isfinite(v) for v in numbers)


def _refuse(constant: str) -> object:
    raise AssertionError(f"{constant} in JSON output")


@settings(FUZZ, max_examples=100)
@given(PROGRAMS.map(lambda t: t.encode("utf-8", "surrogatepass")))
def test_nc_inspect_json_is_strict_json_or_one_line_exit_2(
    folder: Path, capsys: pytest.CaptureFixture[str], data: bytes
) -> None:
    program = folder / "fuzz.ngc"
    program.write_bytes(data)
    cap = str(WORK_CAP)
    code = run(
        ["nc", "inspect", str(program), "--json", "--max-segments", cap]
        + ["--max-repeated-lines", cap]
    )
    out, err = capsys.readouterr()
    assert code in (0, 2), err
    if code == 0:
        report = json.loads(out, parse_constant=_refuse)
        assert _all_finite(report), report
    else:
        assert out == "" and err.count("\n") == 1 and "Traceback" not in err
