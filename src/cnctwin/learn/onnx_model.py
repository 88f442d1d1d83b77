"""Model files: ONNX with the feature schema embedded; loading, checking and running them.

:func:`export_onnx` converts a :class:`~cnctwin.learn.TrainResult` with skl2onnx (a GPR with
:func:`cnctwin.learn.gpr_graph.gpr_graph`, a graph built by hand) and stores,
in the model's metadata, the feature schema (``cnctwin.schema``, with its SHA-256), the
model description (``cnctwin.model``: kind, task, target, classes, band, outputs) and the
training report (``cnctwin.report``). Inputs are one ``features`` matrix ``(rows, features)``:
double precision for ``linear``, ``mlp`` and ``gpr`` (GPR with its standard deviation, the
target's standardisation folded into the graph), single for ``gbm`` (tree ensembles run in
float32 in ONNX; scikit-learn's trees compare float32 inputs too).

:class:`Predictor` is what the twin loads: :meth:`Predictor.load` checks the stored schema
against its hash and, given the signals a machine offers, that every source signal is there;
:meth:`Predictor.predict_window` runs one window's features (as
:meth:`cnctwin.learn.FeaturePath.update` gives them) through onnxruntime.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin import finite_json
from cnctwin.errors import DataError, InputError
from cnctwin.learn.dataset import Dataset
from cnctwin.learn.gpr_graph import gpr_graph
from cnctwin.learn.schema import FeatureSchema
from cnctwin.learn.training import (
    BAND_LEVEL,
    TrainResult,
    _class_metrics,
    _regression_metrics,
)

__all__ = ["Predictor", "evaluate_model", "export_onnx"]

_SCHEMA_KEY = "cnctwin.schema"
_MODEL_KEY = "cnctwin.model"
_REPORT_KEY = "cnctwin.report"
_OPSET = {"": 17, "ai.onnx.ml": 3}


def export_onnx(result: TrainResult, schema: FeatureSchema, path: str | Path) -> Path:
    """Write ``result``'s model to ``path`` (ONNX) with ``schema`` and its report embedded.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    import onnx
    from skl2onnx import to_onnx
    from skl2onnx.common.data_types import DoubleTensorType, FloatTensorType

    kind = result.report["model"]
    dtype = np.float32 if kind == "gbm" else np.float64
    tensor = FloatTensorType if kind == "gbm" else DoubleTensorType
    final = result.estimator[-1] if hasattr(result.estimator, "steps") else result.estimator
    options: dict[Any, Any] = {}
    if result.task == "classification":
        options[id(final)] = {"zipmap": False}
    if kind == "gpr":
        # by hand: skl2onnx's graph multiplies k* by the full K^-1 (module gpr_graph)
        proto = gpr_graph(result.estimator, len(schema.names), _OPSET)
    else:
        proto = to_onnx(
            result.estimator,
            initial_types=[("features", tensor([None, len(schema.names)]))],
            options=options or None,
            target_opset=_OPSET,
        )
    graph = proto.graph
    outputs: dict[str, str] = {}
    if result.task == "classification":
        outputs = {"label": graph.output[0].name, "probabilities": graph.output[1].name}
    else:
        outputs = _unscale(graph, result.y_scale, with_std=kind == "gpr")
    description = {
        "kind": kind,
        "task": result.task,
        "target": result.report["target"],
        "classes": result.classes,
        "band_level": BAND_LEVEL if result.task == "regression" else None,
        "band": result.band if result.task == "regression" else None,
        "band_form": "k * std" if kind == "gpr" else "+- half_width",
        "outputs": outputs,
        "input_dtype": np.dtype(dtype).name,
    }
    onnx.helper.set_model_props(
        proto,
        {
            _SCHEMA_KEY: schema.to_json(),
            _MODEL_KEY: finite_json.dumps(description),
            _REPORT_KEY: finite_json.dumps(result.report),
        },
    )
    proto.producer_name = "cnctwin.learn"
    onnx.checker.check_model(proto)
    path = Path(path)
    path.write_bytes(proto.SerializeToString())
    return path


