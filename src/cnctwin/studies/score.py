"""The score of a dexel study setting: min-max normalisation and weighted sum (Heide 2025, Eq. 2-3).

Heide 2025 (Sec. 2.3) rates every setting (dexel density, cycle time) by three metrics, each the
lower the better: the mean deviation of the width of cut ``A_ae``, the relative feed error
``A_vf`` and the total runtime ``A_T``. Each is min-max normalised over all settings (Eq. 2; the
text extraction of the paper lost both minus signs)::

    A_i* = (A_i - min(A)) / (max(A) - min(A))

and the score is their weighted sum (Eq. 3)::

    S = w_ae A_ae* + w_vf A_vf* + w_T A_T*,    w = (0.4, 0.4, 0.2)

so ``S`` lies in [0, 1] and the optimum is the setting of least ``S``. Heide 2025 rates a
setting over all feeds (their optimum, 10 /mm and 12.5 ms, is one setting "for the investigated
feed range"); here ``A_ae`` and ``A_vf`` of a setting are the means over its feeds and ``A_T``
the sum of its runtimes (the six passes make the paper's one 328 s program).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import ConfigError
from cnctwin.studies.dexel_study import RunResult

__all__ = [
    "AE_RESOLUTION_MM",
    "FEED_RESOLUTION_PCT",
    "WEIGHTS",
    "Setting",
    "min_max",
    "optimum",
    "score",
    "settings",
]

#: Heide 2025, Sec. 2.3: weights of (width of cut, feed, runtime).
WEIGHTS = (0.4, 0.4, 0.2)
#: Resolution of the width of cut: dexel ends are float32 (about 5e-7 mm at 5 mm), mm.
AE_RESOLUTION_MM = 1e-6
#: Resolution of the feed error: the displacement per cycle in float64 rounds at ~1e-10 %, %.
FEED_RESOLUTION_PCT = 1e-6


def min_max(values: ArrayLike, resolution: float = 0.0) -> NDArray[np.float64]:
    """Min-max normalisation to [0, 1] (Heide 2025, Eq. 2).

    Parameters
    ----------
    values
        The metric over all settings (any unit), finite.
    resolution
        Spread (same unit) at or below which the values are indistinguishable: they then all
        normalise to 0 instead of to rounding noise divided by rounding noise. >= 0.

    Returns
    -------
    numpy.ndarray
        ``(A - min A) / (max A - min A)``, or zeros when ``max A - min A <= resolution``.

    Raises
    ------
    ConfigError
        On an empty or non-finite input, or a negative resolution.
    """
    a = np.asarray(values, dtype=np.float64)
    if a.size == 0 or not np.all(np.isfinite(a)):
        raise ConfigError(f"values={a.tolist()!r}; give at least one finite value to normalise")
    if not (math.isfinite(resolution) and resolution >= 0.0):
        raise ConfigError(f"resolution={resolution!r}; give a finite resolution >= 0")
    low = float(a.min())
    span = float(a.max()) - low
    if span <= resolution:
        return np.zeros_like(a)
    return (a - low) / span


def score(
    delta_ae_mm: ArrayLike,
    feed_deviation_pct: ArrayLike,
    runtime_s: ArrayLike,
    weights: Sequence[float] = WEIGHTS,
) -> NDArray[np.float64]:
    """The score ``S`` of every setting (Heide 2025, Eq. 3); lower is better.

    Parameters
    ----------
    delta_ae_mm
        Mean width-of-cut deviation of each setting, mm.
    feed_deviation_pct
        Mean feed deviation of each setting, percent.
    runtime_s
        Runtime of each setting, s.
    weights
        ``(w_ae, w_vf, w_T)``, each >= 0.

    Returns
    -------
    numpy.ndarray
        ``w_ae A_ae* + w_vf A_vf* + w_T A_T*`` with :func:`min_max` normalisation
        (resolutions :data:`AE_RESOLUTION_MM`, :data:`FEED_RESOLUTION_PCT`, 0 s).

    Raises
    ------
    ConfigError
        On arrays of different lengths or weights that are not three finite numbers >= 0.
    """
    w = np.asarray(weights, dtype=np.float64)
    if w.shape != (3,) or not np.all(np.isfinite(w)) or np.any(w < 0.0):
        raise ConfigError(f"weights={list(weights)!r}; give three finite weights >= 0")
    ae, vf, t = (
        np.asarray(v, dtype=np.float64) for v in (delta_ae_mm, feed_deviation_pct, runtime_s)
    )
    if not ae.shape == vf.shape == t.shape:
        raise ConfigError(
            f"metrics of {ae.size}, {vf.size} and {t.size} settings; "
            "give one value per setting of each"
        )
    return (
        w[0] * min_max(ae, AE_RESOLUTION_MM)
        + w[1] * min_max(vf, FEED_RESOLUTION_PCT)
        + w[2] * min_max(t)
    )


@dataclass(frozen=True, slots=True)
class Setting:
    """One setting (density, cycle time) over all its feeds, with its score.

    Attributes
    ----------
    density_per_mm, cycle_s
        The setting: 1/mm, s.
    delta_ae_mm
        Mean over the feeds of the runs' mean width-of-cut deviation, mm.
    feed_deviation_pct
        Mean over the feeds of the runs' mean feed deviation, percent.
    volume_deviation_pct
        Largest ``|volume_deviation_pct|`` of the setting's runs, percent: material the discrete
        positions leave (not part of the score).
    cpu_s, runtime_s
        CPU and wall time of the setting's runs together, s.
    process_s
        Process time of the setting's runs together, s.
    feeds
        Number of runs (feeds).
    score
        Heide 2025's ``S`` (Eq. 3) among the settings it was scored with; runtime = ``cpu_s``.
    """

    density_per_mm: float
    cycle_s: float
    delta_ae_mm: float
    feed_deviation_pct: float
    volume_deviation_pct: float
    cpu_s: float
    runtime_s: float
    process_s: float
    feeds: int
    score: float


def settings(results: Sequence[RunResult], weights: Sequence[float] = WEIGHTS) -> list[Setting]:
    """Group runs by (density, cycle time), aggregate over feeds and score them.

    Parameters
    ----------
    results
        The runs of a study (any order).
    weights
        ``(w_ae, w_vf, w_T)`` of :func:`score`.

    Returns
    -------
    list of Setting
        One per setting, ordered by density then cycle time, scored with the CPU time as
        runtime (the measure that parallel runs on a shared machine do not inflate).

    Raises
    ------
    ConfigError
        On no results, or settings that do not all have the same feeds.
    """
    groups: dict[tuple[float, float], list[RunResult]] = {}
    for result in results:
        key = (result.spec.density_per_mm, result.spec.cycle_s)
        groups.setdefault(key, []).append(result)
    if not groups:
        raise ConfigError("no runs to score; run the study first")
    feed_sets = {tuple(sorted(r.spec.feed_mm_min for r in group)) for group in groups.values()}
    if len(feed_sets) != 1:
        raise ConfigError(
            f"settings with different feeds {sorted(feed_sets)!r}; score complete studies only"
        )
    keys = sorted(groups)
    rows = [
        (
            float(np.mean([r.delta_ae_mm for r in groups[k]])),
            float(np.mean([r.feed_deviation_pct for r in groups[k]])),
            float(max(abs(r.volume_deviation_pct) for r in groups[k])),
            float(sum(r.cpu_s for r in groups[k])),
            float(sum(r.runtime_s for r in groups[k])),
            float(sum(r.process_s for r in groups[k])),
        )
        for k in keys
    ]
    ae, vf, _, cpu, _, _ = (np.array(column) for column in zip(*rows, strict=True))
    s = score(ae, vf, cpu, weights)
    return [
        Setting(k[0], k[1], *row, len(groups[k]), float(s_k))
        for k, row, s_k in zip(keys, rows, s, strict=True)
    ]


def optimum(scored: Sequence[Setting], max_volume_deviation_pct: float | None = None) -> Setting:
    """The setting of least score; among equal scores the cheapest ``rho^2 / t_cycle``.

    Parameters
    ----------
    scored
        Scored settings (:func:`settings`).
    max_volume_deviation_pct
        If given, choose only among settings whose removed volume is within this many percent
        of a continuous cut's at every feed (>= 0).

    Raises
    ------
    ConfigError
        On no settings, a negative bound, or no setting within the bound.
    """
    if not scored:
        raise ConfigError("no settings to choose from; run the study first")
    candidates = list(scored)
    if max_volume_deviation_pct is not None:
        if not (math.isfinite(max_volume_deviation_pct) and max_volume_deviation_pct >= 0.0):
            raise ConfigError(
                f"max_volume_deviation_pct={max_volume_deviation_pct!r}; give a bound >= 0 %"
            )
        candidates = [s for s in scored if s.volume_deviation_pct <= max_volume_deviation_pct]
        if not candidates:
            least = min(s.volume_deviation_pct for s in scored)
            raise ConfigError(
                f"no setting removes volume within {max_volume_deviation_pct} % of a continuous "
                f"cut (the closest is {least:.3g} %); give a looser bound"
            )
    return min(candidates, key=lambda s: (s.score, s.density_per_mm**2 / s.cycle_s))
