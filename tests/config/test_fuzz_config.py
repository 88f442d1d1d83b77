"""Property tests of bounded configurations: extreme numbers end in a result or a ConfigError.

Configurations are a small valid one with one to three numeric keys replaced by what a
careless or hostile user would write: nan, infinities, 1e308, -0, 1e-308, integers far
beyond 64 bits, negative numbers, strings, booleans, arrays, and random floats. Each goes
through the loader and through ``cnctwin simulate --json`` and ``cnctwin signals --json``
(in process) on a tiny program; the running twin's tables (``[twin]``, ``[connection]``,
``[historian]``, ``[control]``, ``[virtual]``) go through the twin's loader.

The property: the loader returns a configuration or raises a one-line
:class:`~cnctwin.errors.ConfigError`; the commands exit 0 with valid JSON or 2 with one line,
never 1; and no example allocates more than the work limit allows: the limit is set to 50 MB
(``CNCTWIN_MEMORY_LIMIT_GB``) and the peak of traced allocations checked against it.
Derandomized for reproducible CI; the work per example is bounded by the limit, not by
wall-clock time, so the tests pass on a loaded machine.
"""

from __future__ import annotations

import copy
import json
import math
import tracemalloc
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cnctwin.cli.app import run
from cnctwin.config import load_config
from cnctwin.config.limits import MEMORY_LIMIT_ENV
from cnctwin.errors import ConfigError

FUZZ = settings(
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
LIMIT_GB = 0.05
#: Allowance over the limit for what the limit does not count: the program's chunk of
#: samples, the interpreter, numba's dispatch, the JSON output (measured well below this).
SLACK_BYTES = 30e6

BASE: dict[str, Any] = {
    "machine": {
        "rapid_mm_min": 6000.0,
        "max_spindle_rpm": 12000.0,
        "axes": {"x": {"max_velocity_mm_min": 8000.0}, "z": {"max_accel_mm_s2": 1000.0}},
        "work_offsets": {"g54": [0.0, 0.0, 0.0]},
        "spindle": {"rated_power_kw": 15.0},
    },
    "tools": [
        {
            "number": 1,
            "kind": "flat",
            "diameter_mm": 6.0,
            "flute_length_mm": 15.0,
            "flutes": 2,
            "helix_deg": 30.0,
            "length_mm": 0.0,
        }
    ],
    "stock": {"min_mm": [0.0, 0.0, -5.0], "max_mm": [20.0, 10.0, 0.0]},
    "material": {"name": "AA6060-T6", "density_kg_m3": 2700.0},
    "simulation": {"density_per_mm": 2.0, "cycle_ms": 12.5},
}

#: The keys the fuzzer replaces: table path and key.
KEYS: list[tuple[Any, ...]] = [
    ("machine", "rapid_mm_min"),
    ("machine", "max_spindle_rpm"),
    ("machine", "axes", "x", "max_velocity_mm_min"),
    ("machine", "axes", "z", "max_accel_mm_s2"),
    ("machine", "work_offsets", "g54"),
    ("machine", "spindle", "rated_power_kw"),
    ("tools", 0, "number"),
    ("tools", 0, "diameter_mm"),
    ("tools", 0, "flute_length_mm"),
    ("tools", 0, "flutes"),
    ("tools", 0, "helix_deg"),
    ("tools", 0, "length_mm"),
    ("stock", "min_mm"),
    ("stock", "max_mm"),
    ("material", "density_kg_m3"),
    ("simulation", "density_per_mm"),
    ("simulation", "cycle_ms"),
]

PROGRAM = """G21 G90 G94 G17
T1 M6
S8000 M3
G0 X-5 Y5 Z2
G1 Z-1 F300
G1 X25 F900
G0 Z5
M30
"""

_EXTREMES = [
    math.nan,
    math.inf,
    -math.inf,
    1e308,
    -1e308,
    1e-308,
    -0.0,
    0,
    -1,
    10**30,
    -(10**30),
    2**63,
    1e9,
    1e6,
    # the largest valid coordinate and density, and a long flute: valid, but their product
    # must hit the work limit
    1e5,
    -1e5,
    100.0,
    0.1,
    2000.0,
    "x",
    True,
    [1.0],
]
SCALAR = st.one_of(
    st.sampled_from(_EXTREMES),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**20), max_value=10**20),
)
VALUE = st.one_of(SCALAR, st.lists(SCALAR, min_size=3, max_size=3))
MUTATIONS = st.lists(st.tuples(st.sampled_from(KEYS), VALUE), min_size=1, max_size=3)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        # repr gives nan, inf, -inf, 1e+308, -0.0: all valid TOML floats.
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    return "[" + ", ".join(_toml_value(v) for v in value) + "]"