def _unscale(graph: Any, y_scale: tuple[float, float], with_std: bool) -> dict[str, str]:
    """Append ``prediction = mean + scale * output`` (and ``std = scale * std``) to a
    regression graph fitted on a standardised target; returns the output names."""
    from onnx import helper

    mean, scale = y_scale
    mu = graph.output[0].name
    dtype = graph.output[0].type.tensor_type.elem_type
    graph.initializer.extend(
        [
            helper.make_tensor("cnctwin_y_scale", dtype, [], [scale]),
            helper.make_tensor("cnctwin_y_mean", dtype, [], [mean]),
        ]
    )
    nodes = [
        helper.make_node("Mul", [mu, "cnctwin_y_scale"], ["cnctwin_mu_scaled"]),
        helper.make_node("Add", ["cnctwin_mu_scaled", "cnctwin_y_mean"], ["prediction"]),
    ]
    outputs = [_renamed(graph.output[0], "prediction")]
    if with_std:
        nodes.append(helper.make_node("Mul", [graph.output[1].name, "cnctwin_y_scale"], ["std"]))
        outputs.append(_renamed(graph.output[1], "std"))
    graph.node.extend(nodes)
    del graph.output[:]
    graph.output.extend(outputs)
    names = {"prediction": "prediction"}
    if with_std:
        names["std"] = "std"
    return names


def _renamed(value_info: Any, name: str) -> Any:
    """A graph output's type under another name (a column ``[N]`` where it has no shape)."""
    from onnx import helper

    tensor = value_info.type.tensor_type
    if tensor.HasField("shape"):
        copy = type(value_info)()
        copy.CopyFrom(value_info)
        copy.name = name
        return copy
    return helper.make_tensor_value_info(name, tensor.elem_type, [None])


