"""Roughness in the live cycle: the kinematic feed marks and Royandi 2026's chain.

Independent sides: the closed forms of the feed marks with the feed per tooth of the NC
program (F / (S z)) and of the feed override commanded to the machine; the paper's 56 cuts and
its printed metrics for Eq. 24; and the offline quality functions applied to the historian's
record of the run, sample for sample and section for section. Lockstep runs in process (one
machine step per cycle): deterministic, however loaded the machine running the tests is.
"""

from __future__ import annotations

import asyncio
import math
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from cnctwin.control import RuleConfig
from cnctwin.errors import ConfigError
from cnctwin.quality import ROYANDI_2026_EQ24, end_mill_feed_marks, fit_metrics
from cnctwin.store.historian import Historian
from cnctwin.thread import MqttConfig, RunState
from cnctwin.thread.mqtt import SensorValue
from cnctwin.twin.config import RunConfig, load_run_config
from cnctwin.twin.local import LocalConnection
from cnctwin.twin.pipeline import build_twin, shed_order, signal_names
from cnctwin.twin.recorder import Recorder
from cnctwin.twin.roughness import RoughnessConfig, RoughnessStage
from cnctwin.twin.runtime import RunSummary
from cnctwin.twin.state import CycleState
from cnctwin.virtual import VirtualMachine

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "roughness" / "roughness_twin.toml"
STEP_S = 0.025  # machine time per twin cycle
#: The example's slots: NC line -> programmed feed (mm/min); S 6000 rpm, 4 flutes.
SLOTS = {17: 1800.0, 23: 2400.0, 29: 1200.0}
RPM, FLUTES, CORNER_MM, DIAMETER_MM = 6000.0, 4, 1.0, 10.0
#: The sensor's synthetic vibration RMS, g: a level plus a part growing with the force.
VIB_G0, VIB_G_PER_N = 0.8, 0.004


class _Accelerometer:
    """An accelerometer's RMS as an ``[mqtt]`` sensor source would deliver it
    (``vibration_rms_g``), from the virtual machine's own force at each read."""

    rejected: dict[str, int] = {}

    def __init__(self, vm: VirtualMachine) -> None:
        self.vm = vm
        self.link = SimpleNamespace(drain=list)  # no broker: no link events

    def latest(self) -> dict[str, SensorValue]:
        values = self.vm.snapshot()
        force = math.hypot(values["force_x_n"], values["force_y_n"])
        return {"vibration_rms_g": SensorValue(VIB_G0 + VIB_G_PER_N * force, time.monotonic())}

    def problems(self) -> dict[str, str]:
        return {}

    def stats(self) -> dict[str, Any]:
        return {}


@pytest.fixture(scope="module")
def example() -> RunConfig:
    return load_run_config(EXAMPLE)


def _with_vibration(config: RunConfig) -> RunConfig:
    """The example with the accelerometer's RMS declared as an [mqtt] sensor signal (the
    test's source delivers it) and read by [twin.roughness], and the form error on."""
    roughness = config.twin.roughness.model_copy(update={"vibration": "vibration_rms_g"})
    sensor = {"topic": "cell4/spindle/accel_rms", "signal": "vibration_rms_g", "unit": "g"}
    return config.model_copy(
        update={
            "twin": config.twin.model_copy(
                update={
                    "roughness": roughness,
                    "form_error": config.twin.form_error.model_copy(update={"enabled": True}),
                }
            ),
            "mqtt": MqttConfig.model_validate({"enabled": True, "signals": [sensor]}),
        }
    )


def _run(
    config: RunConfig,
    db: Path,
    *,
    override_pct: float | None = None,
    vibration: bool = False,
    machine: list[VirtualMachine] | None = None,
) -> tuple[RunSummary, list[dict[str, float]]]:
    virtual = config.virtual
    assert virtual is not None
    vm = VirtualMachine(virtual, config)
    if machine is not None:
        machine.append(vm)
    if override_pct is not None:
        vm.command("feed_override_pct", override_pct)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    source: Any = _Accelerometer(vm) if vibration else None
    rows: list[dict[str, float]] = []

    def keep(state: CycleState) -> None:
        if state.new_sample:
            rows.append({**state.measured, **state.predicted, "line": float(state.line)})

    async def main() -> RunSummary:
        await conn.connect()
        try:
            with Historian.open(db) as historian:
                recorder = Recorder(historian, {"test": "roughness"}, 0.0)
                twin = build_twin(
                    config,
                    conn,
                    recorder=recorder,
                    program=virtual.program,
                    realtime=False,
                    mqtt_source=source,
                )
                twin.runtime.on_cycle = keep
                return await twin.runtime.run(duration_s=120.0)
        finally:
            await conn.close()

    return asyncio.run(main()), rows


