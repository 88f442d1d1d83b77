"""The outputs of a dexel study: results.csv, summary.json, report.md and the heat maps.

``summary.json`` holds the study's settings, the optimum of Heide 2025's score with its metrics
(and its runs per feed), our figures at the paper's optimum (10 /mm, 12.5 ms) when the study
has that setting, the best setting that removes the volume of a continuous cut within
:data:`VOLUME_BOUND_PCT` at every feed, the paper's figures, and the T* fit. ``report.md`` puts
them side by side. Units: mm, mm/min, s, percent (names say so).
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from cnctwin import finite_json
from cnctwin.errors import CnctwinError
from cnctwin.studies.dexel_study import PAPER, DexelStudy, RunResult
from cnctwin.studies.plots import write_heatmaps
from cnctwin.studies.scaling import fit_t_star, t_star
from cnctwin.studies.score import WEIGHTS, Setting, optimum, settings

__all__ = ["RESULT_COLUMNS", "VOLUME_BOUND_PCT", "study_summary", "write_outputs"]

#: Bound on the removed-volume deviation of the second optimum reported, percent.
VOLUME_BOUND_PCT = 1.0

#: Columns of results.csv (units in the names; t_star in 1/(mm^2 s)).
RESULT_COLUMNS = (
    "density_per_mm",
    "cycle_s",
    "feed_mm_min",
    "step_mm",
    "t_star",
    "delta_ae_mm",
    "delta_ae_max_mm",
    "feed_deviation_pct",
    "volume_deviation_pct",
    "runtime_s",
    "cpu_s",
    "process_s",
    "steps",
    "steady_steps",
)


def _row(result: RunResult) -> list[float | int]:
    spec = result.spec
    return [
        spec.density_per_mm,
        spec.cycle_s,
        spec.feed_mm_min,
        spec.feed_mm_min / 60.0 * spec.cycle_s,
        float(t_star(spec.density_per_mm, spec.cycle_s)),
        result.delta_ae_mm,
        result.delta_ae_max_mm,
        result.feed_deviation_pct,
        result.volume_deviation_pct,
        result.runtime_s,
        result.cpu_s,
        result.process_s,
        result.steps,
        result.steady_steps,
    ]


def _setting(setting: Setting, results: Sequence[RunResult]) -> dict[str, Any]:
    """A setting's figures and its runs per feed."""
    runs = [
        r
        for r in results
        if (r.spec.density_per_mm, r.spec.cycle_s) == (setting.density_per_mm, setting.cycle_s)
    ]
    return {
        **asdict(setting),
        "cycle_ms": setting.cycle_s * 1e3,
        "t_star": float(t_star(setting.density_per_mm, setting.cycle_s)),
        "realtime_factor": setting.process_s / setting.cpu_s if setting.cpu_s > 0 else None,
        "runs": [
            {
                "feed_mm_min": r.spec.feed_mm_min,
                "delta_ae_mm": r.delta_ae_mm,
                "feed_deviation_pct": r.feed_deviation_pct,
                "volume_deviation_pct": r.volume_deviation_pct,
                "cpu_s": r.cpu_s,
                "process_s": r.process_s,
            }
            for r in sorted(runs, key=lambda r: r.spec.feed_mm_min)
        ],
    }


def study_summary(
    study: DexelStudy, results: Sequence[RunResult], *, workers: int, wall_s: float
) -> tuple[dict[str, Any], list[Setting], Setting]:
    """The summary object, the scored settings and the optimum.

    Parameters
    ----------
    study
        The study.
    results
        Its runs (:func:`cnctwin.studies.run_study`).
    workers
        Processes the runs used.
    wall_s
        Wall time of the whole study, s.
    """
    scored = settings(results)
    best = optimum(scored)
    by_key = {(s.density_per_mm, s.cycle_s): s for s in scored}
    at_paper = by_key.get((PAPER["density_per_mm"], PAPER["cycle_s"]))
    try:
        bounded: dict[str, Any] | None = _setting(optimum(scored, VOLUME_BOUND_PCT), results)
    except CnctwinError:
        bounded = None
    fit = None
    if len(study.densities_per_mm) > 1 and len(study.cycles_s) > 1 and len(scored) >= 3:
        fit = asdict(
            fit_t_star(
                [s.density_per_mm for s in scored],
                [s.cycle_s for s in scored],
                [s.cpu_s for s in scored],
            )
        )
    cut = study.cut
    summary: dict[str, Any] = {
        "study": {
            "runs": len(results),
            "densities_per_mm": list(study.densities_per_mm),
            "cycles_s": list(study.cycles_s),
            "feeds_mm_min": list(study.feeds_mm_min),
            "cut": {**asdict(cut), "pass_length_mm": cut.pass_length_mm},
            "process_per_setting_s": best.process_s,
            "workers": workers,
            "wall_s": wall_s,
            "cpu_s": sum(r.cpu_s for r in results),
        },
        "weights": dict(zip(("ae", "vf", "runtime"), WEIGHTS, strict=True)),
        "optimum": _setting(best, results),
        "at_paper_optimum": _setting(at_paper, results) if at_paper is not None else None,
        "volume_bound_pct": VOLUME_BOUND_PCT,
        "optimum_within_volume_bound": bounded,
        "paper": dict(PAPER),
        "t_star_fit": fit,
    }
    return summary, scored, best


