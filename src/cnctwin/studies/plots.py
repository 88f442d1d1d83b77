"""Heat maps of a dexel study over dexel density x cycle time (after Heide 2025, Fig. 8-10).

Every map has the cycle time on the x axis and the density on the y axis, one cell per run
(measured values, not interpolated), the value printed in the cell. Error maps go from blue
(small) to red (large), runtime maps from dark (fast) to yellow (slow), as in the paper.

- ``delta_ae.png``: mean |delta ae| (drawn in micrometres), one panel per feed (Fig. 8);
- ``feed_deviation.png``: mean feed deviation (%), one panel per feed (Fig. 9);
- ``volume_deviation.png``: removed volume against a continuous cut (%), one panel per feed;
- ``runtime.png``: CPU time of each setting's runs together (s) and ``T* = rho^2 / t_cycle``
  (Fig. 10a and c);
- ``score.png``: Heide 2025's score S (Eq. 3) per setting, aggregated over the feeds, the
  optimum framed (solid) and Heide 2025's optimum, 10 /mm and 12.5 ms, framed (dashed).

Colour scales of the error and runtime maps are logarithmic (the values span decades); values
below a map's floor (for the errors: their resolution, see :mod:`cnctwin.studies.score`) are
drawn at the floor, with their value printed. The feed map's scale reaches at least 1 %.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import LogNorm, Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from cnctwin.studies.dexel_study import PAPER, DexelStudy, RunResult
from cnctwin.studies.scaling import t_star
from cnctwin.studies.score import AE_RESOLUTION_MM, FEED_RESOLUTION_PCT, Setting

__all__ = ["write_heatmaps"]

_PANEL_IN = (3.6, 2.8)


def _grid(study: DexelStudy, value: Callable[[float, float], float]) -> np.ndarray:
    """(densities, cycles) array of ``value(density, cycle)``."""
    return np.array(
        [[value(rho, cycle) for cycle in study.cycles_s] for rho in study.densities_per_mm]
    )


def _heatmap(
    ax: Axes,
    values: np.ndarray,
    study: DexelStudy,
    title: str,
    *,
    cmap: str,
    floor: float | None,
    fmt: str,
    top: float = 0.0,
) -> None:
    """One map: density (rows) x cycle time (columns), log colours from ``floor``.

    With a ``floor`` the colour scale is logarithmic and reaches at least ``top``.
    """
    shown = np.maximum(values, floor) if floor is not None else values
    norm: Normalize
    if floor is not None:
        low = float(shown.min())
        norm = LogNorm(vmin=low, vmax=max(float(shown.max()), low * 10, top))
    else:
        norm = Normalize(vmin=float(shown.min()), vmax=float(shown.max()))
    image = ax.imshow(shown, origin="lower", aspect="auto", cmap=cmap, norm=norm)
    ax.figure.colorbar(image, ax=ax, shrink=0.9)  # type: ignore[union-attr]
    ax.set_xticks(range(len(study.cycles_s)), [f"{c * 1e3:g}" for c in study.cycles_s], fontsize=7)
    ax.set_yticks(range(len(study.densities_per_mm)), [f"{d:g}" for d in study.densities_per_mm])
    ax.set_xlabel("cycle time [ms]")
    ax.set_ylabel("dexel density [1/mm]")
    ax.set_title(title, fontsize=9)
    for (i, j), v in np.ndenumerate(values):
        ax.text(j, i, format(v, fmt), ha="center", va="center", fontsize=5, color="black")


def _per_feed(
    path: Path,
    study: DexelStudy,
    runs: dict[tuple[float, float, float], RunResult],
    metric: Callable[[RunResult], float],
    label: str,
    floor: float,
    fmt: str,
    top: float = 0.0,
) -> Path:
    """One panel per feed of ``metric`` (colour scale from ``floor`` to at least ``top``)."""
    n = len(study.feeds_mm_min)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig = Figure(figsize=(_PANEL_IN[0] * cols, _PANEL_IN[1] * rows), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False)
    for k, feed in enumerate(study.feeds_mm_min):
        values = np.array(
            [
                [metric(runs[(rho, cycle, feed)]) for cycle in study.cycles_s]
                for rho in study.densities_per_mm
            ]
        )
        _heatmap(
            axes.flat[k],
            values,
            study,
            f"{label}, vf = {feed:g} mm/min",
            cmap="coolwarm",
            floor=floor,
            fmt=fmt,
            top=top,
        )
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.savefig(path, dpi=130)
    return path


def write_heatmaps(
    out: Path,
    study: DexelStudy,
    results: Sequence[RunResult],
    scored: Sequence[Setting],
    best: Setting,
) -> list[Path]:
    """Write the heat maps (module notes) into ``out``; return their paths.

    Parameters
    ----------
    out
        An existing folder.
    study
        The study the results belong to.
    results
        One result per run of the study.
    scored
        The scored settings (:func:`cnctwin.studies.settings`).
    best
        The setting to frame on the score map.
    """
    runs = {(r.spec.density_per_mm, r.spec.cycle_s, r.spec.feed_mm_min): r for r in results}
    by_setting = {(s.density_per_mm, s.cycle_s): s for s in scored}
    paths = [
        _per_feed(
            out / "delta_ae.png",
            study,
            runs,
            lambda r: r.delta_ae_mm * 1e3,
            "|delta ae| [um]",
            AE_RESOLUTION_MM * 1e3,
            ".2g",
        ),
        _per_feed(
            out / "feed_deviation.png",
            study,
            runs,
            lambda r: r.feed_deviation_pct,
            "feed deviation [%]",
            FEED_RESOLUTION_PCT,
            ".0e",
            top=1.0,
        ),
        _per_feed(
            out / "volume_deviation.png",
            study,
            runs,
            lambda r: abs(r.volume_deviation_pct),
            "|volume deviation| [%]",
            1e-3,
            ".2g",
        ),
    ]
    fig = Figure(figsize=(_PANEL_IN[0] * 2, _PANEL_IN[1]), layout="constrained")
    left, right = fig.subplots(1, 2)
    cpu = _grid(study, lambda rho, cycle: by_setting[(rho, cycle)].cpu_s)
    process = by_setting[(best.density_per_mm, best.cycle_s)].process_s
    _heatmap(
        left,
        cpu,
        study,
        f"CPU time [s] for {process:.0f} s of process",
        cmap="viridis",
        floor=float(cpu[cpu > 0].min()) if np.any(cpu > 0) else 1e-9,
        fmt=".3g",
    )
    effort = _grid(study, lambda rho, cycle: float(t_star(rho, cycle)))
    _heatmap(
        right,
        effort,
        study,
        "T* = rho^2 / t_cycle [1/(mm^2 s)]",
        cmap="viridis",
        floor=float(effort.min()),
        fmt=".0f",
    )
    paths.append(out / "runtime.png")
    fig.savefig(paths[-1], dpi=130)
    fig = Figure(figsize=(_PANEL_IN[0] * 1.3, _PANEL_IN[1] * 1.2), layout="constrained")
    ax = fig.subplots()
    score = _grid(study, lambda rho, cycle: by_setting[(rho, cycle)].score)
    _heatmap(
        ax,
        score,
        study,
        "score S = 0.4 ae* + 0.4 vf* + 0.2 T*",
        cmap="coolwarm",
        floor=None,
        fmt=".3f",
    )
    frames = [((best.density_per_mm, best.cycle_s), "solid")]
    frames.append(((PAPER["density_per_mm"], PAPER["cycle_s"]), "dashed"))
    for (rho, cycle), style in frames:
        if rho in study.densities_per_mm and cycle in study.cycles_s:
            i, j = study.densities_per_mm.index(rho), study.cycles_s.index(cycle)
            ax.add_patch(
                Rectangle(
                    (j - 0.5, i - 0.5),
                    1,
                    1,
                    fill=False,
                    edgecolor="black",
                    linewidth=2,
                    linestyle=style,
                )
            )
    paths.append(out / "score.png")
    fig.savefig(paths[-1], dpi=130)
    return paths
