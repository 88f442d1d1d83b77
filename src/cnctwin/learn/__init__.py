"""Learned models for the twin: a feature schema, the one feature path, datasets, grouped
training, ONNX model files.

Public API::

    from cnctwin.learn import (FeatureSchema, load_feature_spec, FeaturePath, read_runs,
                               read_table, build_dataset, train, export_onnx, Predictor)

    schema = FeatureSchema.from_spec(load_feature_spec("examples/learn/umich_power.toml"))
    data = build_dataset(read_runs(["experiments/"]), schema, read_table("labels.csv"), "No")
    result = train(data, "S1_OutputPower", "gbm", "run")   # grouped tuning and hold-out
    outcome = outcomes(read_table("labels.csv"), "No", "machining_finalized")
    study = lead_time_study(read_runs(["experiments/"]), schema, outcome,
                            AlarmRule("no", "Machining_Process", "Layer"))  # early warning
    export_onnx(result, schema, "power.onnx")
    model = Predictor.load("power.onnx", available=signal_names)   # schema checked
    path = FeaturePath(model.schema)
    model.predict_window(path.update(sample))                       # one window

The schema, the feature path and the datasets need numpy and scipy; training imports
scikit-learn, model files skl2onnx, onnx and onnxruntime, each on first use. See docs/learn.md.
"""

from typing import TYPE_CHECKING

from cnctwin import _lazy
from cnctwin.learn.dataset import Dataset, Run, build_dataset, read_runs, read_table
from cnctwin.learn.features import FeaturePath, make_filter
from cnctwin.learn.schema import (
    WINDOW_FEATURES,
    FeatureSchema,
    FeatureSpec,
    FilterSpec,
    InvalidWhen,
    WindowSpec,
    load_feature_spec,
)
from cnctwin.learn.splits import grouped_folds, holdout_groups

if TYPE_CHECKING:
    from cnctwin.learn.figures import plot_lead_time, plot_report
    from cnctwin.learn.lead_time import AlarmRule, LeadTimeResult, lead_time_study, outcomes
    from cnctwin.learn.onnx_model import Predictor, evaluate_model, export_onnx
    from cnctwin.learn.training import (
        BAND_LEVEL,
        MODELS,
        TrainResult,
        leave_one_group_out,
        train,
    )

__all__ = [
    "BAND_LEVEL",
    "AlarmRule",
    "MODELS",
    "WINDOW_FEATURES",
    "Dataset",
    "FeaturePath",
    "FeatureSchema",
    "FeatureSpec",
    "FilterSpec",
    "InvalidWhen",
    "LeadTimeResult",
    "Predictor",
    "Run",
    "TrainResult",
    "WindowSpec",
    "build_dataset",
    "evaluate_model",
    "export_onnx",
    "grouped_folds",
    "holdout_groups",
    "lead_time_study",
    "leave_one_group_out",
    "load_feature_spec",
    "make_filter",
    "outcomes",
    "plot_lead_time",
    "plot_report",
    "read_runs",
    "read_table",
    "train",
]

_LAZY = {
    "BAND_LEVEL": "training",
    "MODELS": "training",
    "TrainResult": "training",
    "train": "training",
    "leave_one_group_out": "training",
    "Predictor": "onnx_model",
    "export_onnx": "onnx_model",
    "evaluate_model": "onnx_model",
    "plot_report": "figures",
    "plot_lead_time": "figures",
    "AlarmRule": "lead_time",
    "LeadTimeResult": "lead_time",
    "lead_time_study": "lead_time",
    "outcomes": "lead_time",
}

# scikit-learn, skl2onnx, onnxruntime and matplotlib load only when a model is trained,
# written, run or drawn.
__getattr__, __dir__ = _lazy.exports(__name__, _LAZY)
