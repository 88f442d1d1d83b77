"""The wear library refuses non-finite and out-of-range arguments with an InputError naming
them (the library is called from Python, not only through the CLI's checks)."""

from __future__ import annotations

import math

import pytest

from cnctwin.errors import InputError
from cnctwin.wear import round_to_resolution, synthetic_session
from cnctwin.wear.ekf import CHRISTIAND2024
from cnctwin.wear.stages import StageMonitor, remaining_life


@pytest.mark.parametrize("vb0", [math.nan, math.inf, -1.0, 0.0, 1e308])
def test_filter_refuses_an_initial_wear_outside_its_range(vb0: float) -> None:
    with pytest.raises(InputError, match="vb0_mm"):
        CHRISTIAND2024.filter(vb0_mm=vb0)


@pytest.mark.parametrize("dmr", [math.nan, math.inf, -1.0])
def test_step_refuses_a_removed_volume_that_is_not_finite_and_non_negative(dmr: float) -> None:
    ekf = CHRISTIAND2024.filter(vb0_mm=0.03)
    with pytest.raises(InputError, match="dmr_mm3"):
        ekf.step(dmr, 0.004)
    assert ekf.vb_mm == 0.03  # the state is untouched


@pytest.mark.parametrize("base", [math.nan, math.inf, -math.inf])
def test_step_refuses_a_base_torque_that_is_not_finite(base: float) -> None:
    ekf = CHRISTIAND2024.filter(vb0_mm=0.03)
    with pytest.raises(InputError, match="torque_base_nm"):
        ekf.step(0.0004, 0.004, base)


def test_a_missed_torque_sample_is_still_a_nan() -> None:
    ekf = CHRISTIAND2024.filter(vb0_mm=0.03)
    assert math.isfinite(ekf.step(0.0004, math.nan).vb_mm)


@pytest.mark.parametrize(
    "bounds", [(0.05, 0.2, math.inf), (math.nan, 0.2, 0.55), (0.2, 0.05, 0.55), (0.0, 0.1, 0.2)]
)
def test_stage_monitor_refuses_bad_boundaries(bounds: tuple[float, float, float]) -> None:
    with pytest.raises(InputError, match="boundaries_mm"):
        StageMonitor(bounds)


@pytest.mark.parametrize(
    ("bounds", "expected"),
    [((0.05, "x", 0.5), None), ((0.05, 0.2, 0.55), ("a", 1.0, 2.0)), ((0.05, 0.2, 0.55), (1.0,))],
)
def test_stage_monitor_refuses_values_that_are_not_three_numbers(
    bounds: tuple[object, ...], expected: tuple[object, ...] | None
) -> None:
    with pytest.raises(InputError, match="boundaries_mm|expected_entry_s"):
        StageMonitor(bounds, expected)  # type: ignore[arg-type]  # bad on purpose


@pytest.mark.parametrize(
    ("argument", "value"),
    [("seed", -1), ("seed", 1.5), ("slots", 0), ("rate_hz", math.nan), ("rate_hz", 0.0),
     ("noise_nm", -1.0), ("noise_nm", math.inf), ("vb0_mm", math.nan), ("slots", 10**12)],
)  # fmt: skip
def test_synthetic_session_refuses_bad_arguments(argument: str, value: float) -> None:
    kwargs: dict[str, float] = {"seed": 1, argument: value}
    with pytest.raises(InputError, match=argument if argument != "slots" else "slots"):
        synthetic_session(CHRISTIAND2024, **kwargs)  # type: ignore[arg-type]  # bad on purpose


def test_a_synthetic_session_of_valid_arguments_is_made() -> None:
    series = synthetic_session(CHRISTIAND2024, seed=1, slots=2, rate_hz=20.0)
    assert series.time_s.size == 2 * round(14.0 / 4.0 * 20.0)


@pytest.mark.parametrize(
    ("argument", "value"),
    [("limit_mm", 0.0), ("vb_mm", math.nan), ("var_mm2", math.inf), ("sigmas", -1.0)],
)
def test_remaining_life_refuses_bad_arguments(argument: str, value: float) -> None:
    kwargs = {"vb_mm": 0.1, "var_mm2": 1e-4, "limit_mm": 0.3, "sigmas": 2.0, argument: value}
    with pytest.raises(InputError, match=argument):
        remaining_life(CHRISTIAND2024.propagation, **kwargs)


def test_round_to_resolution_refuses_a_value_that_is_not_finite() -> None:
    with pytest.raises(InputError, match="value inf"):
        round_to_resolution(math.inf, 5e-6)
