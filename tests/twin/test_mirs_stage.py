"""Live elastic MIRS prediction and control (cnctwin.twin.mirs; Ward 2021, Sec. 3.3).

The stage's prediction against the model fed by hand with Ward's Eq. 1 loads, its control law
(the commanded chip load meets the band's edge on the model; the spindle/feed split), the
interval, the lost machine, the configuration's errors, and the loop on the virtual machine in
lockstep (examples/mirs/mirs.toml).
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from pydantic import ValidationError
from twin_helpers import run_lockstep

from cnctwin.errors import ConfigError
from cnctwin.mechanics import ElasticMirsModel, elastic_material, milling_material
from cnctwin.thread import RunState
from cnctwin.twin import CycleState, MirsConfig, RunConfig, load_run_config
from cnctwin.twin.mirs import MirsStage

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "mirs" / "mirs.toml"
K = milling_material("AA7075-T6").coefficients
DEPTHS = np.linspace(0.0, 200e-6, 41)
MODEL = ElasticMirsModel(elastic_material("AA7050-T7451"), 3.26e-3, DEPTHS)


def _by_hand(h_mm: float) -> float:
    """Largest |sigma_xx| (MPa) with Ward's Eq. 1 per unit width written out."""
    h = h_mm * 1e-3
    return MODEL.profile(abs(K.krc * h + K.kre), K.ktc * h + K.kte).max_abs_xx_pa / 1e6


def _meets_edge(h_mm: float, limit_mpa: float = 35.0) -> bool:
    """The chip thickness is the largest whose MIRS is at most the limit (within 0.1 %; the
    model's maximum jumps where its worst position along x moves)."""
    return _by_hand(h_mm) <= limit_mpa < _by_hand(h_mm * 1.001)


def _state(h_mm: float, feed: float = 100.0, spindle: float = 100.0, t_s: float = 1.0):  # type: ignore[no-untyped-def]
    state = CycleState(0, 0.0, t_s, connected=True, new_sample=True, line=3)
    state.measured = {
        "feed_override_pct": feed,
        "spindle_override_pct": spindle,
        "feed_mm_min": 1000.0,
        "run_state": float(RunState.RUNNING),
    }
    state.engagement = SimpleNamespace(contact=h_mm > 0.0, h_max_mm=h_mm)  # type: ignore[assignment]
    return state


def _stage(**changes: object) -> MirsStage:
    settings = {"enabled": True, "contact_length_mm": 3.26, "control": True, "max_mpa": 35.0}
    config = MirsConfig(**{**settings, **changes})  # type: ignore[arg-type]
    return MirsStage(config, K, (20.0, 100.0), (50.0, 100.0))


def test_prediction_is_the_model_at_ward_eq1_loads() -> None:
    state = _stage(control=False).process(_state(0.04))
    assert state.predicted["mirs_max_mpa"] == pytest.approx(_by_hand(0.04), rel=1e-12)
    assert state.commands == []
    idle = _stage().process(_state(0.0))
    assert idle.predicted["mirs_max_mpa"] == 0.0 and idle.commands == []


def test_above_the_band_the_commanded_chip_load_meets_its_edge() -> None:
    state = _stage(spindle_share=0.5).process(_state(0.04, feed=90.0))
    feed, spindle = state.commands
    assert (feed.rule, feed.action, spindle.action) == ("mirs", "feed_override", "spindle_override")
    s = spindle.value / 100.0
    r = (feed.value / 90.0) / s  # the chip-thickness ratio asked for
    assert s == pytest.approx(1.0 - 0.5 * (1.0 - r), rel=1e-9)
    assert _meets_edge(0.04 * r)


def test_the_mirs_grows_with_the_chip_thickness() -> None:
    # what the stage's h* relies on, over the whole range it searches
    h_mm = np.geomspace(1e-5, 10.0, 400)
    mirs = np.array([_by_hand(h) for h in h_mm])
    assert np.all(np.diff(mirs) > 0.0)


def test_the_limit_thickness_is_found_once_and_the_cycle_evaluates_the_model_once() -> None:
    stage = _stage()
    limit = stage.limit_thickness_mm
    assert _by_hand(limit) <= 35.0 < _by_hand(limit * (1.0 + 1e-5))  # the model by hand
    calls = []
    model = stage.mirs_mpa
    stage.mirs_mpa = lambda h_mm: calls.append(h_mm) or model(h_mm)  # type: ignore[method-assign]
    for t_s, (h_mm, feed) in enumerate(((0.04, 100.0), (0.09, 80.0), (0.08, 100.0))):
        calls.clear()
        state = stage.process(_state(h_mm, feed=feed, t_s=100.0 * (t_s + 1)))
        assert calls == [h_mm]  # the prediction; the command needs no search
        (command,) = state.commands
        assert _meets_edge(h_mm * (command.value / feed))


def test_feed_only_by_default_and_the_bounds_hold() -> None:
    (feed,) = _stage().process(_state(0.04)).commands
    assert feed.action == "feed_override"
    assert _meets_edge(0.04 * feed.value / 100.0)
    (low,) = _stage(max_mpa=1.0).process(_state(0.04)).commands  # unreachable: lower bound
    assert low.value == 20.0


def test_below_the_band_it_raises_back_but_never_above_100_percent() -> None:
    (feed,) = _stage(min_mpa=30.0).process(_state(0.01, feed=50.0)).commands
    assert feed.value == 100.0  # 0.02 mm at 100 % is still below 35 MPa
    (feed,) = _stage(min_mpa=30.0).process(_state(0.01, feed=20.0)).commands
    assert 20.0 < feed.value < 100.0  # 0.05 mm at 100 % would be above 35 MPa
    assert _meets_edge(0.01 * feed.value / 20.0)
    assert _stage(min_mpa=30.0).process(_state(0.01, feed=100.0)).commands == []  # at 100 %


