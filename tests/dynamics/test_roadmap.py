"""Stability roadmap on a synthetic program whose depth and immersion change between lines.

The answer is checked by hand against the lobes: each scheduled speed's critical depth,
recomputed at that speed, is at least margin x ap, and a brute-force search over a 1 rpm grid
finds no stable speed nearer to the programmed one (to within the roadmap's 10 rpm grid step).
The lobes are the zero-order approximation of the Insperger & Stépán 1-DOF tool
(../shared/data/stability/NOTES.md section 1), computed independently per segment from its
reported immersion.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.dynamics.roadmap import engagement_segments, stability_roadmap
from cnctwin.dynamics.stability import MillingProcess, ToolDynamics, ToolMode, zoa_lobes
from cnctwin.errors import ConfigError, InputError
from cnctwin.geometry import Cutter, DexelStock
from cnctwin.geometry.engagement_map import EngagementMap
from cnctwin.mechanics import CuttingCoefficients
from cnctwin.nc.interpreter import Interpreter
from cnctwin.nc.setup import NCSetup

RPM = math.pi / 30.0
TOOL = ToolDynamics.from_xy(x=[ToolMode.from_hz(922.0, 0.011, stiffness_n_m=1340049.648)])
COEFFICIENTS = CuttingCoefficients(6e8, 2e8)
GRID = np.arange(5000.0, 24000.0 + 1.0, 10.0)
# Four passes of a 10 mm two-flute end mill across a 60 x 55 mm block:
# line 6: slot 0.5 deep at S10000; line 10: slot 2 deep at S10000; line 14: 0.5 deep beside
# the first slot (ae = 7.5 mm, up-milling: 0 to 120 deg); line 19: slot 2 deep at S13500.
PROGRAM = """G21 G90 G17 G94
T1 M6
S10000 M3
G0 X-10 Y10 Z5
G0 Z-0.5
G1 X70 F1000
G0 Z5
G0 X-10 Y30
G0 Z-2.0
G1 X70 F1000
G0 Z5
G0 X-10 Y17.5
G0 Z-0.5
G1 X70 F1000
G0 Z5
S13500
G0 X-10 Y45
G0 Z-2.0
G1 X70 F1000
G0 Z5
M30
"""


@pytest.fixture(scope="module")
def engagement() -> tuple[EngagementMap, dict[int, float]]:
    from cnctwin.config.tools import ToolConfig

    tool = ToolConfig(number=1, diameter_mm=10.0, flutes=2, helix_deg=0.0, flute_length_mm=20.0)
    stock = DexelStock.box((0.0, 0.0, -10.0), (60.0, 55.0, 0.0), 5.0)
    speeds: dict[int, float] = {}

    def recording():  # the programmed speed of each line, as the CLI records it
        for segment in Interpreter(NCSetup()).run_text(PROGRAM):
            speeds[segment.line] = segment.spindle_rpm
            yield segment

    emap = EngagementMap.build(recording(), stock, {1: Cutter.from_tool_config(tool)},
                               step_mm=0.2)  # fmt: skip
    return emap, speeds


def _critical_mm(entry: float, exit_: float, rpm: np.ndarray) -> np.ndarray:
    process = MillingProcess(2, COEFFICIENTS.ktc, COEFFICIENTS.krc, entry, exit_)
    return zoa_lobes(TOOL, process, rpm * RPM).critical_depth_m * 1e3


def test_segments_carry_the_programmed_engagement(engagement) -> None:
    emap, speeds = engagement
    assert [line for line, _, _ in engagement_segments(emap)] == [6, 10, 14, 19]
    road = stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, GRID)
    ap = [s.ap_mm for s in road.segments]
    assert ap == pytest.approx([0.5, 2.0, 0.5, 2.0], abs=0.21)  # the dexel pitch, 0.2 mm
    slots = [road.segments[i] for i in (0, 1, 3)]
    for seg in slots:
        assert seg.entry_rad == pytest.approx(0.0, abs=0.05)
        assert seg.exit_rad == pytest.approx(math.pi, abs=0.05)
    side = road.segments[2]
    assert side.ae_mm == pytest.approx(7.5, abs=0.25)
    assert side.entry_rad == pytest.approx(0.0, abs=0.05)
    assert side.exit_rad == pytest.approx(math.acos(1 - 2 * 0.75), abs=0.06)  # 120 deg
    assert [s.programmed_rpm for s in road.segments] == [10000.0, 10000.0, 10000.0, 13500.0]
    assert len(road.lobes) == 2  # the three slots share one lobe diagram


@pytest.mark.parametrize("margin", [1.2, 1.5])
def test_schedule_is_the_nearest_stable_speed_by_brute_force(engagement, margin: float) -> None:
    emap, speeds = engagement
    road = stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, GRID, margin=margin)
    fine = np.arange(5000.0, 24000.0 + 0.5, 1.0)
    changed = 0
    for seg in road.segments:
        need = margin * seg.ap_mm
        critical = _critical_mm(seg.entry_rad, seg.exit_rad, fine)
        stable = critical >= need
        # The scheduled speed is stable with the margin, recomputed at that very speed.
        assert seg.has_stable_speed
        assert _critical_mm(seg.entry_rad, seg.exit_rad, np.array([seg.scheduled_rpm]))[0] >= need
        at_programmed = _critical_mm(seg.entry_rad, seg.exit_rad, np.array([seg.programmed_rpm]))
        assert seg.programmed_critical_depth_mm == pytest.approx(at_programmed[0], rel=1e-9)
        if at_programmed[0] >= need:
            assert seg.scheduled_rpm == seg.programmed_rpm
            continue
        changed += 1
        # No speed of the 1 rpm grid nearer to the programmed one is stable, but for the
        # roadmap grid's step.
        nearest = float(np.min(np.abs(fine[stable] - seg.programmed_rpm)))
        distance = abs(seg.scheduled_rpm - seg.programmed_rpm)
        assert nearest <= distance <= nearest + 10.0
        # The stable ranges hold the scheduled speed and no unstable grid speed.
        assert any(lo <= seg.scheduled_rpm <= hi for lo, hi in seg.stable_ranges_rpm)
        for lo, hi in seg.stable_ranges_rpm:
            inside = (GRID >= lo) & (GRID <= hi)
            assert np.all(_critical_mm(seg.entry_rad, seg.exit_rad, GRID[inside]) >= need)
    # S10000 chatters at these depths (a_lim 0.31 mm slot, 0.20 mm side); S13500 at 2 mm
    # keeps (a_lim 3.42 mm), with either margin.
    assert changed == 3
    assert road.segments[3].programmed_stable
    assert road.segments[3].programmed_critical_depth_mm == pytest.approx(3.42, abs=0.01)


def test_no_stable_speed_within_the_limits_is_reported(engagement) -> None:
    emap, speeds = engagement
    narrow = np.arange(10000.0, 12000.0 + 1.0, 10.0)  # a_lim < 1 mm throughout
    road = stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, narrow)
    lines = [s.line for s in road.unstable_segments]
    assert lines == [10, 19]
    for seg in road.unstable_segments:
        assert math.isnan(seg.scheduled_rpm) and seg.stable_ranges_rpm == ()
    # S13500 lies outside the narrow limits: not kept even though stable there.
    assert not road.segments[0].programmed_stable


def test_sdm_agrees_with_zoa_on_the_slots(engagement) -> None:
    # Slotting: ZOA and SDM give nearly the same Hopf lobes (NOTES.md section 1; with two
    # teeth the directional matrix is not constant and they differ by up to 7 % at the lobe
    # bottoms), so the schedules of the 0.5 mm slot and of the 2 mm slot at S13500 (kept) agree.
    emap, speeds = engagement
    grid = np.arange(9000.0, 14000.0 + 1.0, 50.0)
    zoa = stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, grid)
    sdm = stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, grid, method="sdm",
                            max_depth_mm=5.0, steps=40)  # fmt: skip
    for i in (0, 3):
        assert sdm.segments[i].scheduled_rpm == zoa.segments[i].scheduled_rpm
        assert sdm.segments[i].programmed_critical_depth_mm == pytest.approx(
            zoa.segments[i].programmed_critical_depth_mm, rel=0.08
        )


def test_bad_arguments_are_input_errors(engagement) -> None:
    emap, speeds = engagement
    with pytest.raises(InputError, match="margin=0.9"):
        stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, GRID, margin=0.9)
    with pytest.raises(InputError, match="increasing"):
        stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, GRID[::-1])
    with pytest.raises(ConfigError, match="tool T1"):
        stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {2: 2}, GRID)
    with pytest.raises(ConfigError, match="line 6 cuts"):
        stability_roadmap(emap, {}, TOOL, COEFFICIENTS, {1: 2}, GRID)


def test_coarse_to_fine_sdm_schedules_a_computed_stable_speed_near_the_exact_one(
    engagement,
) -> None:
    # The SDM at 20 of the 501 grid speeds, the ZOA's shape between them, and each
    # interpolated candidate computed before it is scheduled: the scheduled speed must be
    # stable by the semi-discretization at that speed, and no farther from the programmed
    # one than the exact schedule (every grid speed computed) plus the coarse spacing.
    from cnctwin.dynamics.stability import sdm_lobes

    emap, speeds = engagement
    grid = np.arange(9000.0, 14000.0 + 1.0, 10.0)
    kwargs = {"method": "sdm", "max_depth_mm": 5.0}
    coarse = stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, grid, **kwargs)
    exact = stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, grid[::5],
                              sdm_points=None, **kwargs)  # fmt: skip
    assert coarse.lobes[0].exact is not None and coarse.lobes[0].exact.sum() == 20
    spacing = (grid[-1] - grid[0]) / 19
    for fast, full in zip(coarse.segments, exact.segments, strict=True):
        assert fast.has_stable_speed == full.has_stable_speed
        if not fast.has_stable_speed:
            continue
        process = MillingProcess(2, COEFFICIENTS.ktc, COEFFICIENTS.krc, fast.entry_rad,
                                 fast.exit_rad)  # fmt: skip
        at = sdm_lobes(TOOL, process, [fast.scheduled_rpm * RPM], max_depth_m=5e-3)
        assert at.critical_depth_m[0] * 1e3 >= 1.2 * fast.ap_mm
        assert fast.scheduled_critical_depth_mm == pytest.approx(at.critical_depth_m[0] * 1e3)
        near = abs(full.scheduled_rpm - full.programmed_rpm)
        assert abs(fast.scheduled_rpm - fast.programmed_rpm) <= near + spacing


def test_tools_without_modes_keep_their_programmed_speed(engagement) -> None:
    emap, speeds = engagement
    none = stability_roadmap(emap, speeds, {}, {}, {1: 2}, GRID)
    assert len(none.unmodelled_segments) == 4 and none.lobes == ()
    for seg in none.segments:
        assert seg.scheduled_rpm == seg.programmed_rpm and seg.lobes == -1
        assert not seg.has_modes and math.isnan(seg.programmed_critical_depth_mm)
    per_tool = stability_roadmap(emap, speeds, {1: TOOL}, {1: COEFFICIENTS}, {1: 2}, GRID)
    shared = stability_roadmap(emap, speeds, TOOL, COEFFICIENTS, {1: 2}, GRID)
    assert [s.scheduled_rpm for s in per_tool.segments] == [
        s.scheduled_rpm for s in shared.segments
    ]
    with pytest.raises(ConfigError, match="T1 has modes but no cutting coefficients"):
        stability_roadmap(emap, speeds, {1: TOOL}, {}, {1: 2}, GRID)
