"""The one feature path: batch over a log equals the live path and the twin's stages."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.errors import ConfigError, DataError
from cnctwin.learn import FeaturePath, FeatureSchema, FeatureSpec, FilterSpec, WindowSpec
from cnctwin.twin.stages import FeatureStage, FilterStage
from cnctwin.twin.state import CycleState

PERIOD_S = 0.0125

SPEC = {
    "sample_period_s": PERIOD_S,
    "signals": {"spindle_power_w": "W", "force_x_n": "N", "feed_mm_min": "mm/min"},
    "filters": {
        "spindle_power_w": {"kind": "hampel", "window": 7},
        "force_x_n": {"kind": "butterworth", "cutoff_hz": 8.0, "order": 2},
        "feed_mm_min": {"kind": "kalman", "process_var": 4.0, "measurement_var": 9.0},
    },
    "windows": [
        {"signal": "spindle_power_w", "length": 16, "features": ["mean", "rms", "slope"]},
        {"signal": "force_x_n", "length": 5, "features": ["peak_to_peak", "mean"]},
    ],
}


def _log(n: int, seed: int) -> dict[str, np.ndarray]:
    """A machine log with noise, spikes and missing samples."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * PERIOD_S
    power = 800 + 300 * np.sin(2 * np.pi * 0.7 * t) + rng.normal(0, 20, n)
    power[rng.integers(0, n, 6)] += 5000  # spikes for the Hampel filter
    force = 120 * np.sin(2 * np.pi * 3 * t) + rng.normal(0, 5, n)
    feed = 600 + 100 * (t > t[n // 2]) + rng.normal(0, 3, n)
    for column in (power, force, feed):
        column[rng.integers(0, n, n // 20)] = np.nan  # samples the machine did not deliver
    force[:3] = np.nan  # a signal that starts late
    return {"spindle_power_w": power, "force_x_n": force, "feed_mm_min": feed, "time_s": t}


def _schema(**changes: object) -> FeatureSchema:
    return FeatureSchema.from_spec(FeatureSpec.model_validate({**SPEC, **changes}))


def test_batch_equals_live_update_sample_for_sample() -> None:
    schema = _schema()
    log = _log(600, 1)
    batch, valid = FeaturePath(schema).batch(log, log["time_s"])
    live = FeaturePath(schema)
    for i in range(600):
        out = live.update({k: float(v[i]) for k, v in log.items()}, float(log["time_s"][i]))
        row = np.array([out[name] for name in schema.names])
        np.testing.assert_allclose(row, batch[i], rtol=1e-12, atol=1e-9, equal_nan=True)
    assert valid[-1] and not valid[0]  # force has no sample yet at the start


def test_batch_equals_the_twins_filter_and_feature_stages() -> None:
    """The offline dataset is what the live twin's stages compute, sample for sample."""
    schema = _schema()
    log = _log(500, 2)
    batch, _ = FeaturePath(schema).batch(log, log["time_s"])
    filters = FilterStage({k: FilterSpec(**v) for k, v in SPEC["filters"].items()}, PERIOD_S)
    windows = FeatureStage([WindowSpec(**w) for w in SPEC["windows"]], PERIOD_S)
    names = list(schema.names)
    compared = 0
    for i in range(500):
        measured = {k: float(v[i]) for k, v in log.items() if math.isfinite(v[i])}
        measured["t_s"] = float(log["time_s"][i])
        state = CycleState(index=i, deadline_s=0.0, connected=True, measured=measured)
        state = windows.process(filters.process(state))
        for signal, value in state.filtered.items():
            if math.isfinite(value):
                assert batch[i, names.index(signal)] == pytest.approx(value, rel=1e-12)
        for name, value in state.features.items():
            assert batch[i, names.index(name)] == pytest.approx(
                value, rel=1e-9, abs=1e-9, nan_ok=True
            )
            compared += 1
    assert compared > 2000


def test_invalid_samples_and_categories() -> None:
    spec = {
        "sample_period_s": 0.1,
        "signals": {"x_mm": "mm"},
        "windows": [{"signal": "x_mm", "length": 3, "features": ["mean"]}],
        "categories": {"phase": ["cut", "air"]},
        "invalid_when": [{"signal": "x_mm", "equals": 198.0}],
    }
    schema = FeatureSchema.from_spec(FeatureSpec.model_validate(spec))
    assert schema.names == ("x_mm", "x_mm_mean", "phase=cut", "phase=air")
    assert schema.sources == ("phase", "x_mm")
    columns = {
        "x_mm": np.array([1.0, 2.0, 198.0, 4.0]),
        "phase": np.array(["air", "cut", "cut", "other"], dtype=object),
    }
    out, valid = FeaturePath(schema).batch(columns)
    np.testing.assert_allclose(out[:, 0], [1, 2, 2, 4])  # the glitch is held over
    np.testing.assert_allclose(out[:, 1], [1, 1.5, 1.5, (1 + 2 + 4) / 3])
    np.testing.assert_allclose(out[:, 2:], [[0, 1], [1, 0], [0, 0], [0, 0]])
    assert valid.tolist() == [True, True, False, True]


def test_spec_errors_name_the_key() -> None:
    with pytest.raises(ValueError, match="windows\\[0\\].signal 'y'"):
        FeatureSpec.model_validate({"signals": {"x": "mm"}, "windows": [{"signal": "y"}]})
    with pytest.raises(ValueError, match="features"):
        FeatureSpec.model_validate(
            {"signals": {"x": "mm"}, "windows": [{"signal": "x", "features": ["median"]}]}
        )
    with pytest.raises(DataError, match="lacks the signal\\(s\\) force_x_n"):
        FeaturePath(_schema()).batch({"spindle_power_w": np.zeros(3), "feed_mm_min": np.zeros(3)})
    with pytest.raises(ConfigError, match="cutoff"):
        FeaturePath(_schema(filters={"force_x_n": {"kind": "butterworth", "cutoff_hz": 50.0}}))


def test_hash_changes_with_any_setting() -> None:
    base = _schema()
    assert base.sha256 == _schema().sha256
    windows = [dict(SPEC["windows"][0], length=17), SPEC["windows"][1]]
    assert _schema(windows=windows).sha256 != base.sha256
    assert _schema(sample_period_s=0.01).sha256 != base.sha256
    reordered = _schema(signals=dict(reversed(SPEC["signals"].items())))
    assert reordered.sha256 != base.sha256
    assert reordered.names[:3] == ("feed_mm_min", "force_x_n", "spindle_power_w")
    # the stored form keeps the order
    assert FeatureSchema.from_json(reordered.to_json(), "test").names == reordered.names