def test_interval_deadband_and_lost_machine() -> None:
    stage = _stage(interval_s=10.0)
    assert len(stage.process(_state(0.04, t_s=1.0)).commands) == 1
    assert stage.process(_state(0.04, t_s=2.0)).commands == []  # within the interval
    lost = _state(0.08, t_s=3.0)
    lost.connected = False
    assert stage.process(lost).commands == [] and "mirs_max_mpa" not in lost.predicted
    stage.forget()  # after a gap (the runtime calls it)
    assert len(stage.process(_state(0.04, t_s=3.5)).commands) == 1
    # inside the deadband: a change below 1 % of override is not worth a command
    near = _state(0.04, feed=100.0, t_s=20.0)
    target = stage.process(near).predicted["mirs_target_feed_pct"]
    assert stage.process(_state(0.04 * target / 100.0, feed=target, t_s=40.0)).commands == []


def test_its_commands_obey_the_lost_machine_policy() -> None:
    from cnctwin.control import ControlConfig, SafetyFilter

    safety = SafetyFilter(
        ControlConfig.model_validate(
            {
                "enabled": True,
                "feed_override": {"min_pct": 20.0, "max_pct": 100.0},
                "spindle_override": {"min_pct": 50.0, "max_pct": 100.0},
            }
        )
    )
    feed, spindle = _stage(spindle_share=1.0).process(_state(0.04)).commands
    readback = {"feed_override_pct": 100.0, "spindle_override_pct": 100.0}
    assert safety.check(feed, 1.0, readback=readback).send
    spindle_verdict = safety.check(spindle, 1.0, readback=readback)
    assert spindle_verdict.send or spindle_verdict.outcome == "clamped"
    # a restarted control at 100 %: the lowered feed is written again; the spindle is only noted
    again = safety.after_reconnect({"feed_override_pct": 100.0, "spindle_override_pct": 100.0}, 9.0)
    resent = {v.decision.action: v for v in again if v.send}
    assert resent["feed_override"].value == pytest.approx(feed.value)
    assert "spindle_override" not in resent


@pytest.mark.parametrize(
    ("changes", "words"),
    [
        ({"control": True}, "control = true needs max_mpa"),
        ({"max_mpa": 30.0, "min_mpa": 30.0}, "min_mpa = 30.0 must be below max_mpa = 30.0"),
        ({"contact_length_mm": 0.0}, "contact_length_mm"),
    ],
)
def test_bad_tables_are_refused(changes: dict[str, object], words: str) -> None:
    with pytest.raises(ValidationError, match=words):
        MirsConfig(enabled=True, **changes)  # type: ignore[arg-type]


def test_an_unknown_elastic_material_is_named() -> None:
    with pytest.raises(ConfigError, match=r"twin\.mirs\.elastic: no elastic material 'steel'"):
        _stage(elastic="steel")


def _column(states: list[dict], name: str, default: float = math.nan) -> np.ndarray:  # type: ignore[type-arg]
    return np.array([s.get(name, default) for s in states])


@pytest.fixture(scope="module")
def example() -> RunConfig:
    return load_run_config(EXAMPLE)


@pytest.fixture(scope="module")
def quiet(example: RunConfig):  # type: ignore[no-untyped-def]
    off = example.model_copy(
        update={"control": example.control.model_copy(update={"enabled": False})}
    )
    return run_lockstep(off, hole=False, duration_s=40.0)


def test_on_the_virtual_machine_the_loop_brings_the_mirs_into_the_band(
    example: RunConfig,
    quiet,  # type: ignore[no-untyped-def]
) -> None:
    run = run_lockstep(example, hole=False, duration_s=40.0)
    band = example.twin.mirs
    assert band.max_mpa is not None
    mirs = _column(run.states, "mirs_max_mpa", 0.0)
    open_loop = _column(quiet.states, "mirs_max_mpa", 0.0)
    cutting, open_cutting = mirs > 0.0, open_loop > 0.0
    assert cutting.sum() > 500
    # without control most of the cut is above the band; with it, only the samples between a
    # heavier engagement's start and the next command (at most interval_s) are
    assert np.mean(open_loop[open_cutting] > band.max_mpa) > 0.5
    assert np.mean(mirs[cutting] > 1.05 * band.max_mpa) < 0.02
    assert mirs.max() <= open_loop.max() + 1e-9
    feed = _column(run.states, "feed_override_pct")
    spindle = _column(run.states, "spindle_override_pct")
    assert np.nanmin(feed) >= example.control.feed_override.min_pct
    assert np.nanmin(spindle) >= example.control.spindle_override.min_pct
    assert np.nanmin(spindle) < 100.0  # the spindle took its share
    mine = [r for r in run.twin.actions.results if r.verdict.decision.rule == "mirs"]
    assert mine and any(r.verdict.send for r in mine)


def test_with_control_disabled_nothing_is_commanded(quiet) -> None:  # type: ignore[no-untyped-def]
    assert set(_column(quiet.states, "feed_override_pct")) == {100.0}
    assert set(_column(quiet.states, "spindle_override_pct")) == {100.0}
    mine = [r for r in quiet.twin.actions.results if r.verdict.decision.rule == "mirs"]
    assert mine and {r.verdict.outcome for r in mine} == {"blocked"}
