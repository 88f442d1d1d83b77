"""Chatter detection against closed forms, the streaming form, and simulated cuts whose
stability the semi-discretization (another algorithm) decides.

Benchmarks: ../shared/data/stability/NOTES.md section 1 (Insperger & Stépán: 2 teeth, 922 Hz,
zeta 0.011, k 1340049.648 N/m, Kt 600, Kn 200 N/mm^2; slot with a 1-DOF tool, a/D = 0.05
down-milling with a symmetric 2-DOF tool).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.dynamics import _sdm
from cnctwin.dynamics.chatter_detection import (
    DetectorSettings,
    StreamingChatterDetector,
    detect_chatter,
)
from cnctwin.dynamics.stability import MillingProcess, ToolDynamics, ToolMode, sdm_lobes
from cnctwin.dynamics.time_domain import simulate_milling
from cnctwin.errors import ConfigError, DataError
from cnctwin.mechanics import CuttingCoefficients

RPM = math.pi / 30.0
MODE = ToolMode.from_hz(922.0, 0.011, stiffness_n_m=1340049.648)
ONE_DOF = ToolDynamics.from_xy(x=[MODE])
TWO_DOF = ToolDynamics.from_xy(x=[MODE], y=[MODE])
INSPERGER = CuttingCoefficients(6e8, 2e8)
SLOT = MillingProcess.from_immersion(2, INSPERGER, 1.0)
AD005 = MillingProcess.from_immersion(2, INSPERGER, 0.05, down_milling=True)
FS = 20_000.0


def _tones(parts: list[tuple[float, float]], seconds: float = 1.0, fs: float = FS) -> np.ndarray:
    t = np.arange(int(seconds * fs)) / fs
    return sum(a * np.sin(2 * np.pi * f * t + 0.3 * i) for i, (f, a) in enumerate(parts))


def test_energy_ratio_frequency_and_amplitude_of_tones_match_the_closed_form() -> None:
    # 6000 rpm, 4 teeth: f_T = 400 Hz. Harmonics 1, 0.5, 0.2 plus a 0.6 tone at 1234.5 Hz.
    harmonics = [(400.0, 1.0), (800.0, 0.5), (1200.0, 0.2)]
    chatter = (1234.5, 0.6)
    signal = _tones([*harmonics, chatter]) + 3.0  # an offset: removed with the mean
    settings = DetectorSettings(FS, 6000.0, 4, window_s=0.2)
    found = detect_chatter(signal, settings)
    assert len(found) == 5 and settings.resolution_hz == pytest.approx(5.0)
    expected = chatter[1] ** 2 / (chatter[1] ** 2 + sum(a * a for _, a in harmonics))
    assert found.energy_ratio == pytest.approx(expected, rel=2e-3)
    # The parabolic peak interpolation: far inside one bin (1234.5 Hz lies between bins).
    assert found.chatter_frequency_hz == pytest.approx(chatter[0], abs=0.1 * 5.0)
    assert found.peak_amplitude == pytest.approx(chatter[1], rel=0.2)  # scalloping <= 15 %
    assert found.chatter.all() and found.chatter_fraction == 1.0
    assert found.first_chatter_s == pytest.approx(0.2)


def test_harmonics_alone_are_not_chatter_and_runout_needs_the_spindle_notches() -> None:
    # 4 teeth at 6000 rpm with runout: a tone at the spindle frequency (100 Hz) and its 3rd.
    signal = _tones([(400.0, 1.0), (800.0, 0.4), (100.0, 0.8), (300.0, 0.2)])
    tooth_only = detect_chatter(signal, DetectorSettings(FS, 6000.0, 4, window_s=0.1))
    assert tooth_only.chatter.all()
    assert tooth_only.chatter_frequency_hz == pytest.approx(100.0, abs=0.5)
    both = DetectorSettings(FS, 6000.0, 4, window_s=0.1, spindle_harmonics=True)
    found = detect_chatter(signal, both)
    assert not found.chatter.any() and found.energy_ratio.max() < 1e-4
    clean = detect_chatter(_tones([(400.0, 1.0), (800.0, 0.4)]), DetectorSettings(
        FS, 6000.0, 4, window_s=0.1))  # fmt: skip
    assert not clean.chatter.any() and clean.energy_ratio.max() < 1e-4


def test_streaming_gives_the_batch_windows_verdict_for_verdict() -> None:
    rng = np.random.default_rng(5)
    t = np.arange(int(0.8 * FS)) / FS
    growing = np.sin(2 * np.pi * 931.0 * t) * np.exp(8.0 * (t - 0.8))
    signal = _tones([(333.3, 1.0), (666.7, 0.3)], 0.8) + growing + 0.01 * rng.normal(size=t.size)
    settings = DetectorSettings(FS, 10000.0, 2, window_s=0.1, hop_s=0.0125)
    batch = detect_chatter(signal, settings)
    stream = StreamingChatterDetector(settings)
    verdicts = []
    cycle = 250  # 12.5 ms at 20 kHz: one twin cycle per push
    for start in range(0, signal.size, cycle):
        verdicts += stream.push(signal[start : start + cycle])
        if len(verdicts):
            assert stream.latest == verdicts[-1]
    assert len(verdicts) == len(batch) == 57
    for index, verdict in enumerate(verdicts):
        assert verdict == batch.window(index)
    # Irregular chunks (empty, single samples, longer than a window) change nothing.
    other = StreamingChatterDetector(settings)
    cuts = np.sort(rng.choice(signal.size, 40, replace=False))
    pieces = np.split(signal, cuts)
    again = [v for piece in [*pieces, signal[:0]] for v in other.push(piece)]
    assert again == verdicts and other.samples_received == signal.size
    assert not batch.chatter[0] and batch.chatter[-1]


# Speeds where the chatter frequency lies well off the tooth-passing harmonics (more than
# 50 Hz): a component within a notch of a harmonic cannot be told from it (docs/chatter.md).
CASES = [
    ("1-DOF slot", ONE_DOF, SLOT, 10000.0),
    ("1-DOF slot", ONE_DOF, SLOT, 17000.0),
    ("2-DOF a/D=0.05", TWO_DOF, AD005, 10000.0),
    ("2-DOF a/D=0.05", TWO_DOF, AD005, 17000.0),
]


@pytest.mark.parametrize(("label", "tool", "process", "rpm"), CASES)
@pytest.mark.parametrize("factor", [0.75, 1.25])
def test_detection_on_simulated_cuts_matches_the_semi_discretization(
    label: str, tool: ToolDynamics, process: MillingProcess, rpm: float, factor: float
) -> None:
    speed = rpm * RPM
    lobes = sdm_lobes(tool, process, [speed], max_depth_m=0.01, steps=40)
    depth = factor * float(lobes.critical_depth_m[0])
    unstable = factor > 1.0  # SDM's verdict at this depth
    radius = np.abs(_sdm.SdmModel.build(tool, process, 40).multipliers(speed, depth, None))
    assert (radius.max() > 1.0) == unstable
    sim = simulate_milling(
        tool, process, spindle_rad_s=speed, depth_m=depth, feed_per_tooth_m=1e-4,
        duration_s=0.6,
    )  # fmt: skip
    fs = 1.0 / sim.time_s[1]
    settings = DetectorSettings(fs, rpm, 2, window_s=0.1, hop_s=0.05)
    found = detect_chatter(sim.acceleration_m_s2[:, 0], settings)
    settled = found.start_s >= 0.3  # the entry transient has died away (stable cuts)
    assert settled.sum() >= 4
    assert np.all(found.chatter[settled] == unstable), found.energy_ratio
    if not unstable:
        assert found.energy_ratio[settled].max() < 0.05
        return
    # Chatter frequency: the SDM's dominant multiplier at this depth, and the time domain's
    # own spectrum of its steady half, within the spectral resolution.
    sdm_hz, _ = _sdm.SdmModel.build(tool, process, 40).chatter(speed, depth, None)
    verdict = sim.chatter(quantity="acceleration")
    assert verdict.chatter
    resolution = settings.resolution_hz
    first = int(np.flatnonzero(found.chatter)[0])
    assert found.chatter_frequency_hz[first] == pytest.approx(sdm_hz, abs=resolution)
    late = found.chatter_frequency_hz[settled]
    assert np.all(np.abs(late - verdict.frequency_hz) <= resolution)


def test_settings_and_signals_are_checked() -> None:
    with pytest.raises(ConfigError, match="teeth"):
        DetectorSettings(FS, 6000.0, 0, window_s=0.1)
    with pytest.raises(ConfigError, match="threshold"):
        DetectorSettings(FS, 6000.0, 2, window_s=0.1, threshold=1.5)
    with pytest.raises(ConfigError, match="at least 16 samples"):
        DetectorSettings(FS, 6000.0, 2, window_s=1e-4)
    with pytest.raises(ConfigError, match="spindle_rpm"):
        DetectorSettings(FS, -1.0, 2, window_s=0.1)
    settings = DetectorSettings(FS, 6000.0, 2, window_s=0.1)
    with pytest.raises(DataError, match="shorter than one window"):
        detect_chatter(np.zeros(100), settings)
    with pytest.raises(DataError, match="finite"):
        detect_chatter(np.full(4000, np.nan), settings)
    with pytest.raises(DataError, match="finite"):
        StreamingChatterDetector(settings).push(np.ones((3, 2)))
