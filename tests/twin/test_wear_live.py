"""Wear in the live cycle: the twin's EKF against the virtual machine's true flank wear.

The virtual machine's accelerated-wear fault gives its tool a true flank wear that grows by
its own law (a rate rising with the wear land, ``dVB/dt = r (1 + (VB/VBref)^2)``) and a
rubbing torque linear in VB (the worn edge's force); the twin's filter knows neither: it
predicts with Christiand 2024's logistic law of a normal tool and explains the torque with
the paper's logarithmic model fitted to calibration pairs. The independent side of every
check is the machine: its true wear (``VirtualMachine.tool_wear_mm``), its run state, and the
historian's record. Lockstep runs in process (one machine step per cycle): deterministic,
however loaded the machine running the tests is.
"""

from __future__ import annotations

import asyncio
import math
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from cnctwin.errors import ConfigError
from cnctwin.store.historian import Historian
from cnctwin.thread.signals import RunState
from cnctwin.twin.config import RunConfig, load_run_config
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.pipeline import build_twin
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.runtime import RunSummary
from cnctwin.twin.state import CycleState
from cnctwin.virtual import VirtualMachine

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "wear" / "wear_twin.toml"
STEP_S = 0.025  # machine time per twin cycle


@pytest.fixture(scope="module")
def wear_config() -> RunConfig:
    return load_run_config(EXAMPLE)


def _run(config: RunConfig, db: Path, *, fault: bool) -> tuple[RunSummary, VirtualMachine, list]:
    """The twin against an in-process virtual machine; per new sample: machine time, true
    wear, and the twin's predictions."""
    assert config.virtual is not None
    virtual = config.virtual if fault else config.virtual.model_copy(update={"faults": []})
    vm = VirtualMachine(virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    rows: list[tuple[float, float, dict[str, float], list[str]]] = []

    def keep(state: CycleState) -> None:
        if state.new_sample:
            events = [e.message for e in state.events if e.kind == "wear_stage"]
            rows.append((state.measured["t_s"], vm.tool_wear_mm, dict(state.predicted), events))

    async def main() -> RunSummary:
        await conn.connect()
        try:
            with Historian.open(db) as historian:
                recorder = Recorder(historian, {"test": "wear"}, 0.0)
                twin = build_twin(
                    config,
                    conn,
                    recorder=recorder,
                    program=virtual.program,
                    realtime=False,
                    clock=lambda: vm.time_s,  # machine time: the 120 s limit is the machine's
                )
                twin.runtime.on_cycle = keep
                return await twin.runtime.run(duration_s=120.0)
        finally:
            await conn.close()

    return asyncio.run(main()), vm, rows


def test_estimate_tracks_the_true_wear_and_stage_iv_stops_the_machine(
    wear_config: RunConfig, tmp_path: Path
) -> None:
    db = tmp_path / "h.sqlite"
    summary, vm, rows = _run(wear_config, db, fault=True)
    # the machine itself is stopped, by the twin, at wear stage IV
    assert summary.ended == "stopped"
    assert vm.run_state == RunState.STOPPED
    stage_iv = next(k for k, row in enumerate(rows) if row[2]["wear_stage"] >= 4)
    true_at_iv = rows[stage_iv][1]
    assert 0.33 < true_at_iv < 0.45  # the stage begins at 0.40 mm of (estimated) wear
    # while the tool cuts, the estimate follows the machine's true wear (measured: mean
    # 0.021 mm, max 0.050 mm); the truth went from 0.02 to 0.39 mm
    cutting = [(true, p["wear_vb_mm"]) for _, true, p, _ in rows if p.get("contact") == 1.0]
    true, estimate = np.array(cutting).T
    error = np.abs(estimate - true)
    assert true[0] < 0.05 and true[-1] > 0.35
    assert float(np.mean(error)) < 0.03
    assert float(np.max(error)) < 0.07
    # each stage entry is an event, flagged early (the normal tool takes minutes)
    events = [m for *_, found in rows for m in found]
    assert [m.split(" entered stage ")[1].split()[0] for m in events] == ["II", "III", "IV"]
    assert all("earlier than normal" in m for m in events)
    # the decisions and the predictions are in the historian
    with sqlite3.connect(db) as conn:
        decisions = conn.execute("SELECT rule, action, accepted FROM hist_decisions").fetchall()
        kinds = [k for (k,) in conn.execute("SELECT kind FROM hist_events")]
    assert ("worn_out", "stop", 1) in decisions
    assert ("tool_change_due", "tool_change", 0) in decisions  # recorded, nothing written
    assert kinds.count("wear_stage") == 3
    with Historian.open(db) as historian:
        run_id = historian.runs()[-1].run_id
        recorded = historian.samples(run_id, ["wear_vb_mm", "wear_stage"], predicted=True)
    assert np.nanmax(recorded["wear_stage"]) == 4.0
    assert np.nanmax(recorded["wear_vb_mm"]) == pytest.approx(rows[-1][2]["wear_vb_mm"])


def test_clean_run_gives_no_stage_iv(wear_config: RunConfig, tmp_path: Path) -> None:
    summary, vm, rows = _run(wear_config, tmp_path / "h.sqlite", fault=False)
    assert summary.ended == "finished"
    assert vm.run_state == RunState.FINISHED
    assert vm.tool_wear_mm == 0.0
    assert max(p["wear_stage"] for _, _, p, _ in rows) == 1.0
    # the model's floor: zero wear torque is VB 0.038 mm in the fitted Eq. 8
    assert max(p["wear_vb_mm"] for _, _, p, _ in rows) < 0.06
    life = [p["wear_life_s"] for _, _, p, _ in rows if "wear_life_s" in p]
    assert life and min(life) > 60.0 and all(math.isfinite(v) for v in life)


@pytest.mark.parametrize(
    ("table", "expected"),
    [
        ("stages_mm = [0.2, 0.1, 0.4]", "stages_mm must be three increasing wear values"),
        ("vb_max_mm = 0.7", "vb_max_mm = 0.7 mm must be below p2/p3 = 0.6423 mm"),
        ("life_vb_mm = 0.62", "life_vb_mm = 0.62 mm must be below vb_max_mm = 0.62 mm"),
        ('signal = "spindle_current_a"', "needs torque_constant_nm_a"),
    ],
)
def test_bad_wear_table_is_one_line_error(tmp_path: Path, table: str, expected: str) -> None:
    text = EXAMPLE.read_text().replace("[twin.wear]\n", f"[twin.wear]\n{table}\n", 1)
    if table.startswith(("stages_mm", "vb_max_mm", "life_vb_mm")):
        key = table.split(" =")[0]
        text = "\n".join(
            line
            for line in text.splitlines()
            if not (line.startswith(f"{key} =") and line != table)
        )
    path = tmp_path / "wear.toml"
    path.write_text(text)
    (path.parent / "wear_slots.ngc").write_text((EXAMPLE.parent / "wear_slots.ngc").read_text())
    with pytest.raises(ConfigError) as err:
        load_run_config(path)
    assert "\n" not in str(err.value) and expected in str(err.value)
    assert "twin.wear" in str(err.value)
