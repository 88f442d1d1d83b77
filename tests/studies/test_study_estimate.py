"""The estimated cost of a study from its first run, by hand."""

from __future__ import annotations

import pytest

from cnctwin.studies import DexelStudy, RunSpec, SideMillingCut, estimate_wall_s


def test_estimate_scales_the_first_run_by_each_runs_cost() -> None:
    study = DexelStudy((5.0, 10.0), (0.01,), (100.0, 200.0), SideMillingCut(block_length_mm=30.0))
    # rho^2 / (t_cycle vf): 25, 12.5, 100, 50; the first (10 /mm, 100 mm/min) costs 100 of 187.5.
    first = RunSpec(10.0, 0.01, 100.0)
    assert estimate_wall_s(study, first, 2.0, 1) == pytest.approx((3.75, 8.0))
    assert estimate_wall_s(study, first, 2.0, 2) == pytest.approx((1.875, 4.0))
    # More processes than runs share no further.
    assert estimate_wall_s(study, first, 2.0, 16) == pytest.approx((0.9375, 2.0))
