"""Training, ONNX export and loading: the ONNX model equals the scikit-learn one on held-out
rows (onnxruntime against scikit-learn), grouped hold-out, schema checks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cnctwin.errors import DataError, InputError
from cnctwin.learn import (
    Dataset,
    FeaturePath,
    FeatureSchema,
    FeatureSpec,
    Predictor,
    evaluate_model,
    export_onnx,
    train,
)

SPEC = FeatureSpec.model_validate(
    {
        "sample_period_s": 0.1,
        "signals": {"feed_mm_s": "mm/s", "depth_mm": "mm", "speed_rpm": "rpm"},
        "windows": [{"signal": "feed_mm_s", "length": 4, "features": ["mean"]}],
    }
)


def _data(rows_per_group: int = 40, groups: int = 8, seed: int = 0) -> Dataset:
    """Power = a smooth function of the inputs plus a per-group offset and noise."""
    schema = FeatureSchema.from_spec(SPEC)
    rng = np.random.default_rng(seed)
    n = rows_per_group * groups
    x = rng.uniform([1, 0.5, 3000], [20, 3, 12000], size=(n, 3))
    features = np.column_stack([x, x[:, 0] + rng.normal(0, 0.5, n)])
    group = np.repeat([f"e{g}" for g in range(groups)], rows_per_group).astype(object)
    offset = np.repeat(rng.normal(0, 5, groups), rows_per_group)
    power = 3 * x[:, 0] * x[:, 1] + 0.002 * x[:, 2] + offset + rng.normal(0, 2, n)
    worn = np.repeat(["worn" if g % 2 else "unworn" for g in range(groups)], rows_per_group)
    power_c = power + np.where(worn == "worn", 25.0, 0.0)
    columns = {"run": group, "power_w": power, "tool": worn.astype(object), "power_c": power_c}
    return Dataset(schema, features, columns)


@pytest.mark.parametrize("model", ["linear", "gbm", "mlp", "gpr"])
def test_onnx_equals_sklearn_on_held_out_rows(model: str, tmp_path) -> None:
    data = _data()
    result = train(data, "power_w", model, "run", quick=True, max_gpr_points=120)
    report = result.report
    assert not set(report["groups_holdout"]) & set(report["groups_tuning"])
    path = export_onnx(result, data.schema, tmp_path / "m.onnx")
    predictor = Predictor.load(path, available={"feed_mm_s", "depth_mm", "speed_rpm", "x"})
    held = np.isin(data.columns["run"], report["groups_holdout"])
    x = data.features[held]
    expected = result.predict(x)
    got = predictor.predict(x)
    tol = 1e-9 if model == "gpr" else 1e-6
    scale = np.max(np.abs(expected["prediction"]))
    np.testing.assert_allclose(
        got["prediction"], expected["prediction"], rtol=tol, atol=tol * scale
    )
    if model == "gpr":
        np.testing.assert_allclose(got["std"], expected["std"], rtol=1e-9)
        assert np.all(got["band"] > 0)
    # the learned relation is real: better than predicting the mean
    assert report["holdout"]["r2"] > 0.5
    assert 0.0 <= report["holdout"]["band_coverage"] <= 1.0
    # one window through the live feature path
    path_live = FeaturePath(predictor.schema)
    features = path_live.update({"feed_mm_s": 10.0, "depth_mm": 1.0, "speed_rpm": 6000.0})
    window = predictor.predict_window(features)
    assert set(window) >= {"power_w", "power_w_band"}
    assert np.isfinite(window["power_w"])


@pytest.mark.parametrize("model", ["linear", "gbm", "mlp"])
def test_classifier_onnx_equals_sklearn(model: str, tmp_path) -> None:
    data = _data(seed=3)
    result = train(data, "tool", model, "run", quick=True)
    assert result.classes == ["unworn", "worn"]
    metrics = result.report["holdout"]
    assert set(metrics) >= {"balanced_accuracy", "roc_auc", "confusion_matrix"}
    predictor = Predictor.load(export_onnx(result, data.schema, tmp_path / "c.onnx"))
    x = data.features[np.isin(data.columns["run"], result.report["groups_holdout"])]
    np.testing.assert_allclose(
        predictor.predict(x)["probabilities"], result.predict(x)["probabilities"], atol=1e-6
    )


def test_schema_mismatch_refused(tmp_path) -> None:
    data = _data()
    path = export_onnx(
        train(data, "power_w", "linear", "run", quick=True), data.schema, tmp_path / "m.onnx"
    )
    with pytest.raises(DataError, match="lacks the signal\\(s\\) speed_rpm"):
        Predictor.load(path, available={"feed_mm_s", "depth_mm"})
    predictor = Predictor.load(path)
    other = FeatureSchema.from_spec(SPEC.model_copy(update={"sample_period_s": 0.2}))
    with pytest.raises(DataError, match="differs from the model's"):
        evaluate_model(predictor, Dataset(other, data.features, data.columns))
    # an altered schema in the file is refused by its hash
    import onnx

    proto = onnx.load(path)
    for prop in proto.metadata_props:
        if prop.key == "cnctwin.schema":
            stored = json.loads(prop.value)
            stored["spec"]["sample_period_s"] = 0.5
            prop.value = json.dumps(stored)
    onnx.save(proto, tmp_path / "altered.onnx")
    with pytest.raises(DataError, match="was altered"):
        Predictor.load(tmp_path / "altered.onnx")
    (tmp_path / "junk.onnx").write_bytes(b"not a model")
    with pytest.raises(DataError, match="not an ONNX model"):
        Predictor.load(tmp_path / "junk.onnx")


def test_bad_requests_are_input_errors() -> None:
    data = _data()
    with pytest.raises(InputError, match="--model 'svm'"):
        train(data, "power_w", "svm", "run")
    with pytest.raises(InputError, match="--target 'nope'"):
        train(data, "nope", "gbm", "run")
    with pytest.raises(InputError, match="--model gpr predicts numbers"):
        train(data, "tool", "gpr", "run")
    one = Dataset(data.schema, data.features, {**data.columns, "one": np.full(len(data), "a")})
    with pytest.raises(InputError, match="1 group"):
        train(one, "power_w", "linear", "one")


def test_leave_one_group_out_scores_every_group_with_a_model_that_never_saw_it() -> None:
    from cnctwin.learn import leave_one_group_out

    data = _data(rows_per_group=10, groups=5)
    loo = leave_one_group_out(data, "power_w", "linear", "run", quick=True)
    assert sorted(loo["per_group"]) == [f"e{g}" for g in range(5)]
    assert loo["pooled"]["rows"] == len(data)
    # each group's score equals a train() that holds out exactly that group
    alone = train(data, "power_w", "linear", "run", quick=True, holdout_names=["e3"])
    assert alone.report["groups_holdout"] == ["e3"]
    assert loo["per_group"]["e3"]["mae"] == pytest.approx(alone.report["holdout"]["mae"])
