"""The lead-time study: the held-out run's decision uses nothing of that run but its samples
up to the decision (property test), and equals an independent computation with
scikit-learn's own leave-one-group-out splitter, its ROC threshold list and a convolution."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cnctwin.errors import InputError
from cnctwin.learn import FeatureSchema, FeatureSpec, Run
from cnctwin.learn.lead_time import (
    SOLVER,
    AlarmRule,
    first_flag,
    hold_out_decision,
    lead_time_study,
    run_windows,
    smoothed,
)

SPEC = FeatureSpec.model_validate(
    {
        "sample_period_s": 0.1,
        "stride": 3,
        "signals": {"load_a": "A", "speed_mm_s": "mm/s"},
        "windows": [{"signal": "load_a", "length": 5, "features": ["rms", "peak_to_peak"]}],
    }
)
RULE = AlarmRule("no", "phase", "Layer", smooth=4)


def _runs(seed: int, n_runs: int = 7, n_alarm: int = 3) -> tuple[list[Run], dict[str, str]]:
    """Runs of 60-90 samples: a 'Prep' start then 'Layer' samples; an alarm run's load
    fluctuates more once it is cutting (a loose part), with noise on every run."""
    rng = np.random.default_rng(seed)
    runs, outcome = [], {}
    for k in range(n_runs):
        alarm = k < n_alarm
        n = int(rng.integers(60, 90))
        spread = 2.0 if alarm else 1.0
        load = 5.0 + rng.normal(0.0, spread, n)
        speed = rng.uniform(3.0, 20.0) + rng.normal(0.0, 0.2, n)
        phase = np.array(["Prep"] * 8 + ["Layer 1 Up"] * (n - 8), dtype=object)
        key = str(k + 1)
        runs.append(Run(key, {"load_a": load, "speed_mm_s": speed, "phase": phase}))
        outcome[key] = "no" if alarm else "yes"
    return runs, outcome


SCHEMA = FeatureSchema.from_spec(SPEC)


@settings(max_examples=12, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    held=st.integers(0, 6),
    cut=st.integers(10, 59),
    garbage=st.floats(-1e3, 1e3),
)
def test_held_out_decision_uses_no_later_sample_and_not_its_label(
    seed: int, held: int, cut: int, garbage: float
) -> None:
    runs, outcome = _runs(seed)
    key = runs[held].key
    threshold, trace, _ = hold_out_decision(run_windows(runs, SCHEMA, outcome, RULE), key, RULE)
    # the held-out run's samples from `cut` on replaced by garbage, its label flipped
    changed = runs[held].columns["load_a"].copy()
    changed[cut:] = garbage
    altered = [Run(r.key, {**r.columns, "load_a": changed}) if r.key == key else r for r in runs]
    flipped = {**outcome, key: "yes" if outcome[key] == "no" else "no"}
    windows = run_windows(altered, SCHEMA, flipped, RULE)
    threshold2, trace2, _ = hold_out_decision(windows, key, RULE)
    assert threshold2 == threshold  # nothing of the held-out run chooses the threshold
    # the scored samples before `cut` (phase 'Layer' from sample 8 on) have equal scores
    before = cut - 8
    np.testing.assert_array_equal(trace2[:before], trace[:before])
    flag, flag2 = first_flag(trace, threshold), first_flag(trace2, threshold2)
    if flag is not None and flag < before:
        assert flag2 == flag


def test_decision_equals_scikit_learn_pipeline_computed_independently() -> None:
    from sklearn.linear_model import LogisticRegression
    from sklearn.metrics import roc_curve
    from sklearn.model_selection import LeaveOneGroupOut
    from sklearn.pipeline import Pipeline
    from sklearn.preprocessing import StandardScaler

    runs, outcome = _runs(3, n_runs=8, n_alarm=3)
    windows = run_windows(runs, SCHEMA, outcome, RULE)
    # rows: every training window, grouped by run; all scored samples for the traces
    x = np.concatenate([w.x[w.train] for w in windows])
    y = np.concatenate([np.full(int(w.train.sum()), w.alarm) for w in windows])
    g = np.concatenate([np.full(int(w.train.sum()), w.key) for w in windows])
    by_key = {w.key: w for w in windows}

    def model(rows: np.ndarray) -> Pipeline:
        est = LogisticRegression(C=1.0, class_weight="balanced", solver=SOLVER, max_iter=200)
        return Pipeline([("scale", StandardScaler()), ("lr", est)]).fit(x[rows], y[rows])

    def trace(m: Pipeline, key: str) -> np.ndarray:
        p = m.predict_proba(by_key[key].x)[:, 1]
        return np.convolve(p, np.ones(RULE.smooth) / RULE.smooth, mode="valid")

    study = lead_time_study(runs, SCHEMA, outcome, RULE)
    decisions = {r["run"]: r for r in study.report["runs"]}
    for outer_train, outer_test in LeaveOneGroupOut().split(x, y, g):
        key = str(g[outer_test][0])
        maxima, labels = [], []
        for inner_train, inner_test in LeaveOneGroupOut().split(
            x[outer_train], y[outer_train], g[outer_train]
        ):
            inner_key = str(g[outer_train][inner_test][0])
            maxima.append(trace(model(outer_train[inner_train]), inner_key).max())
            labels.append(by_key[inner_key].alarm)
        fpr, tpr, thresholds = roc_curve(labels, maxima, drop_intermediate=False)
        j = tpr - fpr
        threshold = float(np.max(thresholds[j == j.max()]))  # the highest of the best
        score = trace(model(outer_train), key)
        hits = np.flatnonzero(score >= threshold)
        decision = decisions[key]
        assert decision["threshold"] == pytest.approx(threshold, rel=1e-12) or (
            math.isinf(threshold) and math.isinf(decision["threshold"])
        )
        assert decision["flagged"] == bool(hits.size)
        if hits.size:
            w = by_key[key]
            first = hits[0] + RULE.smooth - 1  # 'valid' drops the first smooth - 1 samples
            assert decision["flag_time_s"] == pytest.approx(w.t_s[first])
            assert decision["before_end_s"] == pytest.approx(w.end_s - w.t_s[first])


def test_smoothed_is_the_causal_mean_and_waits_for_a_full_window() -> None:
    p = np.array([0.0, 1.0, 1.0, 1.0, 0.0, 1.0])
    s = smoothed(p, 3)
    assert np.isnan(s[:2]).all()
    np.testing.assert_allclose(s[2:], [2 / 3, 1.0, 2 / 3, 2 / 3])
    assert first_flag(s, 0.9) == 3
    assert first_flag(s, 1.1) is None


def test_refuses_an_alarm_class_no_run_has() -> None:
    runs, outcome = _runs(0)
    with pytest.raises(InputError, match="--alarm 'maybe'"):
        run_windows(runs, SCHEMA, outcome, AlarmRule("maybe", "phase", "Layer"))
    with pytest.raises(InputError, match="--phase-column 'stage'"):
        run_windows(runs, SCHEMA, outcome, AlarmRule("no", "stage", "Layer"))
