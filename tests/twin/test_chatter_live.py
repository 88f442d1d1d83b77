"""Online chatter detection and avoidance (cnctwin.twin.chatter_live, docs/chatter-live.md).

On the virtual machine in lockstep (examples/chatter_live): the machine's own time-domain
model with the tool's modes makes the vibration; the twin detects chatter in the served
displacement block and moves the spindle to the stability roadmap's speed. Proved against
what the twin does not compute itself: the semi-discretization's lobes (an independent method)
say whether the depth at the final speed is stable, the program's geometry says when the cut
reached full engagement, and the machine's vibration says whether the cut settled (its change
over one tooth period, which a stable cut's periodic motion does not have).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Awaitable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from cnctwin.dynamics import load_stability_config
from cnctwin.dynamics.stability import MillingProcess, sdm_lobes
from cnctwin.errors import ConfigError, DataError
from cnctwin.mechanics import immersion_angles, milling_material
from cnctwin.thread import ConnectionLost, ConnectionState, MachineConnection, Reading, SampleBlock
from cnctwin.twin import CycleState, LocalConnection, RunConfig, build_twin, load_run_config
from cnctwin.twin.chatter_live import ChatterConfig, ChatterRequest, ChatterStage
from cnctwin.virtual import VirtualMachine

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "chatter_live" / "chatter_live.toml"
STEP_S = 0.01
RPM = math.pi / 30.0


def _config(folder: Path, depth_mm: float, **chatter: Any) -> RunConfig:
    config = load_run_config(EXAMPLE)
    assert config.virtual is not None and config.virtual.program is not None
    text = config.virtual.program.read_text(encoding="utf-8").replace("Z-2.5", f"Z-{depth_mm:g}")
    program = folder / f"cut_{depth_mm:g}.ngc"
    program.write_text(text, encoding="utf-8")
    twin = config.twin.model_copy(
        update={"chatter": config.twin.chatter.model_copy(update=chatter)}
    )
    return config.model_copy(
        update={"virtual": config.virtual.model_copy(update={"program": program}), "twin": twin}
    )


def _run(config: RunConfig) -> dict[str, Any]:
    """The twin against the in-process machine; rows, events, decisions, the vibration."""
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    rows: list[dict[str, float]] = []
    events: list[Any] = []
    decisions: list[Any] = []
    blocks: list[np.ndarray] = []

    def keep(state: CycleState) -> None:
        rows.append({**state.measured, **state.predicted})
        events.extend(state.events)
        decisions.extend(state.decisions)
        taken = sum(b.shape[0] for b in blocks)
        blocks.append(vm.block("vibration", taken).samples)

    async def main() -> dict[str, Any]:
        await conn.connect()
        try:
            twin = build_twin(config, conn, program=config.virtual.program, realtime=False)
            twin.runtime.on_cycle = keep
            summary = await twin.runtime.run(duration_s=30.0)
            order.extend(stage.name for stage in twin.runtime.stages)
            return twin.runtime.timings["chatter"].summary(), summary.stage_results["chatter"]
        finally:
            await conn.close()

    order: list[str] = []
    timing, results = asyncio.run(main())
    return {
        "order": order,
        "results": results,
        "rows": rows,
        "events": events,
        "decisions": decisions,
        "samples": np.vstack(blocks),
        "timing": timing,
    }


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict[str, Any]]:
    folder = tmp_path_factory.mktemp("chatter_live")
    return {
        "unstable": _run(_config(folder, 2.5)),
        "stable": _run(_config(folder, 1.0)),
    }


def _sdm_depth_mm(rpm: float) -> float:
    """The semi-discretization's critical depth of the example's half-immersion cut, mm."""
    tool = load_stability_config(EXAMPLE.parent / "tool_modes.toml").tool_dynamics()
    k = milling_material("AA6060-T6").coefficients
    entry, exit_ = immersion_angles(0.012, 0.006, True)
    process = MillingProcess(4, k.ktc, k.krc, entry, exit_)
    lobes = sdm_lobes(tool, process, [rpm * RPM], max_depth_m=0.01)
    return float(lobes.critical_depth_m[0]) * 1e3


def _full_engagement_s(rows: list[dict[str, float]]) -> float:
    """When the tool's axis reached the stock's end face (X = 150 mm) in the cut."""
    return next(r["t_s"] for r in rows if r["x_mm"] >= 150.0 and abs(r.get("force_y_n", 0)) > 10)


def _avoided(rows: list[dict[str, float]]) -> dict[str, float]:
    """The first cycle after the avoidance was asked."""
    return next(r for r in rows if r.get("chatter_avoided") == 1.0)


def test_the_depth_of_the_example_is_unstable_and_the_stable_one_stable_by_the_sdm() -> None:
    assert _sdm_depth_mm(8000.0) < 2.5 / 1.5  # 1.32 mm: 2.5 mm chatters, 1.0 mm does not
    assert _sdm_depth_mm(8000.0) > 1.0 * 1.2


def test_chatter_is_detected_within_50_ms_of_full_engagement(runs: dict[str, Any]) -> None:
    run = runs["unstable"]
    found = [e for e in run["events"] if e.kind == "chatter"]
    assert len(found) == 1
    onset = _full_engagement_s(run["rows"])
    latency = found[0].data["window_end_s"] - onset
    assert 0.0 < latency < 0.05
    assert found[0].data["frequency_hz"] == pytest.approx(930.0, abs=30.0)  # near the mode
    # the run's summary reports the same detection, timed from the steady engagement: after
    # the tool's first contact, within the detector's windows of the full engagement
    (detection,) = run["results"]["detections"]
    assert detection["window_end_s"] == found[0].data["window_end_s"]
    assert detection["frequency_hz"] == found[0].data["frequency_hz"]
    contact = next(r["t_s"] for r in run["rows"] if r.get("contact", 0.0) > 0.5)
    assert 0.0 < detection["after_engagement_s"] < found[0].data["window_end_s"] - contact
    assert abs(detection["after_engagement_s"] - latency) < 0.2
    assert runs["stable"]["results"]["detections"] == []


def test_avoidance_moves_to_the_roadmap_speed_keeping_the_chip_load(
    runs: dict[str, Any],
) -> None:
    run = runs["unstable"]
    sent = {
        r.verdict.command: r
        for r in run["decisions"]
        if r.verdict.decision.rule == "chatter_avoidance"
    }
    spindle = sent["spindle_override_pct"].verdict
    feed = sent["feed_override_pct"].verdict
    assert spindle.outcome == "sent" and feed.outcome == "sent"
    roadmap_rpm = _avoided(run["rows"])["chatter_stable_rpm"]
    assert spindle.value == pytest.approx(100.0 * roadmap_rpm / 8000.0)
    assert feed.value == pytest.approx(spindle.value)  # F / (N n) unchanged
    cutting = [r for r in run["rows"] if abs(r.get("force_y_n", 0.0)) > 10.0]
    late = cutting[-40]  # still in the steady cut, well after the command
    assert late["spindle_rpm"] == pytest.approx(roadmap_rpm, rel=0.005)
    fz = late["feed_mm_min"] / (4 * late["spindle_rpm"])
    assert fz == pytest.approx(1600.0 / (4 * 8000.0), rel=0.02)
    # independent: the semi-discretization calls the depth stable at the chosen speed
    assert _sdm_depth_mm(roadmap_rpm) > 2.5
    (change,) = run["results"]["avoidances"]
    assert change["stable_rpm"] == roadmap_rpm and change["programmed_rpm"] == 8000.0
    assert change["spindle_override_pct"] == spindle.value
    assert change["machine_s"] == _avoided(run["rows"])["t_s"]


def test_the_cut_at_the_new_speed_settles(runs: dict[str, Any]) -> None:
    run = runs["unstable"]
    samples = run["samples"]
    times = np.arange(samples.shape[0]) / 10_000.0
    rows = run["rows"]
    rpm = _avoided(rows)["chatter_stable_rpm"]
    period = 60.0 / (4 * rpm)
    change = samples - np.column_stack(
        [np.interp(times - period, times, samples[:, k]) for k in (0, 1)]
    )

    def level(a: float) -> float:
        return float(np.sqrt(np.mean(change[(times >= a) & (times < a + 0.05)] ** 2)))

    t_command = _avoided(rows)["t_s"]
    # the change over one tooth period: chatter's; 0.5 s later under a tenth, and it stays
    assert level(t_command + 0.5) < 0.1 * level(t_command)
    assert level(t_command + 1.5) < 0.1 * level(t_command)
    ratios = [r["chatter_ratio"] for r in rows if t_command + 0.3 < r["t_s"] < t_command + 1.5]
    assert max(ratios) < 0.2


def test_no_false_detection_on_a_stable_cut(runs: dict[str, Any]) -> None:
    run = runs["stable"]
    assert not [e for e in run["events"] if e.kind.startswith("chatter")]
    assert not run["decisions"]
    judged = [r for r in run["rows"] if r.get("contact") == 1.0]
    assert len(judged) > 150
    assert max(r["chatter_detected"] for r in judged) == 0.0


def test_the_stage_is_timed_and_its_outputs_reach_rules(runs: dict[str, Any]) -> None:
    timing = runs["unstable"]["timing"]
    assert timing["count"] > 400
    notes = [r for r in runs["unstable"]["decisions"] if r.verdict.decision.rule == "chatter_seen"]
    assert notes and "roadmap speed" in notes[0].verdict.decision.reason


class _Blocks(MachineConnection):
    """A connection stand-in: serves ``block`` or fails."""

    def __init__(self) -> None:
        super().__init__()
        self.state = ConnectionState.CONNECTED
        self.lost = False
        self.calls = 0

    async def _open(self) -> None:
        return None

    async def _close(self) -> None:
        return None

    async def _read(self) -> Reading:
        raise NotImplementedError

    async def _write(self, name: str, value: float) -> None:
        raise NotImplementedError

    async def _block(self, name: str, since: int) -> SampleBlock:
        return SampleBlock(name, since, 10_000.0, np.zeros((100, 2)))

    def _start_read_block(self, name: str, since: int) -> Awaitable[SampleBlock]:
        self.calls += 1
        if self.lost:
            raise ConnectionLost("gone")
        return self._block(name, since)


def test_no_reading_and_no_command_while_the_machine_is_lost() -> None:
    blocks = _Blocks()
    stage = ChatterStage(
        ChatterConfig(enabled=True, avoid=False), blocks, {1: 4}, None, (50, 120), (0, 150)
    )
    state = CycleState(0, 0.0, 1.0, connected=False, tool=1, line=14)
    asyncio.run(stage.process(state))
    assert blocks.calls == 0 and not state.commands
    blocks.lost = True
    state = CycleState(1, 0.0, 1.01, connected=True, tool=1, line=14)
    state.measured = {"spindle_rpm": 8000.0, "t_s": 1.0}
    asyncio.run(stage.process(state))
    assert not state.commands and "chatter_ratio" not in state.predicted


class _Answering(_Blocks):
    """A machine that takes the block read when it is sent and answers it when told
    (``answer``)."""

    def __init__(self) -> None:
        super().__init__()
        self.answer = asyncio.Event()

    async def _block(self, name: str, since: int) -> SampleBlock:
        await self.answer.wait()
        return await super()._block(name, since)


def test_the_read_goes_out_before_the_physics_and_the_stage_takes_its_answer() -> None:
    machine = _Answering()
    stage = ChatterStage(
        ChatterConfig(enabled=True, avoid=False), machine, {1: 4}, None, (50, 120), (0, 150)
    )
    request = ChatterRequest(stage)

    async def cycle() -> CycleState:
        state = CycleState(0, 0.0, 1.0, connected=True, tool=1, line=14)
        state.measured = {"spindle_rpm": 8000.0, "t_s": 1.0}
        request.process(state)
        assert machine.calls == 1  # the machine has the request before the physics stages run
        machine.answer.set()  # ... and answers while they run
        return await stage.process(state)

    state = asyncio.run(cycle())
    assert machine.calls == 1 and state.predicted["chatter_vibration_um"] == 0.0


def test_the_request_stage_follows_the_read(runs: dict[str, Any]) -> None:
    order = runs["unstable"]["order"]
    assert order[:3] == ["read", "chatter_request", "kinematics"]
    assert order.index("chatter") > order.index("features")


def test_bad_configuration_is_refused_in_one_line(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="hop_s"):
        ChatterConfig(window_s=0.02, hop_s=0.05)
    with pytest.raises(ValueError, match="stability_file"):
        ChatterConfig(enabled=True, avoid=True)
    config = _config(tmp_path, 2.5)
    assert config.virtual is not None
    silent = config.virtual.vibration.model_copy(update={"stability_file": None})
    vm = VirtualMachine(config.virtual.model_copy(update={"vibration": silent}), config)
    with pytest.raises(DataError, match="set \\[virtual.vibration\\]"):
        vm.block("vibration", 0)
    conn = LocalConnection(vm)

    async def build() -> None:
        await conn.connect()
        build_twin(config, conn, program=None, realtime=False)

    with pytest.raises(ConfigError, match="twin.chatter.avoid needs the NC program"):
        asyncio.run(build())


class _Garbage(_Blocks):
    """Serves good blocks, or (``bad``) one the machine's decoder refuses."""

    def __init__(self) -> None:
        super().__init__()
        self.bad = False

    async def _block(self, name: str, since: int) -> SampleBlock:
        if self.bad:
            raise DataError("block 'vibration': Machine.Vibration.Block: rate nan Hz; valid: ...")
        return await super()._block(name, since)


