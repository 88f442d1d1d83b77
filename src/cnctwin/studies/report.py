"""The outputs of a dexel study: results.csv, summary.json, report.md and the heat maps.

``summary.json`` holds the study's settings, the constraints, the constrained optimum (the least
Heide 2025 score among the settings that meet them, :func:`~cnctwin.studies.constrained_optimum`)
with its metrics and its runs per feed, the least score of all, every excluded setting with the
constraint that excluded it, our figures at the paper's optimum (10 /mm, 12.5 ms) when the
study has that setting, the paper's figures, and the T* fit. ``report.md`` leads with the
constrained optimum and puts the others beside it. Units: mm, mm/min, s, percent (names say
so).
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from cnctwin import finite_json
from cnctwin.studies.dexel_study import PAPER, DexelStudy, RunResult
from cnctwin.studies.plots import write_heatmaps
from cnctwin.studies.scaling import fit_t_star, t_star
from cnctwin.studies.score import WEIGHTS, Constraints, Setting, constrained_optimum, settings

__all__ = ["RESULT_COLUMNS", "study_summary", "summary_lead", "write_outputs"]

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
        "realtime_factor": setting.realtime_factor,
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
    study: DexelStudy,
    results: Sequence[RunResult],
    *,
    workers: int,
    wall_s: float,
    constraints: Constraints | None = None,
) -> tuple[dict[str, Any], list[Setting], Setting]:
    """The summary object, the scored settings and the setting to frame on the score map (the
    constrained optimum, else the least score).

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
    constraints
        What the optimum must meet (default :class:`~cnctwin.studies.Constraints`).
    """
    scored = settings(results)
    choice = constrained_optimum(scored, constraints)
    by_key = {(s.density_per_mm, s.cycle_s): s for s in scored}
    at_paper = by_key.get((PAPER["density_per_mm"], PAPER["cycle_s"]))
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
            "process_per_setting_s": choice.score_optimum.process_s,
            "workers": workers,
            "wall_s": wall_s,
            "cpu_s": sum(r.cpu_s for r in results),
        },
        "weights": dict(zip(("ae", "vf", "runtime"), WEIGHTS, strict=True)),
        "constraints": asdict(choice.constraints),
        "optimum": _setting(choice.optimum, results) if choice.optimum is not None else None,
        "score_optimum": _setting(choice.score_optimum, results),
        "excluded": [
            {
                "density_per_mm": s.density_per_mm,
                "cycle_ms": s.cycle_s * 1e3,
                "score": s.score,
                "volume_deviation_pct": s.volume_deviation_pct,
                "realtime_factor": s.realtime_factor,
                "reasons": list(reasons),
            }
            for s, reasons in choice.excluded
        ],
        "at_paper_optimum": _setting(at_paper, results) if at_paper is not None else None,
        "paper": dict(PAPER),
        "t_star_fit": fit,
    }
    return summary, scored, choice.optimum or choice.score_optimum


def _constraints_text(constraints: dict[str, float]) -> str:
    """The constraints of a summary in words."""
    return (
        f"removed volume within {constraints['max_volume_deviation_pct']:g} % of a continuous "
        f"cut's at every feed, real-time factor >= {constraints['min_realtime_factor']:g}"
    )


def summary_lead(summary: dict[str, Any]) -> list[str]:
    """The report's opening: the constrained optimum, and why the least score was excluded."""
    best, top = summary["optimum"], summary["score_optimum"]
    rule = _constraints_text(summary["constraints"])
    if best is None:
        text = [f"No setting meets the constraints ({rule})."]
    else:
        text = [
            f"Optimum: {best['density_per_mm']:g} /mm, {best['cycle_ms']:g} ms "
            f"(S = {best['score']:.3f}): the least score among the settings that meet the "
            f"constraints ({rule})."
        ]
    excluded = {(e["density_per_mm"], e["cycle_ms"]): e for e in summary["excluded"]}
    key = (top["density_per_mm"], top["cycle_ms"])
    if key in excluded:
        text.append(
            f"The least score of all, {key[0]:g} /mm, {key[1]:g} ms (S = {top['score']:.3f}), "
            f"is excluded: {'; '.join(excluded[key]['reasons'])}."
        )
    study = summary["study"]
    total = len(study["densities_per_mm"]) * len(study["cycles_s"])
    text.append(f"{len(excluded)} of {total} settings excluded (table below).")
    return text


