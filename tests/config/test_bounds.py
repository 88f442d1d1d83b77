"""Regression tests of the bounded configuration and the work limit (issue 11).

Each defect found by hand has its test: a tool with ``flute_length_mm = 1e308`` (a segfault),
tiny cycle times, a huge stock, tiny and huge dexel densities, ``flutes = 1e9``. The work
limit (:mod:`cnctwin.memory`) is tested against hand-computed sizes. The commands'
refusals of the same values are tested in tests/cli/test_config_bounds_cli.py.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from cnctwin.config import load_config
from cnctwin.dynamics.config import StabilityConfig
from cnctwin.errors import ConfigError
from cnctwin.geometry import DexelStock
from cnctwin.memory import (
    DEFAULT_MEMORY_LIMIT_GB,
    MEMORY_LIMIT_ENV,
    check_memory,
    format_bytes,
    memory_limit_bytes,
)
from cnctwin.nc.segments import Segment
from cnctwin.simulation.cut import COLUMNS, StepTable
from cnctwin.twin.config import load_run_config

EXAMPLES = Path(__file__).resolve().parents[2] / "src" / "cnctwin" / "examples"

PROGRAM = "G21 G90 G94\nT1 M6\nS8000 M3\nG0 X-5 Y5 Z2\nG1 Z-1 F300\nG1 X25 F900\nM30\n"


def _error(tmp_path: Path, text: str, *, run_config: bool = False) -> str:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_run_config(path) if run_config else load_config(path)
    message = str(err.value)
    assert "\n" not in message
    return message.removeprefix(f"{path}: ")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 10\nflute_length_mm = 1e308\n",
            "tools[0].flute_length_mm: must be >= 0.01 and <= 2000; got 1e+308",
        ),
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 10\nflutes = 1e9\n",
            "tools[0].flutes: must be >= 1 and <= 100; got 1000000000.0",
        ),
        (
            "[[tools]]\nnumber = 1\ndiameter_mm = 1e-9\n",
            "tools[0].diameter_mm: must be >= 0.01 and <= 1000; got 1e-09",
        ),
        (
            "[simulation]\ncycle_ms = 0.0001\n",
            "simulation.cycle_ms: must be >= 0.1 and <= 1000; got 0.0001",
        ),
        (
            "[simulation]\ndensity_per_mm = 1e6\n",
            "simulation.density_per_mm: must be >= 0.1 and <= 100; got 1000000.0",
        ),
        (
            "[stock]\nmax_mm = [1e6, 1e6, 1e6]\n",
            "stock.max_mm[0]: must be >= -100000 and <= 100000; got 1000000.0",
        ),
        (
            "[machine]\ng28_home_mm = [0, -0.0, inf]\n",
            "machine.g28_home_mm[2]: must be a finite number; got inf",
        ),
        (
            "[machine.spindle.motor]\nresistance_ohm = 1e308\ninductance_h = 1\n"
            "torque_constant_nm_a = 1\nback_emf_constant_v_s_rad = 1\ninertia_kg_m2 = 1\n"
            "viscous_friction_nm_s_rad = 0\n",
            "machine.spindle.motor.resistance_ohm: must be > 0 and <= 1000; got 1e+308",
        ),
    ],
)
def test_physics_values_out_of_range_name_key_range_and_value(
    tmp_path: Path, text: str, expected: str
) -> None:
    assert _error(tmp_path, text).startswith(expected)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("[twin]\ncycle_s = 1e-9\n", "twin.cycle_s: must be >= 0.001 and <= 1; got 1e-09"),
        ("[twin]\nwatchdog_s = 1e300\n", "twin.watchdog_s: must be > 0 and <= 3600"),
        ("[twin.filters.force_x_n]\nkind = 'butterworth'\ncutoff_hz = 1e300\n", "<= 100000"),
        ("[historian]\nmax_pending = 100000000000\n", "historian.max_pending: must be >= 1"),
        ("[connection]\ntimeout_s = 1e-9\n", "connection.timeout_s: must be >= 0.001"),
        ("[virtual]\nseed = -1\n", "virtual.seed: must be >= 0"),
        (
            "[control]\nmax_commands_per_s = nan\n",
            "control.max_commands_per_s: must be a finite number; got nan",
        ),
        (
            "[[rules]]\nname = 'a'\ncondition = 'x > 1'\naction = 'feed_override'\nvalue = 1e308\n",
            "rules[0].value: must be >= -1000 and <= 1000 (%), or an expression; got 1e+308",
        ),
    ],
)
def test_twin_values_out_of_range_are_one_line_errors(
    tmp_path: Path, text: str, expected: str
) -> None:
    assert expected in _error(tmp_path, text, run_config=True)


def test_the_packaged_configurations_are_in_range() -> None:
    load_config(EXAMPLES / "demo.toml")
    load_run_config(EXAMPLES / "demo_twin.toml")


# --- the work limit ---------------------------------------------------------------------------


def test_the_limit_defaults_and_is_raised_by_the_environment(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv(MEMORY_LIMIT_ENV, raising=False)
    assert memory_limit_bytes() == DEFAULT_MEMORY_LIMIT_GB * 1e9
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "32")
    assert memory_limit_bytes() == 32e9
    check_memory("thirty GB", 30e9, lambda _: "unused")


@pytest.mark.parametrize("text", ["0", "-1", "nan", "inf", "lots", "1e7"])
def test_a_bad_limit_is_a_config_error(monkeypatch: pytest.MonkeyPatch, text: str) -> None:
    monkeypatch.setenv(MEMORY_LIMIT_ENV, text)
    with pytest.raises(ConfigError, match=MEMORY_LIMIT_ENV):
        memory_limit_bytes()


def test_the_refusal_says_what_fits(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "2")
    with pytest.raises(ConfigError) as err:
        check_memory("eight GB", 8e9, lambda fraction: f"ask for {fraction:g} of it")
    assert str(err.value) == (
        f"eight GB (~8 GB) exceeds the memory limit of 2 GB ({MEMORY_LIMIT_ENV}): "
        "ask for 0.25 of it"
    )
    assert format_bytes(2.5e14) == "250 TB" and format_bytes(1500) == "1.5 kB"


def test_a_huge_stock_is_refused_before_it_is_allocated() -> None:
    # 1e6 mm cube at 10 /mm: 3 families of (1e7)^2 rays = 3e14 rays.
    with pytest.raises(ConfigError) as err:
        DexelStock.box((0.0, 0.0, 0.0), (1e6, 1e6, 1e6), 10.0)
    message = str(err.value)
    assert "is 3e+14 rays" in message and "use a density <=" in message


def test_the_stock_estimate_matches_what_is_allocated(monkeypatch: pytest.MonkeyPatch) -> None:
    # 100 x 100 x 20 mm at 5 /mm: 500 x 500 + 2 x 500 x 100 = 350,000 rays.
    size = DexelStock.estimate_nbytes((0, 0, -20), (100, 100, 0), 5.0)
    assert DexelStock.box((0, 0, -20), (100, 100, 0), 5.0).nbytes == size
    # A limit just below it refuses the stock, and names the density that would fit.
    monkeypatch.setenv(MEMORY_LIMIT_ENV, str(0.99 * size / 1e9))
    with pytest.raises(ConfigError, match=r"is 3\.5e\+05 rays .*use a density <= 4\.97 /mm"):
        DexelStock.box((0, 0, -20), (100, 100, 0), 5.0)


def test_the_heap_growth_is_checked(monkeypatch: pytest.MonkeyPatch) -> None:
    stock = DexelStock.box((0, 0, -20), (100, 100, 0), 5.0)
    monkeypatch.setenv(MEMORY_LIMIT_ENV, str(1.01 * stock.nbytes / 1e9))
    with pytest.raises(ConfigError, match="growing the z rays' heap"):
        stock.grow_heap("z")


def test_the_step_table_stops_at_the_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    # 160 bytes a row: a 1.6 MB limit holds 10,000 rows.
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "0.0016")
    table = StepTable()
    block = np.zeros((5000, len(COLUMNS)))
    table.append(block)
    table.append(block)
    assert len(table) == 10_000
    with pytest.raises(ConfigError, match="more than 1e\\+04 positions.*at most 1e\\+04 positions"):
        table.append(block[:1])
    assert len(table) == 10_000


def test_a_semi_discretization_too_large_is_refused() -> None:
    config = StabilityConfig.model_validate(
        {
            "modes": [{"direction": "x", "fn_hz": 1000.0, "damping_ratio": 0.02,
                       "stiffness_n_m": 1e7}],
            "cut": {"teeth": 2, "ktc_n_mm2": 600.0, "krc_n_mm2": 200.0},
            "lobes": {"method": "sdm", "steps": 10_000},
        }
    )  # fmt: skip
    # 2 + 20,000 square, 8 (20,002 + 40,000) bytes a row: about 9.6 GB.
    with pytest.raises(ConfigError, match=r"20002 x 20002 transition matrix \(~9\.6 GB\)"):
        config.check_work(2000.0)
    auto = config.model_copy(update={"lobes": config.lobes.model_copy(update={"steps": "auto"})})
    auto.check_work(2000.0)  # 40 steps: a few kB


def _segments() -> Iterator[Segment]:
    from cnctwin.nc.interpreter import Interpreter
    from cnctwin.nc.setup import NCSetup

    return Interpreter(NCSetup()).run_text(PROGRAM.replace("T1 M6\n", ""))


def test_an_engagement_map_stops_at_the_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    from cnctwin.geometry import Cutter
    from cnctwin.geometry.engagement_map import EngagementMap

    stock = DexelStock.box((0, 0, -5), (20, 10, 0), 2.0)
    cutters = {0: Cutter.flat(diameter_mm=6.0, flute_length_mm=15.0, flutes=2)}
    # About 45 mm of path at 0.001 mm a location: 45,000 locations, 1000 B each.
    monkeypatch.setenv(MEMORY_LIMIT_ENV, "0.01")
    with pytest.raises(ConfigError, match=r"engagement map 0\.001 mm a location .*use a step"):
        EngagementMap.build(_segments(), stock, cutters, step_mm=0.001)


def test_sampling_into_one_chunk_stops_at_the_limit(monkeypatch: pytest.MonkeyPatch) -> None:
    from cnctwin.nc.sampler import sample_program

    monkeypatch.setenv(MEMORY_LIMIT_ENV, "0.001")
    with pytest.raises(ConfigError, match="iterate a TrajectorySampler"):
        sample_program(_segments(), rapid_mm_min=6000.0, cycle_s=1e-4)
    samples, duration = sample_program(_segments(), rapid_mm_min=6000.0, cycle_s=0.0125)
    assert samples.t_s.size == math.ceil(duration / 0.0125)


@pytest.mark.parametrize(
    ("tools", "bounds", "expected"),
    [
        ('{"1": {"diameter": 1e308}}', '{"min": [0, 0, 0], "max": [1, 1, 1]}', "<= 1000"),
        ('{"1": {"diameter": 6, "length": NaN}}', '{"min": [0, 0, 0], "max": [1, 1, 1]}', "finite"),
        ("{}", '{"min": [0, 0, "x"], "max": [1, 1, 1]}', "bounds.min[2]: 'x' is not a number"),
        ("{}", '{"min": 0, "max": [1, 1, 1]}', "give three numbers"),
        ("{}", '{"min": [0, 0, 0], "max": [1e6, 1, 1]}', "stock.max_mm[0]: must be >= -100000"),
    ],
)
def test_camotics_projects_are_bounded_too(
    tmp_path: Path, tools: str, bounds: str, expected: str
) -> None:
    path = tmp_path / "p.camotics"
    path.write_text(f'{{"units": "metric", "tools": {tools}, "workpiece": {{"bounds": {bounds}}}}}')
    with pytest.raises(ConfigError) as err:
        load_config(path)
    assert expected in str(err.value) and "\n" not in str(err.value)


SLOT = Path(__file__).resolve().parents[2] / "examples" / "stability" / "insperger_slot.toml"


def test_a_union_key_is_named_without_pydantic_member_names(tmp_path: Path) -> None:
    from cnctwin.dynamics.config import load_stability_config

    path = tmp_path / "s.toml"
    path.write_text(SLOT.read_text().replace("steps = 40", "steps = 100000"))
    with pytest.raises(ConfigError, match=r": lobes\.steps: must be less than or equal to 10000"):
        load_stability_config(path)
