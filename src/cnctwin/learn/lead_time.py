"""Early warning of a run that will not finish, held out by run, with its lead time.

A classifier of windows says, at every sample of a run, how likely the run is to end in the
alarm class (the UMich ``machining_finalized = no``: the workpiece moved in the vise and the
operator stopped the program). An online rule turns its probabilities into one decision per
run: the first sample where their mean over the last ``smooth`` scored samples reaches a
threshold flags the run. The lead time is the time from that sample to the end of
machining (the run's last sample in an active phase), s.

:func:`lead_time_study` scores this honestly, leaving each run out in turn:

1. the classifier (logistic regression on standardised features, balanced class weights,
   fixed ``C``: nothing tuned) is fitted on the windows of every other run, every
   ``stride``-th active sample of the schema, labelled by its run's outcome;
2. the threshold is chosen on those other runs only: each of them is left out in turn
   inside them (an inner leave-one-run-out), its online score traced by a model that never
   saw it, and the threshold is the highest value that maximises Youden's J at the run
   level (alarm runs flagged / alarm runs minus other runs flagged / other runs; Youden
   1950, "Index for rating diagnostic tests", Cancer 3(1));
3. the rule runs on the held-out run, sample by sample, with that model and threshold.

The held-out run's samples and label enter nothing but step 3, and step 3 is causal (a
decision at time t reads samples up to t): ``tests/learn/test_lead_time.py`` checks both.
Features are those of the one feature path (:class:`~cnctwin.learn.FeaturePath`) and its
schema. Times in s; probabilities and scores in [0, 1].
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError
from cnctwin.learn.dataset import TIME_COLUMN, Run, key_of
from cnctwin.learn.features import FeaturePath
from cnctwin.learn.schema import FeatureSchema

__all__ = [
    "AlarmRule",
    "LeadTimeResult",
    "RunWindows",
    "choose_threshold",
    "first_flag",
    "hold_out_decision",
    "lead_time_study",
    "outcomes",
    "run_windows",
    "smoothed",
]

#: scikit-learn's solver for the logistic regression: Newton steps with a Cholesky solve,
#: exact and fast for the few features of a schema (the study fits a model per inner fold).
SOLVER = "newton-cholesky"


@dataclass(frozen=True)
class AlarmRule:
    """What is flagged and when a sample counts.

    Attributes
    ----------
    alarm
        The outcome class to flag (text, as in the labels table).
    phase_column
        Column of the runs holding the machining phase (text).
    active_prefix
        A sample is scored (and a training window) only where its phase starts with this.
    smooth
        Samples averaged by the online rule (the last ``smooth`` scored ones), >= 1.
    c
        Inverse regularisation strength of the logistic regression (scikit-learn ``C``).
    """

    alarm: str
    phase_column: str
    active_prefix: str
    smooth: int = 20
    c: float = 1.0


@dataclass(frozen=True)
class RunWindows:
    """One run's scored samples: features, times and outcome.

    Attributes
    ----------
    key
        The run's key.
    outcome
        The run's outcome (its label).
    alarm
        Whether the run ended in the alarm class.
    x
        Features of every active, valid sample, ``(n, features)``.
    t_s
        Their times, s from the run's first sample.
    train
        Which of them are training windows (every ``stride``-th sample of the run).
    end_s
        End of machining: the time of the run's last active sample, s.
    """

    key: str
    outcome: str
    alarm: bool
    x: NDArray[np.float64]
    t_s: NDArray[np.float64]
    train: NDArray[np.bool_]
    end_s: float


@dataclass
class LeadTimeResult:
    """The study's report and, per run, the trace the figure draws.

    Attributes
    ----------
    report
        JSON-ready: the rule, per-run decisions and the summary.
    traces
        Run key -> (time before the end of machining, s; smoothed score) of every scored
        sample, from the leave-one-run-out model.
    """

    report: dict[str, Any]
    traces: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]]


def outcomes(table: Mapping[str, NDArray[Any]], key_column: str, target: str) -> dict[str, str]:
    """Run key -> outcome text from a labels table with one row per run.

    Raises
    ------
    cnctwin.errors.InputError
        For a key or target column the table lacks (naming the columns it has).
    """
    for option, name in (("--label-key", key_column), ("--target", target)):
        if name not in table:
            raise InputError(
                f"{option} {name!r} is not a column of the labels (columns: {', '.join(table)})"
            )
    return {
        key_of(k): str(v).strip()
        for k, v in zip(table[key_column], table[target], strict=True)
        if str(v).strip() not in ("", "nan")
    }


def run_windows(
    runs: Sequence[Run], schema: FeatureSchema, outcome: Mapping[str, str], rule: AlarmRule
) -> list[RunWindows]:
    """Each labelled run's active samples through the schema's feature path.

    Runs without an outcome or without an active sample are left out.

    Raises
    ------
    cnctwin.errors.InputError
        For a run without the phase column, or an alarm class no run has.
    """
    if schema.spec.kind != "series":
        raise InputError("--features: the lead time needs a 'series' spec (runs over time)")
    path = FeaturePath(schema)
    out = []
    for run in runs:
        label = outcome.get(run.key)
        if label is None:
            continue
        if rule.phase_column not in run.columns:
            raise InputError(
                f"--phase-column {rule.phase_column!r} is not a column of run {run.key} "
                f"(columns: {', '.join(sorted(run.columns))})"
            )
        t = run.columns.get(TIME_COLUMN)
        times = None if t is None else np.asarray(t, dtype=float)
        features, valid = path.batch(run.columns, times)
        n = features.shape[0]
        if times is None:
            times = np.arange(n) * schema.spec.sample_period_s
        phase = np.asarray(run.columns[rule.phase_column]).astype(str)
        active = valid & np.char.startswith(phase, rule.active_prefix)
        index = np.flatnonzero(active)
        if index.size == 0:
            continue
        out.append(
            RunWindows(
                key=run.key,
                outcome=label,
                alarm=label == rule.alarm,
                x=features[index],
                t_s=times[index] - times[0],
                train=index % schema.spec.stride == 0,
                end_s=float(times[index[-1]] - times[0]),
            )
        )
    if not any(r.alarm for r in out):
        classes = sorted(set(outcome.values()))
        raise InputError(f"--alarm {rule.alarm!r}: no labelled run has it (classes: {classes})")
    return out


def smoothed(proba: NDArray[np.float64], smooth: int) -> NDArray[np.float64]:
    """Causal moving mean: element i is the mean of ``proba[i - smooth + 1 : i + 1]``, NaN
    for the first ``smooth - 1`` (no decision before a full window)."""
    total = np.concatenate([[0.0], np.cumsum(proba)])
    out = np.full(proba.size, np.nan)
    out[smooth - 1 :] = (total[smooth:] - total[: proba.size - smooth + 1]) / smooth
    return out


def first_flag(score: NDArray[np.float64], threshold: float) -> int | None:
    """Index of the first score at or above ``threshold``; ``None`` if none is."""
    with np.errstate(invalid="ignore"):
        hits = np.flatnonzero(score >= threshold)
    return int(hits[0]) if hits.size else None


def _fit(runs: Sequence[RunWindows], c: float) -> Any:
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    x = np.concatenate([r.x[r.train] for r in runs])
    y = np.concatenate([np.full(int(r.train.sum()), r.alarm) for r in runs])
    model = make_pipeline(
        StandardScaler(),
        LogisticRegression(C=c, class_weight="balanced", solver=SOLVER, max_iter=200),
    )
    return model.fit(x, y)


def _score(model: Any, run: RunWindows, smooth: int) -> NDArray[np.float64]:
    proba = model.predict_proba(run.x)[:, list(model.classes_).index(True)]
    return smoothed(np.asarray(proba, dtype=float), smooth)


def choose_threshold(maxima: Sequence[float], alarm: Sequence[bool]) -> float:
    """The highest threshold among those maximising Youden's J over runs.

    ``maxima`` are the runs' highest scores (a run is flagged at threshold θ when its
    maximum is >= θ); candidates are the maxima themselves and infinity (no run flagged,
    J = 0: where nothing separates the runs, nothing is ever flagged).
    """
    m = np.asarray(maxima, dtype=float)
    a = np.asarray(alarm, dtype=bool)
    best = (-math.inf, -math.inf)
    for theta in [*np.unique(m), math.inf]:
        flagged = m >= theta
        j = float(np.mean(flagged[a]) if a.any() else 0.0) - float(
            np.mean(flagged[~a]) if (~a).any() else 0.0
        )
        if j > best[0] or (j == best[0] and theta > best[1]):
            best = (j, float(theta))
    return best[1]


def hold_out_decision(
    runs: Sequence[RunWindows], held: str, rule: AlarmRule
) -> tuple[float, NDArray[np.float64], Any]:
    """The threshold, the held-out run's score trace and the model, for run ``held``.

    The model and the threshold are computed from the other runs only (see the module's
    description); the trace is the held-out run's smoothed probability at each of its
    scored samples.

    Raises
    ------
    cnctwin.errors.InputError
        When the other runs lack a class (no model can be fitted).
    """
    others = [r for r in runs if r.key != held]
    target = next(r for r in runs if r.key == held)
    if len({r.alarm for r in others}) < 2:
        raise InputError(
            f"leaving run {held} out leaves runs of one outcome only; a classifier needs both"
        )
    maxima, alarm = [], []
    for inner in others:
        rest = [r for r in others if r.key != inner.key]
        if len({r.alarm for r in rest}) < 2:
            continue  # without this run one class is gone: it cannot be scored out of fold
        maxima.append(_peak(_score(_fit(rest, rule.c), inner, rule.smooth)))
        alarm.append(inner.alarm)
    threshold = choose_threshold(maxima, alarm)
    model = _fit(others, rule.c)
    return threshold, _score(model, target, rule.smooth), model


def _peak(score: NDArray[np.float64]) -> float:
    """A run's highest score; 0 for a run shorter than one smoothing window."""
    finite = score[np.isfinite(score)]
    return float(finite.max()) if finite.size else 0.0