def _cycle(stage: ChatterStage, k: int) -> CycleState:
    state = CycleState(k, 0.0, 1.0 + 0.01 * k, connected=True, tool=1, line=14)
    state.measured = {"spindle_rpm": 8000.0, "t_s": 1.0 + 0.01 * k}
    return asyncio.run(stage.process(state))


def test_a_garbage_block_after_good_ones_is_rejected_and_the_stage_goes_on() -> None:
    blocks = _Garbage()
    stage = ChatterStage(
        ChatterConfig(enabled=True, avoid=False), blocks, {1: 4}, None, (50, 120), (0, 150)
    )
    _cycle(stage, 0)  # a good block: the machine serves vibration
    blocks.bad = True
    state = _cycle(stage, 1)
    assert [e.kind for e in state.events] == ["chatter_block_rejected"]
    assert "rate nan Hz" in state.events[0].message and not state.commands
    blocks.bad = False
    state = _cycle(stage, 2)  # the next good block is taken again
    assert not state.events and "chatter_vibration_um" in state.predicted


def test_a_machine_whose_first_block_is_garbage_is_refused() -> None:
    blocks = _Garbage()
    blocks.bad = True
    stage = ChatterStage(
        ChatterConfig(enabled=True, avoid=False), blocks, {1: 4}, None, (50, 120), (0, 150)
    )
    with pytest.raises(DataError, match=r"^twin\.chatter: block 'vibration'"):
        _cycle(stage, 0)
