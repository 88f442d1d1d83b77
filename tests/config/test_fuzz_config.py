"""Property tests of bounded configurations: extreme numbers end in a result or a ConfigError.

Configurations are a small valid one with one to three numeric keys replaced by what a
careless or hostile user would write: nan, infinities, 1e308, -0, 1e-308, integers far
beyond 64 bits, negative numbers, strings, booleans, arrays, and random floats
(tests/hostile_inputs.py). Each goes through the loader (and through ``cnctwin simulate
--json`` and ``cnctwin signals --json``: in tests/cli/test_fuzz_cli.py); the running twin's
tables (``[twin]``, ``[connection]``, ``[historian]``, ``[control]``, ``[virtual]``) go
through the twin's loader.

The property: the loader returns a configuration or raises a one-line
:class:`~cnctwin.errors.ConfigError`. Derandomized for reproducible CI.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
from hostile_inputs import BASE, CONFIG_PROGRAM, FUZZ, MUTATIONS, VALUE, mutated, toml
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.config import load_config
from cnctwin.errors import ConfigError


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("fuzz")
    program = folder / "p.ngc"
    program.write_text(CONFIG_PROGRAM)
    return folder / "c.toml", program


def test_the_toml_writer_round_trips() -> None:
    import tomllib

    assert tomllib.loads(toml(BASE)) == BASE


@settings(FUZZ, max_examples=200)
@given(mutations=MUTATIONS)
def test_loader_returns_a_config_or_one_line_error(
    files: tuple[Path, Path], mutations: list[tuple[tuple[Any, ...], Any]]
) -> None:
    config, _ = files
    config.write_text(toml(mutated(mutations)))
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


#: Numeric keys of the running twin's tables, for the loader of twin configurations.
RUN_KEYS: list[tuple[Any, ...]] = [
    ("twin", "cycle_s"),
    ("twin", "watchdog_s"),
    ("twin", "density_per_mm"),
    ("twin", "position_deadband_mm"),
    ("twin", "force_band", "k"),
    ("twin", "force_band", "scatter_window"),
    ("twin", "form_error", "overhang_mm"),
    ("twin", "wear", "vb_max_mm"),
    ("twin", "wear", "settle_samples"),
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
    config.write_text(toml(data))
    try:
        loaded = load_run_config(config)
    except ConfigError as err:
        assert "\n" not in str(err)
        return
    assert 0.001 <= loaded.twin.cycle_s <= 1.0
    assert 1 <= loaded.historian.max_pending <= 10_000_000
