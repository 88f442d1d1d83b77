"""Torque and material-removal series for the wear EKF: synthetic sessions and runs.

A series is what the filter needs per sample: time (s), measured spindle torque (N m, ``nan``
for a missed sample), material removed during the sample (mm^3), optionally the torque the
model expects without wear (N m) and the true wear (mm) when it is known.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cnctwin.drives import spindle_preset
from cnctwin.errors import InputError
from cnctwin.memory import check_memory
from cnctwin.wear.ekf import EKFPreset, WearEKF, material_removed_mm3
from cnctwin.wear.stages import StageEvent, StageMonitor

__all__ = ["TorqueSeries", "EKFRun", "run_filter", "synthetic_session", "IDLE_TORQUE_NM"]

#: Idle (no-load) motor torque of Christiand 2024's spindle drive (preset
#: ``christiand2024`` of :mod:`cnctwin.drives`) holding 20,000 rpm, N m.
IDLE_TORQUE_NM = (
    spindle_preset("christiand2024").motor.steady_state(20_000.0 * 2.0 * math.pi / 60.0).torque
)


@dataclass(frozen=True, slots=True)
class TorqueSeries:
    """Samples for the wear EKF.

    Attributes
    ----------
    time_s
        Sample times, s.
    torque_nm
        Measured spindle torque, N m (``nan`` = missed sample).
    material_removed_mm3
        Material removed during each sample, mm^3.
    torque_base_nm
        Torque without wear per sample (idle friction plus cutting torque), N m.
    vb_mm
        True wear, mm, when known (else ``None``).
    """

    time_s: NDArray[np.float64]
    torque_nm: NDArray[np.float64]
    material_removed_mm3: NDArray[np.float64]
    torque_base_nm: NDArray[np.float64]
    vb_mm: NDArray[np.float64] | None = None


def synthetic_session(
    preset: EKFPreset,
    *,
    seed: int,
    rate_hz: float = 100.0,
    slots: int = 40,
    noise_nm: float = 5e-4,
    vb0_mm: float = 0.02,
) -> TorqueSeries:
    """A slot-milling session like Christiand 2024's experiment (section 5), with known wear.

    Slots 14 mm long cut at 4 mm/s and 20,000 rpm with a 1 mm two-flute tool, 0.01 mm deep;
    the wear follows the preset's logistic law from ``vb0_mm``; the measured torque is the
    idle torque plus the wear torque plus Gaussian noise of ``noise_nm`` (N m).

    Parameters
    ----------
    preset
        Wear law and wear-torque model that generate the truth.
    seed
        Random seed.
    rate_hz
        Samples per second.
    slots
        Number of slots cut.
    noise_nm
        Standard deviation of the torque noise, N m.
    vb0_mm
        Wear of the tool at the start, mm.

    Raises
    ------
    InputError
        If ``seed`` is not an integer >= 0, ``slots`` not an integer >= 1, ``rate_hz`` or
        ``vb0_mm`` not finite and > 0, ``noise_nm`` not finite and >= 0, or the session would
        not fit in memory.
    """
    if not (isinstance(seed, int) and seed >= 0):
        raise InputError(f"seed {seed!r}: give an integer >= 0")
    if not (isinstance(slots, int) and slots >= 1):
        raise InputError(f"slots {slots!r}: give an integer >= 1")
    for name, value, unit in (("rate_hz", rate_hz, "Hz"), ("vb0_mm", vb0_mm, "mm")):
        if not (math.isfinite(value) and value > 0.0):
            raise InputError(f"{name} {value!r}: give a finite value > 0 {unit}")
    if not (math.isfinite(noise_nm) and noise_nm >= 0.0):
        raise InputError(f"noise_nm {noise_nm!r}: give a finite value >= 0 N m")
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    rpm = 20_000.0
    feed_per_tooth_mm = 4.0 / (2.0 * rpm / 60.0)
    dmr = material_removed_mm3(feed_per_tooth_mm, 2, 1.0, 0.01, rpm / 60.0 * dt)
    per_slot = 14.0 / 4.0 * rate_hz
    check_memory(
        f"a synthetic session of {slots} slots at {rate_hz:g} Hz is {slots * per_slot:.3g} samples",
        slots * per_slot * 8.0 * 6,
        lambda fraction: f"use at most {slots * fraction:.3g} slots or a lower rate_hz",
    )
    n = slots * int(round(14.0 / 4.0 / dt))
    law = preset.propagation
    vb = np.empty(n)
    current = vb0_mm
    for k in range(n):
        current = law.propagate(current, dmr)
        vb[k] = current
    wear = np.array([preset.wear_torque.torque_nm(v) for v in vb])
    base = np.full(n, IDLE_TORQUE_NM)
    torque = base + wear + rng.normal(0.0, noise_nm, n)
    time = (np.arange(1, n + 1) * dt).astype(np.float64)
    return TorqueSeries(time, torque, np.full(n, dmr), base, vb)


@dataclass(frozen=True, slots=True)
class EKFRun:
    """The filter run over a series.

    Attributes
    ----------
    vb_mm, var_mm2
        Estimate and variance after each sample.
    prior_vb_mm, innovation_nm, gain_mm_per_nm
        Per-sample filter internals (``nan`` where no update happened).
    events
        Wear-stage notifications.
    """

    vb_mm: NDArray[np.float64]
    var_mm2: NDArray[np.float64]
    prior_vb_mm: NDArray[np.float64]
    innovation_nm: NDArray[np.float64]
    gain_mm_per_nm: NDArray[np.float64]
    events: list[StageEvent]


def run_filter(ekf: WearEKF, series: TorqueSeries, stages: StageMonitor | None = None) -> EKFRun:
    """Run the filter over a whole series, collecting its internals and stage events."""
    n = series.time_s.size
    out = np.empty((5, n))
    events: list[StageEvent] = []
    for k in range(n):
        step = ekf.step(
            float(series.material_removed_mm3[k]),
            float(series.torque_nm[k]),
            float(series.torque_base_nm[k]),
        )
        out[:, k] = (
            step.vb_mm,
            step.var_mm2,
            step.prior_vb_mm,
            step.innovation_nm,
            step.gain_mm_per_nm,
        )
        if stages is not None:
            events.extend(stages.update(float(series.time_s[k]), step.vb_mm))
    return EKFRun(out[0], out[1], out[2], out[3], out[4], events)
