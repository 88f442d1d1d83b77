"""Datasets from the historian, its exports and replay logs: the same rows from each."""

from __future__ import annotations

import numpy as np
import pytest

from cnctwin.errors import DataError, InputError
from cnctwin.learn import FeaturePath, FeatureSchema, FeatureSpec, build_dataset, read_runs
from cnctwin.store import Historian

SPEC = FeatureSpec.model_validate(
    {
        "sample_period_s": 0.0125,
        "signals": {"spindle_power_w": "W", "feed_mm_min": "mm/min"},
        "filters": {"spindle_power_w": {"kind": "hampel", "window": 5}},
        "windows": [{"signal": "spindle_power_w", "length": 8, "features": ["mean", "slope"]}],
        "stride": 3,
    }
)


def _record(db, runs: int = 3, n: int = 60) -> list[dict[str, np.ndarray]]:
    rng = np.random.default_rng(0)
    logs = []
    with Historian.open(db) as historian:
        for k in range(runs):
            run = historian.start_run({"program": f"p{k}.ngc", "tool": "worn" if k else "new"})
            t = np.arange(n) * 0.0125
            power = 500 + 50 * k + rng.normal(0, 10, n)
            feed = np.full(n, 600.0 + k)
            for i in range(n):
                historian.record_samples(
                    run, float(t[i]), {"spindle_power_w": power[i], "feed_mm_min": feed[i]}
                )
            historian.end_run(run)
            logs.append({"time_s": t, "spindle_power_w": power, "feed_mm_min": feed})
    return logs


def test_historian_runs_exports_and_logs_give_the_same_rows(tmp_path) -> None:
    db = tmp_path / "h.db"
    logs = _record(db)
    schema = FeatureSchema.from_spec(SPEC)
    direct = build_dataset(read_runs([f"historian:{db}"]), schema)
    assert sorted(set(direct.columns["run"])) == ["1", "2", "3"]
    assert set(direct.columns["tool"]) == {"new", "worn"}  # run metadata as labels
    # every third of 60 samples but the first (a slope needs two samples)
    assert len(direct) == 3 * 19
    # the rows are the feature path's batch over each recorded log
    expected, valid = FeaturePath(schema).batch(logs[0], logs[0]["time_s"])
    first = direct.columns["run"] == "1"
    every_third = valid & (np.arange(60) % 3 == 0)
    np.testing.assert_array_equal(direct.features[first], expected[every_third])
    # exports of the same runs (CSV and Parquet) give the same rows
    with Historian.open(db, create=False) as historian:
        for run in (1, 2, 3):
            historian.export(run, tmp_path / f"run_{run}.{'csv' if run % 2 else 'parquet'}")
    exported = build_dataset(read_runs([str(tmp_path)]), schema)
    np.testing.assert_array_equal(exported.features, direct.features)
    np.testing.assert_array_equal(exported.columns["run"], direct.columns["run"])


def test_labels_join_on_the_run_key_and_bad_sources_are_named(tmp_path) -> None:
    schema = FeatureSchema.from_spec(SPEC)
    for k in (1, 2):
        (tmp_path / f"experiment_0{k}.csv").write_text(
            "spindle_power_w,feed_mm_min\n" + "".join(f"{500 + i},{600}\n" for i in range(12))
        )
    labels = {"No": np.array([1.0, 2.0]), "tool_condition": np.array(["unworn", "worn"], object)}
    data = build_dataset(read_runs([str(tmp_path / "experiment_*.csv")]), schema, labels, "No")
    by_run = dict(zip(data.columns["run"], data.columns["tool_condition"], strict=True))
    assert by_run == {"1": "unworn", "2": "worn"}
    # no time column: samples sample_period_s apart
    assert data.columns["row"].tolist() == list(range(len(data)))
    with pytest.raises(InputError, match="--label-key 'Nr'"):
        build_dataset(read_runs([str(tmp_path)]), schema, labels, "Nr")
    with pytest.raises(InputError, match="no such file"):
        read_runs([str(tmp_path / "missing.csv")])
    (tmp_path / "experiment_03.csv").write_text("feed_mm_min\n1\n")
    with pytest.raises(DataError, match="run 3 lacks the signal\\(s\\) spindle_power_w"):
        build_dataset(read_runs([str(tmp_path)]), schema)