def _auc(y: NDArray[np.bool_], p: NDArray[np.float64]) -> float:
    from sklearn.metrics import roc_auc_score

    return float(roc_auc_score(y, p)) if 0 < y.sum() < y.size else math.nan


def lead_time_study(
    runs: Sequence[Run],
    schema: FeatureSchema,
    outcome: Mapping[str, str],
    rule: AlarmRule,
    seed: int = 0,
) -> LeadTimeResult:
    """Leave each run out in turn; flag it online; report lead times and false alarms.

    Parameters
    ----------
    runs
        The runs (:func:`~cnctwin.learn.read_runs`).
    schema
        The feature schema (a ``series`` spec; its ``stride`` picks the training windows).
    outcome
        Run key -> outcome class (:func:`outcomes`).
    rule
        The alarm class, the active phases and the rule's smoothing.
    seed
        Seed of the random split of windows reported only as the leakage comparison.

    Returns
    -------
    LeadTimeResult
        ``report["runs"]``: per run its outcome, whether and when it was flagged, how long
        before the end of machining (s; for an alarm run its lead time), the threshold
        used; ``report["summary"]``: alarm runs flagged, their lead times, false alarms
        on the other runs, the window ROC AUC left out by run and (leakage, never a figure
        of merit) by random windows.
    """
    windows = run_windows(runs, schema, outcome, rule)
    if len(windows) < 4:
        raise InputError(
            f"{len(windows)} labelled run(s) with active samples; leaving one run out "
            f"needs at least 4"
        )
    per_run: list[dict[str, Any]] = []
    traces: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
    pooled_y, pooled_p = [], []
    for run in windows:
        threshold, score, model = hold_out_decision(windows, run.key, rule)
        flag = first_flag(score, threshold)
        before_end = None if flag is None else float(run.end_s - run.t_s[flag])
        traces[run.key] = (run.end_s - run.t_s, score)
        proba = model.predict_proba(run.x[run.train])[:, list(model.classes_).index(True)]
        pooled_y.append(np.full(proba.size, run.alarm))
        pooled_p.append(proba)
        per_run.append(
            {
                "run": run.key,
                "outcome": run.outcome,
                "alarm": run.alarm,
                "flagged": flag is not None,
                "flag_time_s": None if flag is None else float(run.t_s[flag]),
                "end_of_machining_s": run.end_s,
                "before_end_s": before_end,
                "lead_time_s": before_end if run.alarm else None,
                "threshold": threshold,
                "max_score": _peak(score),
                "scored_samples": int(score.size),
            }
        )
    alarm_runs = [r for r in per_run if r["alarm"]]
    other_runs = [r for r in per_run if not r["alarm"]]
    leads = [r["lead_time_s"] for r in alarm_runs if r["flagged"]]
    y = np.concatenate(pooled_y)
    summary = {
        "runs": len(per_run),
        "alarm_runs": len(alarm_runs),
        "alarm_runs_flagged": sum(r["flagged"] for r in alarm_runs),
        "lead_times_s": leads,
        "median_lead_time_s": float(np.median(leads)) if leads else None,
        "other_runs": len(other_runs),
        "false_alarms": sum(r["flagged"] for r in other_runs),
        "false_alarm_runs": [r["run"] for r in other_runs if r["flagged"]],
        "window_roc_auc_leave_one_run_out": _auc(y, np.concatenate(pooled_p)),
        "window_roc_auc_random_windows": _random_split_auc(windows, rule, seed),
    }
    report = {
        "schema_sha256": schema.sha256,
        "features": list(schema.names),
        "rule": {
            "alarm": rule.alarm,
            "phase_column": rule.phase_column,
            "active_prefix": rule.active_prefix,
            "smooth_samples": rule.smooth,
            "smooth_s": rule.smooth * schema.spec.sample_period_s,
            "logistic_c": rule.c,
            "threshold": "highest maximiser of run-level Youden J, inner leave-one-run-out",
        },
        "summary": summary,
        "runs": per_run,
    }
    return LeadTimeResult(report, traces)


def _random_split_auc(runs: Sequence[RunWindows], rule: AlarmRule, seed: int) -> float:
    """Window ROC AUC of 5 folds of windows drawn at random (windows of one run on both
    sides): the leakage the grouped study avoids, for comparison only."""
    from sklearn.linear_model import LogisticRegression
    from sklearn.model_selection import StratifiedKFold, cross_val_predict
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    x = np.concatenate([r.x[r.train] for r in runs])
    y = np.concatenate([np.full(int(r.train.sum()), r.alarm) for r in runs])
    model = make_pipeline(
        StandardScaler(),
        LogisticRegression(C=rule.c, class_weight="balanced", solver=SOLVER, max_iter=200),
    )
    folds = StratifiedKFold(5, shuffle=True, random_state=seed)
    proba = cross_val_predict(model, x, y, cv=folds, method="predict_proba")[:, 1]
    return _auc(y, proba)
