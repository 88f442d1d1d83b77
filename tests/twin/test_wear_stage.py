"""The wear stage alone, on hand-made samples: the idle torque it learns, the steady-cut gate,
and the estimate it converges to (the wear whose Eq. 8 torque is the measured excess: closed
form through the model's inverse)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from cnctwin.twin import CycleState, WearConfig
from cnctwin.twin.tool_wear import WearStage

IDLE_NM = 0.6
CUTTING_NM = 0.75
CONFIG = {
    "enabled": True,
    "vb0_mm": 0.05,
    "q_per_mm3": 1e-9,  # practically no growth: the estimate is the torque's alone
    "vb_max_mm": 0.62,
    "p0_nm": 0.1582,
    "p1_per_mm": 1.0,
    "p2": 0.6423,
    "p3_per_mm": 1.0,
    "p4_nm": 0.4385,
    "process_var_mm2": 1e-6,
    "measurement_var_nm2": 1e-4,
}


def _sample(
    index: int, signal: str, value: float, *, contact: bool, rpm: float = 10_000.0
) -> CycleState:
    state = CycleState(index, 0.0, index * 0.0125)
    state.connected = state.new_sample = True
    state.tool = 1
    state.dt_machine_s = 0.025
    state.measured = {"spindle_rpm": rpm, signal: value}
    state.engagement = SimpleNamespace(contact=contact, removed_volume_mm3=5.0 if contact else 0.0)
    state.predicted["predicted_torque_nm"] = CUTTING_NM if contact else 0.0
    return state


@pytest.mark.parametrize(
    ("signal", "per_nm"), [("spindle_torque_nm", 1.0), ("spindle_current_a", 2.0)]
)
def test_stage_learns_idle_waits_for_a_steady_cut_and_finds_the_wear(
    signal: str, per_nm: float
) -> None:
    config = WearConfig(
        **CONFIG, signal=signal, torque_constant_nm_a=1.0 / per_nm if per_nm != 1.0 else None
    )
    stage = WearStage(config)
    true_vb = 0.25
    wear_nm = stage.torque_model.torque_nm(true_vb)
    # in air, steady speed: the idle torque is learnt (the first sample has no speed before
    # it to call steady)
    for k in range(10):
        stage.process(_sample(k, signal, IDLE_NM * per_nm, contact=False))
    assert stage.idle_torque_nm == pytest.approx(IDLE_NM)
    # a spindle speeding up in air teaches nothing
    stage.process(_sample(10, signal, 5.0 * per_nm, contact=False, rpm=5_000.0))
    assert stage.idle_torque_nm == pytest.approx(IDLE_NM)
    stage.process(_sample(11, signal, IDLE_NM * per_nm, contact=False))
    # the cut: the first settle_samples - 1 samples only predict
    measured = (IDLE_NM + CUTTING_NM + wear_nm) * per_nm
    states = [_sample(12 + k, signal, measured, contact=True) for k in range(400)]
    for state in states:
        stage.process(state)
    updated = [("wear_torque_nm" in s.predicted) for s in states]
    assert updated[: config.settle_samples - 1] == [False] * (config.settle_samples - 1)
    assert all(updated[config.settle_samples :])
    last = states[-1].predicted
    assert last["wear_torque_nm"] == pytest.approx(wear_nm, rel=1e-9)
    assert last["wear_vb_mm"] == pytest.approx(true_vb, abs=1e-3)
    assert last["wear_stage"] == 3.0  # stages begin at 0.05, 0.2, 0.55 mm (the defaults)
    # life to 0.3 mm under the (nearly flat) law: far away, and the time is material / rate
    assert last["wear_life_mm3"] > 1e6
    assert last["wear_life_s"] == pytest.approx(last["wear_life_mm3"] / (5.0 / 0.025))


def test_entering_the_material_is_no_steady_cut() -> None:
    stage = WearStage(WearConfig(**CONFIG))
    for k in range(5):
        stage.process(_sample(k, "spindle_torque_nm", IDLE_NM, contact=False))
    states = []
    for k in range(20):  # the predicted torque rises 10 % a sample: the tool enters
        state = _sample(5 + k, "spindle_torque_nm", 3.0, contact=True)
        state.predicted["predicted_torque_nm"] = CUTTING_NM * 1.1**k
        stage.process(state)
        states.append(state)
    assert not any("wear_torque_nm" in s.predicted for s in states)
    assert states[-1].predicted["wear_vb_mm"] == pytest.approx(0.05, rel=1e-6)