def _fmt(value: Any, spec: str) -> str:
    return "–" if value is None else format(value, spec)


def _report(summary: dict[str, Any]) -> str:
    """report.md: our figures next to Heide 2025's."""
    study, paper, best = summary["study"], summary["paper"], summary["optimum"]
    ours_at = summary["at_paper_optimum"] or {}
    bounded = summary["optimum_within_volume_bound"] or {}
    rows = (
        ("dexel density [1/mm]", "density_per_mm", ".3g"),
        ("cycle time [ms]", "cycle_ms", ".4g"),
        ("mean abs delta ae [mm]", "delta_ae_mm", ".3g"),
        ("feed deviation [%]", "feed_deviation_pct", ".2g"),
        ("removed volume dev., worst feed [%]", "volume_deviation_pct", ".3g"),
        ("runtime [s] (ours: CPU)", "cpu_s", ".3g"),
        ("process time [s]", "process_s", ".4g"),
        ("score S", "score", ".3f"),
    )
    paper_row = {
        **paper,
        "cycle_ms": paper["cycle_s"] * 1e3,
        "cpu_s": paper["runtime_s"],
        "volume_deviation_pct": None,
    }
    lines = [
        "# Dexel density x cycle time study (Heide 2025, Sec. 2.3)",
        "",
        f"{study['runs']} runs: densities {study['densities_per_mm']} /mm, cycle times "
        f"{[c * 1e3 for c in study['cycles_s']]} ms, feeds {study['feeds_mm_min']} mm/min; "
        f"side milling ae = {study['cut']['ae_mm']} mm, ap = {study['cut']['ap_mm']} mm with a "
        f"{study['cut']['diameter_mm']} mm flat end mill, passes of "
        f"{study['cut']['pass_length_mm']:.1f} mm ({study['process_per_setting_s']:.1f} s of "
        f"process per setting). {study['workers']} worker process(es), "
        f"{study['wall_s']:.1f} s wall, {study['cpu_s']:.1f} s CPU in all.",
        "",
        f"| | Heide 2025 optimum | our optimum | ours at 10 /mm, 12.5 ms "
        f"| ours, best within {VOLUME_BOUND_PCT:g} % volume |",
        "|---|---:|---:|---:|---:|",
    ]
    for label, key, spec in rows:
        lines.append(
            f"| {label} | {_fmt(paper_row.get(key), spec)} | {_fmt(best.get(key), spec)} "
            f"| {_fmt(ours_at.get(key), spec)} | {_fmt(bounded.get(key), spec)} |"
        )
    lines += [
        "",
        "Scores are relative to the settings of their own study (min-max normalisation, Eq. 2);"
        " runtimes come from different machines (Heide 2025: IFW CutS, wall time; ours: CPU "
        "time of the simulation loop of one process).",
        "",
    ]
    fit = summary["t_star_fit"]
    if fit is not None:
        lines += [
            "## Runtime against T* = rho^2 / t_cycle",
            "",
            f"CPU time per setting ~ (T*)^{fit['exponent']:.3f} (R^2 = {fit['r2']:.3f}, "
            f"{fit['points']} settings); freely, ~ rho^{fit['density_exponent']:.2f} "
            f"t_cycle^{fit['cycle_exponent']:.2f} (R^2 = {fit['r2_free']:.3f}). "
            "T* holds when the exponent is 1 (rho^2 t_cycle^-1).",
            "",
        ]
    lines += [
        "## Per feed at our optimum",
        "",
        "| feed [mm/min] | delta ae [mm] | feed deviation [%] | volume deviation [%] | CPU [s] |",
        "|---:|---:|---:|---:|---:|",
    ]
    for run in best["runs"]:
        lines.append(
            f"| {run['feed_mm_min']:g} | {run['delta_ae_mm']:.3g} | "
            f"{run['feed_deviation_pct']:.2g} | {run['volume_deviation_pct']:.3g} | "
            f"{run['cpu_s']:.3g} |"
        )
    lines += [
        "",
        "Heat maps: delta_ae.png, feed_deviation.png, volume_deviation.png (per feed), "
        "runtime.png, score.png (per setting, over all feeds). Metrics: docs/study.md.",
        "",
    ]
    return "\n".join(lines)


def write_outputs(
    out: Path, study: DexelStudy, results: Sequence[RunResult], *, workers: int, wall_s: float
) -> dict[str, Any]:
    """Write results.csv, the heat maps, summary.json and report.md into ``out`` (created).

    Returns
    -------
    dict
        The summary (as in summary.json), with ``files``: the paths written.
    """
    out.mkdir(parents=True, exist_ok=True)
    summary, scored, best = study_summary(study, results, workers=workers, wall_s=wall_s)
    csv_path = out / "results.csv"
    with csv_path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(RESULT_COLUMNS)
        for result in results:
            writer.writerow([format(v, ".6g") for v in _row(result)])
    plots = write_heatmaps(out, study, results, scored, best)
    report_path = out / "report.md"
    report_path.write_text(_report(summary))
    summary_path = out / "summary.json"
    summary["files"] = [str(p) for p in (csv_path, *plots, report_path, summary_path)]
    summary_path.write_text(finite_json.dumps(summary, indent=2) + "\n")
    return summary
