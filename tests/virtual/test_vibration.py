"""The virtual machine's regenerative vibration (cnctwin.virtual.vibration, MillingStream).

Against independent methods: the semi-discretization's critical depth (Insperger & Stépán,
a different method from the time-domain integration) says which depth of the example's side
cut is stable; the machine's vibration sensor must agree, by the offline detector's verdict
and by the vibration's size. The stream in pieces must give what one simulation gives.
"""

from __future__ import annotations

import asyncio
import math
import socket
from pathlib import Path

import numpy as np
import pytest

from cnctwin.dynamics import (
    CutConditions,
    DetectorSettings,
    MillingStream,
    detect_chatter,
    load_stability_config,
    simulate_milling,
)
from cnctwin.dynamics.stability import MillingProcess, sdm_lobes
from cnctwin.errors import DataError
from cnctwin.geometry import Cutter
from cnctwin.mechanics import immersion_angles, milling_material
from cnctwin.thread import OpcUaConnection, SampleBlock
from cnctwin.twin import load_run_config
from cnctwin.virtual import OpcUaMachineServer, VirtualMachine

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "chatter_live" / "chatter_live.toml"
RPM = math.pi / 30.0
MODES = load_stability_config(EXAMPLE.parent / "tool_modes.toml").tool_dynamics()
COEFFICIENTS = milling_material("AA6060-T6").coefficients


def _sdm_critical_mm(rpm: float) -> float:
    entry, exit_ = immersion_angles(0.012, 0.006, True)
    process = MillingProcess(4, COEFFICIENTS.ktc, COEFFICIENTS.krc, entry, exit_)
    return float(sdm_lobes(MODES, process, [rpm * RPM], max_depth_m=0.01).critical_depth_m[0]) * 1e3


def _cut(tmp_path: Path, depth_mm: float) -> np.ndarray:
    """The y displacement (um) the machine's sensor took over 1 s of the steady cut."""
    config = load_run_config(EXAMPLE)
    assert config.virtual is not None and config.virtual.program is not None
    text = config.virtual.program.read_text(encoding="utf-8").replace("Z-2.5", f"Z-{depth_mm:g}")
    program = tmp_path / "cut.ngc"
    program.write_text(text, encoding="utf-8")
    vm = VirtualMachine(config.virtual.model_copy(update={"program": program}), config)
    while vm.snapshot()["x_mm"] < 151.0:  # to full engagement: the axis past the end face
        vm.step(vm.tick_s)
    for _ in range(10):  # the entry's transient
        vm.step(vm.tick_s)
    start = vm.block("vibration", 0).end_index
    for _ in range(200):  # 1 s of the steady cut
        vm.step(vm.tick_s)
    samples = [vm.block("vibration", start).samples]
    return np.vstack(samples)[:, 1]


@pytest.mark.parametrize("fraction", [0.75, 1.25])
def test_the_machine_chatters_above_the_sdm_lobe_and_not_below(
    tmp_path: Path, fraction: float
) -> None:
    critical = _sdm_critical_mm(8000.0)  # 1.32 mm at half immersion
    signal = _cut(tmp_path, round(fraction * critical, 2))
    settings = DetectorSettings(
        sample_rate_hz=10_000.0, spindle_rpm=8000.0, teeth=4, window_s=0.1, threshold=0.2
    )
    result = detect_chatter(signal, settings)
    if fraction < 1.0:
        assert not result.chatter.any()
        assert result.energy_ratio.max() < 0.02
        assert np.std(signal) < 10.0  # um: the forced vibration
    else:
        assert result.chatter.all()
        assert np.nanmedian(result.chatter_frequency_hz) == pytest.approx(925.0, abs=30.0)
        assert np.std(signal) > 20.0