def _fmt(value: Any, spec: str) -> str:
    return "–" if value is None else format(value, spec)


def _report(summary: dict[str, Any]) -> str:
    """report.md: our figures next to Heide 2025's."""
    study, paper = summary["study"], summary["paper"]
    best = summary["optimum"] or {}
    top = summary["score_optimum"]
    ours_at = summary["at_paper_optimum"] or {}
    rows = (
        ("dexel density [1/mm]", "density_per_mm", ".3g"),
        ("cycle time [ms]", "cycle_ms", ".4g"),
        ("mean abs delta ae [mm]", "delta_ae_mm", ".3g"),
        ("feed deviation [%]", "feed_deviation_pct", ".2g"),
        ("removed volume dev., worst feed [%]", "volume_deviation_pct", ".3g"),
        ("runtime [s] (ours: CPU)", "cpu_s", ".3g"),
        ("process time [s]", "process_s", ".4g"),
        ("real-time factor", "realtime_factor", ".3g"),
        ("score S", "score", ".3f"),
    )
    paper_row = {
        **paper,
        "cycle_ms": paper["cycle_s"] * 1e3,
        "cpu_s": paper["runtime_s"],
        "volume_deviation_pct": None,
        "realtime_factor": paper["process_s"] / paper["runtime_s"],
    }
    lines = [
        "# Dexel density x cycle time study (Heide 2025, Sec. 2.3)",
        "",
        *summary_lead(summary),
        "",
        f"{study['runs']} runs: densities {study['densities_per_mm']} /mm, cycle times "
        f"{[c * 1e3 for c in study['cycles_s']]} ms, feeds {study['feeds_mm_min']} mm/min; "
        f"side milling ae = {study['cut']['ae_mm']} mm, ap = {study['cut']['ap_mm']} mm with a "
        f"{study['cut']['diameter_mm']} mm flat end mill, passes of "
        f"{study['cut']['pass_length_mm']:.1f} mm ({study['process_per_setting_s']:.1f} s of "
        f"process per setting). {study['workers']} worker process(es), "
        f"{study['wall_s']:.1f} s wall, {study['cpu_s']:.1f} s CPU in all.",
        "",
        "| | Heide 2025 optimum | our optimum (constrained) | our least S (unconstrained) "
        "| ours at 10 /mm, 12.5 ms |",
        "|---|---:|---:|---:|---:|",
    ]
    for label, key, spec in rows:
        lines.append(
            f"| {label} | {_fmt(paper_row.get(key), spec)} | {_fmt(best.get(key), spec)} "
            f"| {_fmt(top.get(key), spec)} | {_fmt(ours_at.get(key), spec)} |"
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
    if summary["excluded"]:
        lines += [
            "## Excluded settings",
            "",
            "| density [1/mm] | cycle time [ms] | score S | excluded because |",
            "|---:|---:|---:|---|",
        ]
        lines += [
            f"| {e['density_per_mm']:g} | {e['cycle_ms']:g} | {e['score']:.3f} "
            f"| {'; '.join(e['reasons'])} |"
            for e in summary["excluded"]
        ]
        lines.append("")
    lines += [
        "## Per feed at our optimum",
        "",
        "| feed [mm/min] | delta ae [mm] | feed deviation [%] | volume deviation [%] | CPU [s] |",
        "|---:|---:|---:|---:|---:|",
    ]
    for run in best.get("runs", []):
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
    out: Path,
    study: DexelStudy,
    results: Sequence[RunResult],
    *,
    workers: int,
    wall_s: float,
    constraints: Constraints | None = None,
) -> dict[str, Any]:
    """Write results.csv, the heat maps, summary.json and report.md into ``out`` (created);
    ``constraints`` as in :func:`study_summary`.

    Returns
    -------
    dict
        The summary (as in summary.json), with ``files``: the paths written.
    """
    out.mkdir(parents=True, exist_ok=True)
    summary, scored, best = study_summary(
        study, results, workers=workers, wall_s=wall_s, constraints=constraints
    )
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
