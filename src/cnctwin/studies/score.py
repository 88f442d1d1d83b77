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

``S`` sees neither the material the discrete positions leave uncut nor whether the simulation
keeps up with the machine, so its least value can be a setting no twin could use (5 /mm at
200 ms leaves 59 % of the quick study's 2880 mm/min cut standing). :func:`constrained_optimum`
therefore picks the least ``S`` among the settings that meet :class:`Constraints` (removed
volume within a tolerance of a continuous cut's at every feed, real-time factor >= 1) and
says which constraint excluded each of the others.
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
    "Choice",
    "Constraints",
    "Setting",
    "constrained_optimum",
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

    @property
    def realtime_factor(self) -> float:
        """Process time over CPU time of the setting's runs (> 1: faster than the machine)."""
        return self.process_s / self.cpu_s if self.cpu_s > 0.0 else math.inf


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


def optimum(scored: Sequence[Setting]) -> Setting:
    """The setting of least score; among equal scores the cheapest ``rho^2 / t_cycle``.

    Raises
    ------
    ConfigError
        On no settings.
    """
    if not scored:
        raise ConfigError("no settings to choose from; run the study first")
    return min(scored, key=lambda s: (s.score, s.density_per_mm**2 / s.cycle_s))


#: Largest least real-time factor a constraint may ask for (process time / CPU time).
MAX_REALTIME_FACTOR = 1e6


@dataclass(frozen=True, slots=True)
class Constraints:
    """What a setting must meet to be chosen.

    Attributes
    ----------
    max_volume_deviation_pct
        Tolerance on the removed volume against a continuous cut's, at the setting's worst
        feed (:attr:`Setting.volume_deviation_pct`), percent, 0 to 100.
    min_realtime_factor
        Least process time over CPU time of the setting's runs (:attr:`Setting.realtime_factor`),
        > 0 and at most :data:`MAX_REALTIME_FACTOR`; 1: the simulation keeps up with the machine.
    """

    max_volume_deviation_pct: float = 1.0
    min_realtime_factor: float = 1.0

    def __post_init__(self) -> None:
        if not (
            math.isfinite(self.max_volume_deviation_pct)
            and 0 <= self.max_volume_deviation_pct <= 100
        ):
            raise ConfigError(
                f"volume tolerance {self.max_volume_deviation_pct!r} %; "
                "give a tolerance from 0 to 100 %"
            )
        if not (
            math.isfinite(self.min_realtime_factor)
            and 0 < self.min_realtime_factor <= MAX_REALTIME_FACTOR
        ):
            raise ConfigError(
                f"real-time factor {self.min_realtime_factor!r}; give a least factor > 0 "
                f"and <= {MAX_REALTIME_FACTOR:g}"
            )

    def violations(self, setting: Setting) -> tuple[str, ...]:
        """Why ``setting`` fails the constraints, one phrase each (empty: it meets them)."""
        reasons = []
        if setting.volume_deviation_pct > self.max_volume_deviation_pct:
            reasons.append(
                f"removed volume off by {setting.volume_deviation_pct:.3g} % at its worst feed "
                f"(material left uncut), tolerance {self.max_volume_deviation_pct:g} %"
            )
        if setting.realtime_factor < self.min_realtime_factor:
            reasons.append(
                f"real-time factor {setting.realtime_factor:.3g} < {self.min_realtime_factor:g}"
            )
        return tuple(reasons)


@dataclass(frozen=True, slots=True)
class Choice:
    """The constrained optimum of a study and what the constraints excluded.

    Attributes
    ----------
    optimum
        Least score among the settings that meet the constraints; None when none does.
    score_optimum
        Least score of all settings (Heide 2025's optimum, constraints ignored).
    excluded
        Each setting that fails the constraints with its reasons, by score.
    constraints
        The constraints applied.
    """

    optimum: Setting | None
    score_optimum: Setting
    excluded: tuple[tuple[Setting, tuple[str, ...]], ...]
    constraints: Constraints


def constrained_optimum(
    scored: Sequence[Setting], constraints: Constraints | None = None
) -> Choice:
    """The least score among the settings that meet ``constraints`` (default
    :class:`Constraints`), with the excluded settings and their reasons.

    Raises
    ------
    ConfigError
        On no settings.
    """
    limits = Constraints() if constraints is None else constraints
    reasons = {(s.density_per_mm, s.cycle_s): limits.violations(s) for s in scored}
    feasible = [s for s in scored if not reasons[(s.density_per_mm, s.cycle_s)]]
    excluded = tuple(
        (s, reasons[(s.density_per_mm, s.cycle_s)])
        for s in sorted(scored, key=lambda s: s.score)
        if reasons[(s.density_per_mm, s.cycle_s)]
    )
    return Choice(optimum(feasible) if feasible else None, optimum(scored), excluded, limits)
