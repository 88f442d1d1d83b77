"""The constrained optimum of a dexel study: the least score among the settings that meet the
volume and real-time constraints, and why each other setting was excluded."""

from __future__ import annotations

import math

import pytest

from cnctwin.errors import ConfigError
from cnctwin.studies import Constraints, RunResult, RunSpec, constrained_optimum, settings
from cnctwin.studies.report import summary_lead


def _run(rho: float, cycle: float, ae: float, cpu: float, volume: float) -> RunResult:
    return RunResult(
        spec=RunSpec(rho, cycle, 960.0),
        delta_ae_mm=ae,
        delta_ae_max_mm=ae,
        feed_deviation_pct=0.1,
        volume_deviation_pct=volume,
        runtime_s=cpu,
        cpu_s=cpu,
        process_s=10.0,
        steps=100,
        steady_steps=50,
    )


RESULTS = [
    # Fast and sharp in ae, but its long steps leave islands: 59 % of the cut stands.
    _run(5.0, 0.2, 0.001, 0.01, -58.7),
    # Accurate and real time (10 s of process in 2 s of CPU).
    _run(10.0, 0.0125, 0.01, 2.0, -0.1),
    # Accurate but slower than the machine (10 s of process in 20 s of CPU).
    _run(40.0, 0.00625, 0.002, 20.0, -0.01),
    # Accurate, real time, but a worse score than (10, 12.5 ms).
    _run(10.0, 0.00625, 0.05, 4.0, -0.02),
]


def test_constrained_optimum_meets_the_constraints_and_names_the_exclusions() -> None:
    scored = settings(RESULTS)
    choice = constrained_optimum(scored)
    best = choice.optimum
    assert best is not None
    assert (best.density_per_mm, best.cycle_s) == (10.0, 0.0125)
    assert best.volume_deviation_pct <= 1.0 and best.realtime_factor >= 1.0
    # Every setting that meets both constraints scores no better than the chosen one.
    for s in scored:
        if s.volume_deviation_pct <= 1.0 and s.realtime_factor >= 1.0:
            assert s.score >= best.score
    # The least score overall is the fast setting, excluded for its volume.
    top = choice.score_optimum
    assert (top.density_per_mm, top.cycle_s) == (5.0, 0.2) and top.score < best.score
    reasons = {(s.density_per_mm, s.cycle_s): r for s, r in choice.excluded}
    assert set(reasons) == {(5.0, 0.2), (40.0, 0.00625)}
    assert reasons[(5.0, 0.2)] == (
        "removed volume off by 58.7 % at its worst feed (material left uncut), tolerance 1 %",
    )
    # 10 s of process over 20 s of CPU: a factor of 0.5.
    assert reasons[(40.0, 0.00625)] == ("real-time factor 0.5 < 1",)


def test_looser_constraints_admit_more_and_none_may_remain() -> None:
    scored = settings(RESULTS)
    loose = constrained_optimum(scored, Constraints(60.0, 0.1))
    assert loose.optimum is loose.score_optimum and loose.excluded == ()
    strict = constrained_optimum(scored, Constraints(0.001, 1.0))
    assert strict.optimum is None and len(strict.excluded) == 4
    with pytest.raises(ConfigError, match="volume tolerance -1"):
        Constraints(-1.0)
    with pytest.raises(ConfigError, match="real-time factor 0"):
        Constraints(1.0, 0.0)
    zero_cpu = settings([_run(5.0, 0.2, 0.0, 0.0, 0.0)])[0]
    assert zero_cpu.realtime_factor == math.inf


def test_lead_opens_with_the_constrained_optimum() -> None:
    # The summary fields summary_lead reads, as study_summary writes them.
    summary = {
        "study": {"densities_per_mm": [5.0, 10.0], "cycles_s": [0.0125, 0.2]},
        "constraints": {"max_volume_deviation_pct": 1.0, "min_realtime_factor": 1.0},
        "optimum": {"density_per_mm": 10.0, "cycle_ms": 12.5, "score": 0.2},
        "score_optimum": {"density_per_mm": 5.0, "cycle_ms": 200.0, "score": 0.0},
        "excluded": [{"density_per_mm": 5.0, "cycle_ms": 200.0, "reasons": ["removed volume off"]}],
    }
    lines = summary_lead(summary)
    assert lines[0].startswith("Optimum: 10 /mm, 12.5 ms (S = 0.200): the least score among")
    assert lines[1] == (
        "The least score of all, 5 /mm, 200 ms (S = 0.000), is excluded: removed volume off."
    )
    assert lines[2] == "1 of 4 settings excluded (table below)."
    summary["optimum"] = None
    assert summary_lead(summary)[0].startswith("No setting meets the constraints (removed volume")
