"""A learned model small enough to train inside a test (seconds), for the model-stage tests."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.learn import FeatureSchema, FeatureSpec, Run, build_dataset, export_onnx, train


def tiny_model(folder: Path, spec: dict[str, Any], signal: str) -> Path:
    """A linear model of ``y`` = 2 ``signal`` + noise on synthetic rows, as ``SIGNAL.onnx``."""
    rng = np.random.default_rng(3)
    runs = []
    for key in range(4):
        x = rng.normal(size=200)
        runs.append(Run(str(key), {signal: x, "y": 2.0 * x + rng.normal(0.0, 0.1, 200)}))
    schema = FeatureSchema.from_spec(FeatureSpec.model_validate(spec))
    result = train(build_dataset(runs, schema), "y", "linear", "run", quick=True)
    return export_onnx(result, schema, folder / f"{signal}.onnx")
