"""The model stage (``[[twin.models]]``): a model trained on a recorded run of the virtual
machine, run by the twin through onnxruntime, checked against scikit-learn on the recorded
features; models the twin cannot feed are refused at start."""

from __future__ import annotations

import asyncio
import hashlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tiny_models import tiny_model
from twin_helpers import STEP_S

from cnctwin.errors import ConfigError
from cnctwin.learn import (
    FeaturePath,
    FeatureSchema,
    FeatureSpec,
    build_dataset,
    export_onnx,
    read_runs,
    train,
)
from cnctwin.store import Historian
from cnctwin.twin import LocalConnection, RunConfig, build_twin, run_session
from cnctwin.virtual import VirtualMachine

pytest.importorskip("onnxruntime")
pytest.importorskip("skl2onnx")

#: Samples per recorded run (the demo cuts from about sample 120 at 25 ms machine time).
SAMPLES = 700

SPEC = {
    "sample_period_s": 0.0125,
    "signals": {"spindle_power_w": "W", "feed_mm_min": "mm/min"},
    "filters": {"spindle_power_w": {"kind": "butterworth", "cutoff_hz": 5.0}},
    "windows": [{"signal": "spindle_power_w", "length": 20, "features": ["mean", "rms"]}],
}


def _config(base: RunConfig, models: list[dict[str, Any]]) -> RunConfig:
    assert base.virtual is not None
    twin = base.twin.model_copy(update={"models": []}).model_dump()
    twin["models"] = models
    return RunConfig.from_machining(
        base,
        connection=base.connection,
        virtual=base.virtual.model_copy(update={"faults": []}),
        historian=base.historian,
        rules=[],
        control={"enabled": False},
        twin=twin,
    )


def _record(config: RunConfig, db: Path) -> int:
    """One lockstep run of the demo for :data:`SAMPLES` samples, recorded in ``db``."""
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    historian = Historian.open(db)
    stop = asyncio.Event()
    seen = [0]

    def count(state: Any) -> None:
        seen[0] += 1
        if seen[0] >= SAMPLES:
            stop.set()

    try:
        asyncio.run(
            run_session(
                config,
                connection=conn,
                historian=historian,
                stop_event=stop,
                on_cycle=count,
                realtime=False,
            )
        )
        return historian.runs()[-1].run_id
    finally:
        historian.close()


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory, demo_config: RunConfig) -> dict[str, Any]:
    """A GPR of the spindle's force Y from its power and feed, taught on one recorded run
    (split into chunks as groups)."""
    folder = tmp_path_factory.mktemp("model")
    teach = folder / "teach.sqlite"
    _record(_config(demo_config, []), teach)
    runs = read_runs([f"historian:{teach}"])
    n = len(runs[0].columns["time_s"])
    runs[0].columns["chunk"] = (np.arange(n) // 100).astype(float)
    schema = FeatureSchema.from_spec(FeatureSpec.model_validate(SPEC))
    data = build_dataset(runs, schema)
    result = train(data, "force_y_n", "gpr", "chunk", quick=True, max_gpr_points=150)
    path = export_onnx(result, schema, folder / "force.onnx")
    return {"folder": folder, "path": path, "result": result, "schema": schema}


def test_the_twin_records_what_the_trained_model_predicts(
    trained: dict[str, Any], demo_config: RunConfig
) -> None:
    config = _config(demo_config, [{"name": "force_y_model", "path": trained["path"]}])
    db = trained["folder"] / "monitor.sqlite"
    run_id = _record(config, db)
    with Historian.open(db, create=False) as historian:
        meta = historian.run(run_id).summary.meta
        samples = historian.samples(run_id)
        predicted = historian.samples(run_id, predicted=True)
    # the model file's hash is recorded with the run
    digest = hashlib.sha256(Path(trained["path"]).read_bytes()).hexdigest()
    assert meta["models"] == [
        {"name": "force_y_model", "path": str(trained["path"]), "sha256": digest}
    ]
    # the same features, offline over the recorded samples, through scikit-learn
    features, valid = FeaturePath(trained["schema"]).batch(
        {k: samples[k] for k in ("spindle_power_w", "feed_mm_min")}, samples["time_s"]
    )
    expected = trained["result"].predict(features[valid])
    ready = predicted["force_y_model_ready"] == 1.0
    assert np.array_equal(ready, valid)
    assert ready.sum() > SAMPLES // 2
    got = predicted["force_y_model"][ready]
    np.testing.assert_allclose(got, expected["prediction"], rtol=1e-9, atol=1e-6)
    band = trained["result"].band * expected["std"]
    np.testing.assert_allclose(predicted["force_y_model_band"][ready], band, rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(predicted["force_y_model_high"][ready], got + band, atol=1e-6)
    # a model that learned something: the cut's force is not a constant
    assert np.std(got) > 1.0


def _build(config: RunConfig) -> None:
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    build_twin(config, LocalConnection(vm), realtime=False)


def test_a_model_reading_a_signal_the_twin_lacks_is_refused(
    tmp_path: Path, demo_config: RunConfig
) -> None:
    spec = {
        "sample_period_s": 0.0125,
        "signals": {"X1_OutputPower": "kW"},
        "windows": [{"signal": "X1_OutputPower", "length": 5, "features": ["rms"]}],
    }
    path = tiny_model(tmp_path, spec, "X1_OutputPower")
    config = _config(demo_config, [{"name": "load", "path": path}])
    with pytest.raises(ConfigError) as err:
        _build(config)
    message = str(err.value)
    assert "\n" not in message
    assert "twin.models[0]" in message and "'X1_OutputPower'" in message


def test_a_model_of_another_sample_period_or_a_taken_name_is_refused(
    tmp_path: Path, demo_config: RunConfig
) -> None:
    spec = {"sample_period_s": 0.1, "signals": {"spindle_power_w": "W"}}
    path = tiny_model(tmp_path, spec, "spindle_power_w")
    with pytest.raises(ConfigError, match=r"sample period of 0\.1 s .* every 0\.0125 s"):
        _build(_config(demo_config, [{"name": "power", "path": path}]))
    spec["sample_period_s"] = 0.0125
    path = tiny_model(tmp_path, spec, "spindle_power_w")
    with pytest.raises(ConfigError, match="'contact' is already a signal"):
        _build(_config(demo_config, [{"name": "contact", "path": path}]))
    not_a_model = tmp_path / "bad.onnx"
    not_a_model.write_bytes(b"not onnx")
    with pytest.raises(ConfigError, match=r"twin\.models\[0\].*not an ONNX model"):
        _build(_config(demo_config, [{"name": "power", "path": not_a_model}]))
