"""The model stage: a learned model (``[[twin.models]]``) run on every sample of the cycle.

A model file of ``cnctwin learn train`` (:mod:`cnctwin.learn.onnx_model`) carries its
feature schema. The stage feeds each new sample, its measured signals and the predictions
of the stages before it (``predicted_force_xy_n``, ...), to the schema's one feature path
(:class:`cnctwin.learn.FeaturePath`, the same code that built the training data) and runs
the window's features once through onnxruntime (:class:`cnctwin.learn.Predictor`).

Names the stage adds to :attr:`CycleState.predicted` for a model named ``NAME``:

- regression: ``NAME`` (the target's unit), ``NAME_band`` (half-width of the model's
  stated 90 % band), ``NAME_low``, ``NAME_high`` (its edges), ``NAME_std`` (GPR only);
- classification: ``NAME`` (class index), ``NAME_p_CLASS`` (probabilities, 0-1);
- ``NAME_ready``: 1 once every feature is finite (the windows have seen a sample), else 0;
  until then the other names are NaN (a rule reading NaN does not fire).

The model is refused at start (:func:`load_models`) when its schema reads a signal the
twin cannot supply, or was built at another sample period than the twin's cycle.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from cnctwin.errors import ConfigError, DataError, InputError
from cnctwin.thread import SIGNALS
from cnctwin.twin.settings import ModelConfig, TwinSettings
from cnctwin.twin.stages import PREDICTIONS
from cnctwin.twin.state import CycleState

if TYPE_CHECKING:
    from cnctwin.learn import FeaturePath, Predictor

__all__ = ["LoadedModel", "ModelStage", "load_models", "model_meta"]

#: Relative tolerance between a schema's sample period and the twin's cycle.
_PERIOD_RTOL = 1e-6


def _file_sha256(path: Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    with path.open("rb") as fh:
        return hashlib.file_digest(fh, "sha256").hexdigest()


@dataclass(frozen=True)
class LoadedModel:
    """A ``[[twin.models]]`` entry loaded and checked.

    Attributes
    ----------
    name
        Its prediction name.
    predictor
        The model file, its schema and onnxruntime session.
    outputs
        The prediction names the stage adds.
    """

    name: str
    predictor: Predictor
    outputs: tuple[str, ...]


def _outputs(name: str, predictor: Predictor) -> tuple[str, ...]:
    model = predictor.model
    if model["task"] == "classification":
        return (name, *(f"{name}_p_{c}" for c in model["classes"]), f"{name}_ready")
    std = ("std" in model["outputs"]) * (f"{name}_std",)
    return (name, f"{name}_band", f"{name}_low", f"{name}_high", *std, f"{name}_ready")


def load_models(settings: TwinSettings) -> list[LoadedModel]:
    """Load every ``[[twin.models]]`` entry of ``settings`` and check it against what the twin
    supplies: the canonical signals (:data:`cnctwin.thread.SIGNALS`), the predictions of the
    stages before the models (:data:`~cnctwin.twin.stages.PREDICTIONS`) and the models before
    it; its schema's ``sample_period_s`` must equal ``cycle_s`` (filters and windows count
    samples).

    Raises
    ------
    cnctwin.errors.ConfigError
        One line naming the entry and the file: a duplicate name, a feature whose signal the
        twin cannot supply (naming it), another sample period, an unreadable or foreign file.
    """
    from cnctwin.learn import Predictor

    cycle_s = settings.cycle_s
    names = {*SIGNALS, *PREDICTIONS}
    loaded: list[LoadedModel] = []
    for k, cfg in enumerate(settings.models):
        where = f"twin.models[{k}] ({cfg.path})"
        if cfg.name in names:
            raise ConfigError(
                f"{where}: name {cfg.name!r} is already a signal, prediction or model; "
                "give another name"
            )
        try:
            predictor = Predictor.load(cfg.path)
        except (DataError, InputError) as err:
            raise ConfigError(f"{where}: {err}") from None
        schema = predictor.schema
        missing = [s for s in schema.sources if s not in names]
        if missing:
            signal = missing[0]
            reads = (
                n for n in schema.names if n == signal or n.startswith((f"{signal}_", f"{signal}="))
            )
            feature = next(reads, signal)
            raise ConfigError(
                f"{where}: the model's feature {feature!r} reads the signal {signal!r}, which "
                "this twin does not supply; train on signals the twin records (the canonical "
                "signals of cnctwin.thread.SIGNALS and the predictions of docs/twin.md)"
            )
        period = schema.spec.sample_period_s
        if not math.isclose(period, cycle_s, rel_tol=_PERIOD_RTOL):
            raise ConfigError(
                f"{where}: the model's features were built at a sample period of {period:g} s "
                f"but the twin cycles every {cycle_s:g} s; train on runs recorded at "
                f"[twin] cycle_s (set sample_period_s = {cycle_s:g} in the feature spec)"
            )
        model = LoadedModel(cfg.name, predictor, _outputs(cfg.name, predictor))
        names.update(model.outputs)
        loaded.append(model)
    return loaded


def model_meta(configs: Sequence[ModelConfig]) -> list[dict[str, str]]:
    """What a run records of its ``[[twin.models]]``: name, file and the file's SHA-256."""
    return [
        {"name": cfg.name, "path": str(cfg.path), "sha256": _file_sha256(cfg.path)}
        for cfg in configs
    ]


class ModelStage:
    """Step 9c: one learned model, one inference per new sample.

    Parameters
    ----------
    model
        The loaded model (:func:`load_models`).
    """

    per_sample = True

    def __init__(self, model: LoadedModel) -> None:
        from cnctwin.learn import FeaturePath

        self.model = model
        self.name = f"model_{model.name}"
        self.path: FeaturePath = FeaturePath(model.predictor.schema)
        self._target = model.predictor.model["target"]
        self._nan = dict.fromkeys(model.outputs, math.nan)
        self._nan[f"{model.name}_ready"] = 0.0

    def forget(self) -> None:
        """Start the filters and windows afresh (after a gap in the connection)."""
        self.path.reset()

    def process(self, state: CycleState) -> CycleState:
        """Add the model's predictions (see the module notes) for this sample."""
        if not state.connected:
            return state
        sample = {**state.measured, **state.predicted}
        # the historian's time of the sample (what a dataset of recorded runs windows over)
        t = state.received_s if math.isfinite(state.received_s) else state.deadline_s
        features = self.path.update(sample, t)
        p = state.predicted
        if not all(math.isfinite(v) for v in features.values()):
            p.update(self._nan)
            return state
        out = self.model.predictor.predict_window(features)
        name = self.model.name
        value = out.pop(self._target)
        p[name] = value
        if f"{self._target}_band" in out:
            band = out[f"{self._target}_band"]
            p.update(
                {
                    f"{name}_band": band,
                    f"{name}_low": value - band,
                    f"{name}_high": value + band,
                }
            )
            if f"{self._target}_std" in out:
                p[f"{name}_std"] = out[f"{self._target}_std"]
        else:
            prefix = f"{self._target}_p_"
            p.update({f"{name}_p_{k[len(prefix) :]}": v for k, v in out.items()})
        p[f"{name}_ready"] = 1.0
        return state