@dataclass
class Predictor:
    """A model file loaded for inference, its schema checked.

    Attributes
    ----------
    path
        The file.
    schema
        The feature schema stored in it.
    model
        Its description: ``kind``, ``task``, ``target``, ``classes``, ``band``, ``outputs``.
    report
        The training report stored in it.
    """

    path: Path
    schema: FeatureSchema
    model: dict[str, Any]
    report: dict[str, Any]
    _session: Any
    _dtype: type

    @classmethod
    def load(cls, path: str | Path, available: Iterable[str] | None = None) -> Predictor:
        """Load ``path``; with ``available`` (the signals a source offers), check that every
        source signal of the schema is among them.

        Raises
        ------
        cnctwin.errors.InputError
            For a file that cannot be read.
        cnctwin.errors.DataError
            For a file that is not a cnctwin model, an altered schema or a missing signal.
        """
        import onnx
        import onnxruntime as ort

        path = Path(path)
        try:
            raw = path.read_bytes()
        except OSError as err:
            raise InputError(f"{path}: cannot read the model ({err.strerror})") from None
        try:
            proto = onnx.load_from_string(raw)
        except Exception as err:  # onnx raises DecodeError and others for a non-model file
            raise DataError(f"{path}: not an ONNX model ({type(err).__name__})") from None
        props = {p.key: p.value for p in proto.metadata_props}
        if _SCHEMA_KEY not in props or _MODEL_KEY not in props:
            raise DataError(f"{path}: an ONNX model without a cnctwin feature schema")
        schema = FeatureSchema.from_json(props[_SCHEMA_KEY], str(path))
        model = json.loads(props[_MODEL_KEY])
        report = json.loads(props.get(_REPORT_KEY, "{}"))
        if available is not None:
            schema.require_signals(frozenset(available), "the signal source")
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        session = ort.InferenceSession(raw, options, providers=["CPUExecutionProvider"])
        dtype = np.float32 if model.get("input_dtype") == "float32" else np.float64
        return cls(path, schema, model, report, session, dtype)

    def check_schema(self, other: FeatureSchema, where: str) -> None:
        """Refuse features built with another schema than the model's.

        Raises
        ------
        cnctwin.errors.DataError
            When the hashes differ (``where`` names the other schema's origin).
        """
        if other.sha256 != self.schema.sha256:
            raise DataError(
                f"{where}: feature schema {other.sha256[:12]}... differs from the model's "
                f"{self.schema.sha256[:12]}... ({self.path}); build the data with the model's "
                f"schema (omit --features)"
            )

    def predict(self, features: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Run rows of features ``(rows, len(schema.names))``; returns ``prediction`` (target
        unit; a classifier's class index), ``std`` (GPR, target unit), ``band`` (regression:
        half-width of the stated 90 % band, target unit) and ``probabilities``
        (classifier)."""
        x = np.ascontiguousarray(features, dtype=self._dtype)
        if x.ndim != 2 or x.shape[1] != len(self.schema.names):
            raise DataError(
                f"features of shape {x.shape}; the model takes (rows, {len(self.schema.names)})"
            )
        names = self.model["outputs"]
        wanted = list(names.values())
        got = dict(zip(wanted, self._session.run(wanted, {"features": x}), strict=True))
        out: dict[str, NDArray[np.float64]] = {}
        if self.model["task"] == "classification":
            proba = np.asarray(got[names["probabilities"]], dtype=float)
            out["probabilities"] = proba
            out["prediction"] = np.argmax(proba, axis=1).astype(float)
            return out
        out["prediction"] = np.asarray(got[names["prediction"]], dtype=float).reshape(-1)
        band = float(self.model["band"]) if self.model.get("band") is not None else math.nan
        if "std" in names:
            out["std"] = np.asarray(got[names["std"]], dtype=float).reshape(-1)
            out["band"] = band * out["std"]
        else:
            out["band"] = np.full(out["prediction"].size, band)
        return out

    def predict_window(self, features: Mapping[str, float]) -> dict[str, float]:
        """One window's prediction from its features by name (``FeaturePath.update``).

        Returns ``{target: value, target_band: half-width}`` (regression, plus
        ``target_std`` for GPR) or ``{target: class index, target_p_CLASS: probability}``.

        Raises
        ------
        cnctwin.errors.DataError
            When a feature is missing.
        """
        try:
            row = np.array([[features[name] for name in self.schema.names]], dtype=self._dtype)
        except KeyError as err:
            raise DataError(f"window lacks the feature {err.args[0]!r} of {self.path}") from None
        out = self.predict(row)
        target = self.model["target"]
        result = {target: float(out["prediction"][0])}
        if "probabilities" in out:
            for k, label in enumerate(self.model["classes"]):
                result[f"{target}_p_{label}"] = float(out["probabilities"][0, k])
        else:
            result[f"{target}_band"] = float(out["band"][0])
            if "std" in out:
                result[f"{target}_std"] = float(out["std"][0])
        return result

    def describe(self) -> dict[str, Any]:
        """What ``cnctwin learn inspect`` prints: model, schema, hold-out metrics."""
        spec = self.schema.spec
        return {
            "file": str(self.path),
            "model": self.model,
            "schema_sha256": self.schema.sha256,
            "features": [
                {"name": n, "unit": u}
                for n, u in zip(self.schema.names, self.schema.units, strict=True)
            ],
            "sources": list(self.schema.sources),
            "sample_period_s": spec.sample_period_s,
            "filters": {k: v.model_dump() for k, v in spec.filters.items()},
            "windows": [w.model_dump() for w in spec.windows],
            "holdout": self.report.get("holdout"),
            "groups_holdout": self.report.get("groups_holdout"),
        }


def evaluate_model(
    predictor: Predictor, data: Dataset, group_by: str | None = None
) -> dict[str, Any]:
    """Score a loaded model on ``data`` (built with the model's schema).

    Returns the metrics of :func:`~cnctwin.learn.train`'s hold-out (regression: MAE, RMSE,
    R^2, coverage of the stated band; classification: balanced accuracy, ROC AUC, confusion
    matrix) over every row with a target, and per group where ``group_by`` is given.

    Raises
    ------
    cnctwin.errors.DataError
        When ``data`` was built with another schema.
    cnctwin.errors.InputError
        When the target or group column is missing.
    """
    predictor.check_schema(data.schema, "the data")
    target = predictor.model["target"]
    column = data.column(target, "the model's target")
    out = predictor.predict(data.features)
    groups = None if group_by is None else np.asarray(data.column(group_by, "--group-by"))
    report: dict[str, Any] = {"model": str(predictor.path), "target": target}
    if predictor.model["task"] == "classification":
        classes = list(predictor.model["classes"])
        text = np.asarray(column).astype(str)
        known = np.isin(text, classes)
        y = np.array([classes.index(t) for t in text[known]], dtype=int)
        report["metrics"] = _class_metrics(y, out["probabilities"][known], classes)
        return report
    y = np.asarray(column, dtype=float)
    known = np.isfinite(y)
    pred, half = out["prediction"], out["band"]
    inside = np.abs(y - pred) <= half
    report["metrics"] = {
        **_regression_metrics(y[known], pred[known]),
        "band_level": predictor.model["band_level"],
        "band_coverage": float(np.mean(inside[known])),
    }
    if groups is not None:
        report["per_group"] = {
            str(g): _regression_metrics(y[known & (groups == g)], pred[known & (groups == g)])
            for g in sorted(set(groups[known].tolist()))
        }
    return report