def _steady(rows: list[dict[str, float]], line: int) -> list[dict[str, float]]:
    """The cutting samples of a slot at its programmed feed (past the acceleration)."""
    feed = SLOTS[line]
    return [
        r
        for r in rows
        if r["line"] == line
        and r["contact"]
        and abs(r["feed_mm_min"] - feed * r["feed_override_pct"] / 100.0) < 1e-3 * feed
        and abs(r["spindle_rpm"] - RPM) < 1e-3 * RPM
    ]


@pytest.mark.parametrize("override_pct", [None, 50.0])
def test_feed_marks_follow_the_closed_form_of_the_programmed_feed_and_override(
    example: RunConfig, tmp_path: Path, override_pct: float | None
) -> None:
    summary, rows = _run(example, tmp_path / "r.sqlite", override_pct=override_pct)
    assert summary.ended == "finished"
    scale = 1.0 if override_pct is None else override_pct / 100.0
    sections = {s["line"]: s for s in summary.stage_results["roughness"]["sections"]}
    assert set(sections) == set(SLOTS)
    for line, feed in SLOTS.items():
        fz_mm = feed * scale / (RPM * FLUTES)  # the program's feed per tooth, override in
        steady = _steady(rows, line)
        assert len(steady) > 20
        for r in steady:
            # Rt = fz^2 / (8 r) (parabolic, within (fz/2r)^2/4 of the exact arc) and Ra = Rt/4
            assert r["roughness_kin_rz_um"] == pytest.approx(
                fz_mm**2 / (8 * CORNER_MM) * 1e3, rel=5e-3
            )
            assert r["roughness_kin_ra_um"] == pytest.approx(
                fz_mm**2 / (32 * CORNER_MM) * 1e3, rel=5e-3
            )
            radius = DIAMETER_MM / 2
            assert r["roughness_kin_wall_rz_um"] == pytest.approx(
                fz_mm**2 / (8 * radius) * 1e3, rel=5e-3
            )
            assert math.isnan(r["roughness_ra_um"])  # no vibration sensor: no power-law Ra
        assert sections[line]["kin_rz_max_um"] == pytest.approx(
            fz_mm**2 / 8 / CORNER_MM * 1e3, rel=0.02
        )
    # the example's rule notes the coarse slot (fz 0.1 mm: Rz 1.25 um > 1.0 um), and only it;
    # at half the feed no slot passes the limit
    assert summary.decisions == (1 if override_pct is None else 0)


def test_royandi_chain_reproduces_the_papers_eq24_figures_on_its_56_cuts() -> None:
    """The stage's Ra on the paper's cuts (Tables 3 and 4, typed in tests/quality) against the
    measured Ra: the paper prints MAPE 9.59 % and RMSE 0.158 um for Eq. 24."""
    from quality.test_roughness import ALL_CUTS, MEASURED  # the paper's tables

    config = RoughnessConfig(enabled=True, vibration="vibration_rms_g")
    stage = RoughnessStage(
        config, [], ["ap_mm", "spindle_rpm", "feed_per_tooth_mm", "vibration_rms_g"]
    )
    predicted = []
    for ap, rpm, fz, vib in ALL_CUTS[:, [0, 1, 2, MEASURED]]:
        state = CycleState(0, 0.0, 0.0)
        state.connected = True
        state.measured = {"spindle_rpm": float(rpm), "vibration_rms_g": float(vib)}
        state.predicted = {"contact": 1.0, "ap_mm": float(ap), "feed_per_tooth_mm": float(fz)}
        predicted.append(stage.process(state).predicted["roughness_ra_um"])
    metrics = fit_metrics(ALL_CUTS[:, 5], np.array(predicted))
    assert metrics.mape_percent == pytest.approx(9.59, abs=0.05)
    assert metrics.rmse == pytest.approx(0.158, abs=0.0015)
    assert metrics.samples == 56