def test_the_stream_in_pieces_is_one_simulation() -> None:
    cutter = Cutter("flat", 12.0, 20.0, flutes=4)  # straight flutes: one slice
    entry, exit_ = immersion_angles(0.012, 0.006, True)
    process = MillingProcess(4, COEFFICIENTS.ktc, COEFFICIENTS.krc, entry, exit_)
    whole = simulate_milling(
        MODES, process, spindle_rad_s=8000 * RPM, depth_m=1.5e-3, feed_per_tooth_m=5e-5,
        duration_s=0.05, cutter=cutter, edge_tangential_n_m=COEFFICIENTS.kte,
        edge_radial_n_m=COEFFICIENTS.kre,
    )  # fmt: skip
    stream = MillingStream(MODES, cutter, COEFFICIENTS, design_rpm=8000.0)
    assert stream.steps_per_tooth == whole.steps_per_tooth
    conditions = CutConditions(8000 * RPM, 1.5e-3, entry, exit_, 5e-5)
    total = whole.time_s.size
    pieces, done = [], 0
    for size in (1, 7, 333, 1000):  # then the rest
        pieces.append(stream.advance(conditions, size))
        done += size
    pieces.append(stream.advance(conditions, total - done))
    rows = np.vstack(pieces)
    np.testing.assert_allclose(rows[:, 0:2], whole.displacement_m, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(rows[:, 6:8], whole.force_n, rtol=1e-9, atol=1e-9)
    assert stream.time_s == pytest.approx(total * whole.tooth_period_s / whole.steps_per_tooth)


def test_the_sensor_serves_what_it_took_since_an_index(tmp_path: Path) -> None:
    config = load_run_config(EXAMPLE)
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    for _ in range(300):  # 1.5 s; the ring holds 1 s
        vm.step(vm.tick_s)
    newest = vm.block("vibration", 0)
    assert newest.rate_hz == 10_000.0
    # samples at 0, 0.1 ms, ..., 1.5 s; the ring keeps the last 10,000
    assert newest.end_index == 15_001 and newest.first_index == 5_001
    tail = vm.block("vibration", 14_991)
    assert tail.first_index == 14_991 and tail.samples.shape == (10, 2)
    np.testing.assert_array_equal(tail.samples, newest.samples[-10:])
    assert vm.block("vibration", 15_001).samples.shape == (0, 2)


def test_the_warm_up_leaves_the_machine_as_it_was() -> None:
    # A warmed machine (its kernels compiled before the clock starts) cuts what a cold one cuts,
    # sample for sample: the warm-up integrates a throw-away stream, not the sensor's.
    config = load_run_config(EXAMPLE)
    assert config.virtual is not None
    warmed, cold = VirtualMachine(config.virtual, config), VirtualMachine(config.virtual, config)
    warmed.warm_up()
    assert warmed.block("vibration", 0).end_index == 0
    for _ in range(400):  # 2 s: into the cut
        warmed.step(warmed.tick_s)
        cold.step(cold.tick_s)
    ours, theirs = warmed.block("vibration", 0), cold.block("vibration", 0)
    assert ours.end_index == theirs.end_index == 20_000
    assert np.abs(theirs.samples).max() > 1.0  # um: the tool did cut
    np.testing.assert_array_equal(ours.samples, theirs.samples)


def test_the_block_travels_over_opc_ua() -> None:
    # The server makes the node's value when it is read: the newest 0.1 s; the client keeps
    # the samples from its index on, and from the oldest served when it asks for older ones.
    config = load_run_config(EXAMPLE)
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    for _ in range(50):  # 0.25 s: samples 0 ... 2500
        vm.step(vm.tick_s)
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    endpoint = f"opc.tcp://127.0.0.1:{port}/cnctwin"

    async def body() -> tuple[SampleBlock, SampleBlock]:
        async with OpcUaMachineServer(vm, "127.0.0.1", port):
            link = config.connection.model_copy(update={"endpoint": endpoint})
            async with OpcUaConnection(link) as connection:
                recent = await connection.read_block("vibration", 2400)
                old = await connection.read_block("vibration", 0)
                with pytest.raises(DataError, match="'vibration' only"):
                    await connection.read_block("acceleration", 0)
                return recent, old

    recent, old = asyncio.run(body())
    here = vm.block("vibration", 2400)
    assert (recent.first_index, recent.rate_hz) == (2400, 10_000.0)
    np.testing.assert_array_equal(recent.samples, here.samples)
    assert old.first_index == 1501 and old.end_index == 2501  # the newest 1000 samples