def _toml(data: dict[str, Any], prefix: str = "") -> str:
    """TOML text of nested tables of scalars and arrays (``tools`` as ``[[tools]]``)."""
    lines = [f"{k} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict | list)]
    lines += [f"{k} = {_toml_value(v)}" for k, v in data.items() if isinstance(v, list)
              and not (v and isinstance(v[0], dict))]  # fmt: skip
    text = "\n".join(lines) + "\n"
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            text += f"\n[{name}]\n" + _toml(value, f"{name}.")
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            for item in value:
                text += f"\n[[{name}]]\n" + _toml(item, f"{name}.")
    return text


def _mutated(mutations: list[tuple[tuple[Any, ...], Any]]) -> dict[str, Any]:
    data = copy.deepcopy(BASE)
    for path, value in mutations:
        table: Any = data
        for part in path[:-1]:
            table = table[part]
        table[path[-1]] = value
    return data


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("fuzz")
    program = folder / "p.ngc"
    program.write_text(PROGRAM)
    return folder / "c.toml", program


@pytest.fixture(scope="module")
def warm(files: tuple[Path, Path]) -> None:
    """Run both commands once on the valid configuration: compile or load the kernels (their
    memory is not the examples')."""
    config, program = files
    config.write_text(_toml(BASE))
    assert run(["simulate", str(program), "--config", str(config), "--json"]) == 0
    assert run(["signals", str(program), "--config", str(config), "--json"]) == 0


def test_the_toml_writer_round_trips() -> None:
    import tomllib

    assert tomllib.loads(_toml(BASE)) == BASE


@settings(FUZZ, max_examples=200)
@given(mutations=MUTATIONS)
def test_loader_returns_a_config_or_one_line_error(
    files: tuple[Path, Path], mutations: list[tuple[tuple[Any, ...], Any]]
) -> None:
    config, _ = files
    config.write_text(_toml(_mutated(mutations)))
    try:
        loaded = load_config(config)
    except ConfigError as err:
        assert "\n" not in str(err)
        return
    for value in (
        loaded.simulation.density_per_mm,
        loaded.simulation.cycle_ms,
        loaded.machine.rapid_mm_min,
        loaded.tools[0].diameter_mm,
        *loaded.stock.max_mm,
    ):
        assert math.isfinite(value)


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
    config.write_text(_toml(_mutated(mutations)))
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


#: Numeric keys of the running twin's tables, for the loader of twin configurations.
RUN_KEYS: list[tuple[Any, ...]] = [
    ("twin", "cycle_s"),
    ("twin", "watchdog_s"),
    ("twin", "density_per_mm"),
    ("twin", "position_deadband_mm"),
    ("twin", "force_band", "k"),
    ("twin", "force_band", "scatter_window"),
    ("twin", "form_error", "overhang_mm"),
    ("connection", "timeout_s"),
    ("connection", "unit_id"),
    ("historian", "max_pending"),
    ("historian", "flush_interval_s"),
    ("control", "max_commands_per_s"),
    ("control", "feed_override", "max_pct"),
    ("virtual", "tick_ms"),
    ("virtual", "seed"),
    ("virtual", "noise", "force_n"),
]


@settings(FUZZ, max_examples=200)
@given(mutations=st.lists(st.tuples(st.sampled_from(RUN_KEYS), VALUE), min_size=1, max_size=3))
def test_twin_loader_returns_a_config_or_one_line_error(
    files: tuple[Path, Path], mutations: list[tuple[tuple[Any, ...], Any]]
) -> None:
    from cnctwin.twin.config import load_run_config

    config, _ = files
    data: dict[str, Any] = {}
    for path, value in mutations:
        table = data
        for part in path[:-1]:
            table = table.setdefault(part, {})
        table[path[-1]] = value
    config.write_text(_toml(data))
    try:
        loaded = load_run_config(config)
    except ConfigError as err:
        assert "\n" not in str(err)
        return
    assert 0.001 <= loaded.twin.cycle_s <= 1.0
    assert 1 <= loaded.historian.max_pending <= 10_000_000