def test_live_values_equal_the_offline_functions_on_the_recorded_run(
    example: RunConfig, tmp_path: Path
) -> None:
    db = tmp_path / "v.sqlite"
    summary, _ = _run(_with_vibration(example), db, vibration=True)
    with Historian.open(db) as h:
        run_id = h.runs()[-1].run_id
        measured = h.samples(run_id, ["spindle_rpm", "vibration_rms_g", "program_line"])
        predicted = h.samples(run_id, predicted=True)
    assert np.array_equal(measured["time_s"], predicted["time_s"])
    cut = (predicted["contact"] == 1.0) & (predicted["feed_per_tooth_mm"] > 0.0)
    assert cut.sum() > 300
    # the power law needs every feature > 0 (an engagement can touch with ap 0)
    known = cut & (predicted["ap_mm"] > 0.0) & (measured["vibration_rms_g"] > 0.0)
    assert known.sum() > 0.9 * cut.sum()
    ra = ROYANDI_2026_EQ24.predict(
        {
            "ap_mm": predicted["ap_mm"][known],
            "spindle_rpm": np.abs(measured["spindle_rpm"][known]),
            "fz_mm": predicted["feed_per_tooth_mm"][known],
            "vibration_g": measured["vibration_rms_g"][known],
        }
    )
    np.testing.assert_allclose(predicted["roughness_ra_um"][known], ra, rtol=1e-12)
    assert np.all(np.isnan(predicted["roughness_ra_um"][~known]))
    marks = end_mill_feed_marks(
        "bull", predicted["feed_per_tooth_mm"][cut] * 1e-3, 0.01, corner_radius_m=0.001
    )
    np.testing.assert_allclose(
        predicted["roughness_kin_ra_um"][cut], marks.floor_ra * 1e6, rtol=1e-12
    )
    np.testing.assert_allclose(
        predicted["roughness_kin_rz_um"][cut], marks.floor_rt * 1e6, rtol=1e-12
    )
    np.testing.assert_allclose(
        predicted["roughness_kin_wall_rz_um"][cut], marks.wall_rt * 1e6, rtol=1e-12
    )
    assert np.all(np.isnan(predicted["roughness_kin_rz_um"][~cut]))
    # the sections of the run's summary: the recorded samples grouped by NC line
    sections = summary.stage_results["roughness"]["sections"]
    assert summary.stage_results["roughness"]["model"] == "Royandi 2026 Eq. 24"
    assert [s["line"] for s in sections] == list(SLOTS)
    lines = measured["program_line"]
    for s in sections:
        mine, mine_ra = cut & (lines == s["line"]), (lines[known] == s["line"])
        assert s["samples"] == int(mine.sum())
        assert s["ra_samples"] == int(mine_ra.sum())
        assert s["ra_mean_um"] == pytest.approx(float(np.mean(ra[mine_ra])), rel=1e-12)
        assert s["ra_max_um"] == float(np.max(ra[mine_ra]))
        assert s["kin_rz_max_um"] == float(np.max(np.asarray(marks.floor_rt)[mine[cut]] * 1e6))
        assert s["form_error_max_um"] == float(np.max(predicted["form_error_um"][mine]))
        assert s["form_error_max_um"] > 0.0
    # Ra grows with fz (exponent 0.55): the fz 0.1 mm slot is the roughest of the ap 2 mm ones
    by_line = {s["line"]: s for s in sections}
    assert by_line[23]["ra_mean_um"] > by_line[17]["ra_mean_um"]
    with Historian.open(db) as h:
        events = [e for e in h.run(run_id).events if e.kind == "roughness_section"]
    assert [e.data["line"] for e in events] == list(SLOTS)


def test_refusals_name_the_key(example: RunConfig, tmp_path: Path) -> None:
    names = signal_names(example)
    with pytest.raises(ConfigError, match="reads 'accel_g', which this twin does not provide"):
        RoughnessStage(RoughnessConfig(enabled=True, vibration="accel_g"), example.tools, names)
    bad = tmp_path / "model.json"
    bad.write_text('{"b0": 2.0, "exponents": {"ap_mm": 0.4, "depth_um": 1.0}}')
    with pytest.raises(ConfigError, match="feature 'depth_um' reads no twin name"):
        RoughnessStage(RoughnessConfig(enabled=True, model=bad), example.tools, names)
    bad.write_text("[1, 2]")
    with pytest.raises(ConfigError, match="twin.roughness.model: .*not a roughness model"):
        RoughnessStage(RoughnessConfig(enabled=True, model=bad), example.tools, names)


def test_shed_under_overload_unless_a_protective_rule_reads_it(example: RunConfig) -> None:
    assert shed_order(example)[-1] == "roughness"
    rough = RuleConfig(name="rough", condition="roughness_section_ra_mean_um > 1.6", action="stop")
    guarded = example.model_copy(update={"rules": [*example.rules, rough]})
    assert "roughness" not in shed_order(guarded)


def test_a_stop_rule_on_a_sections_roughness_stops_the_machine_in_that_section(
    example: RunConfig, tmp_path: Path
) -> None:
    """With control on, a ``stop`` rule on the section's feed marks stops the machine in the
    coarse slot (line 23), confirmed by the machine's own state, through the safety filter."""
    stop = RuleConfig(
        name="too_rough", condition="roughness_section_kin_rz_max_um > 1.0", action="stop"
    )
    config = example.model_copy(
        update={"rules": [stop], "control": example.control.model_copy(update={"enabled": True})}
    )
    vms: list[VirtualMachine] = []
    summary, rows = _run(config, tmp_path / "s.sqlite", machine=vms)
    assert summary.ended == "stopped" and summary.decisions >= 1
    assert vms[0].run_state == RunState.STOPPED
    assert rows[-1]["line"] == 23  # stopped in the slot whose marks passed the limit
    assert "roughness" not in shed_order(config)  # a protective rule reads it: never shed
