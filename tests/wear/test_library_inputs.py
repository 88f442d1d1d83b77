"""The wear EKF and stage monitor refuse non-finite and out-of-range inputs with a
CnctwinError (the library is called from Python, not only through the CLI's checks)."""

from __future__ import annotations

import math

import pytest

from cnctwin.errors import CnctwinError
from cnctwin.wear.ekf import CHRISTIAND2024
from cnctwin.wear.stages import StageMonitor


@pytest.mark.parametrize("vb0", [math.nan, math.inf, -1.0, 0.0, 1e308])
def test_filter_refuses_an_initial_wear_outside_its_range(vb0: float) -> None:
    with pytest.raises(CnctwinError, match="vb0_mm"):
        CHRISTIAND2024.filter(vb0_mm=vb0)


@pytest.mark.parametrize("dmr", [math.nan, math.inf, -1.0])
def test_step_refuses_a_removed_volume_that_is_not_finite_and_non_negative(dmr: float) -> None:
    ekf = CHRISTIAND2024.filter(vb0_mm=0.03)
    with pytest.raises(CnctwinError, match="dmr_mm3"):
        ekf.step(dmr, 0.004)
    assert ekf.vb_mm == 0.03  # the state is untouched


@pytest.mark.parametrize("base", [math.nan, math.inf, -math.inf])
def test_step_refuses_a_base_torque_that_is_not_finite(base: float) -> None:
    ekf = CHRISTIAND2024.filter(vb0_mm=0.03)
    with pytest.raises(CnctwinError, match="torque_base_nm"):
        ekf.step(0.0004, 0.004, base)


def test_a_missed_torque_sample_is_still_a_nan() -> None:
    ekf = CHRISTIAND2024.filter(vb0_mm=0.03)
    assert math.isfinite(ekf.step(0.0004, math.nan).vb_mm)


@pytest.mark.parametrize(
    "bounds", [(0.05, 0.2, math.inf), (math.nan, 0.2, 0.55), (0.2, 0.05, 0.55), (0.0, 0.1, 0.2)]
)
def test_stage_monitor_refuses_bad_boundaries(bounds: tuple[float, float, float]) -> None:
    with pytest.raises(CnctwinError, match="boundaries_mm"):
        StageMonitor(bounds)
