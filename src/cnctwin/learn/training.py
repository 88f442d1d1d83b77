"""Training as a user job: grouped tuning, a hold-out of whole groups, calibration, a report.

:func:`train` takes a :class:`~cnctwin.learn.Dataset`, a target column, a model kind and
the column of groups. It

1. holds out whole groups (:func:`~cnctwin.learn.holdout_groups`), never seen in tuning;
2. tunes the model's few hyper-parameters on grouped folds of the other groups
   (:func:`~cnctwin.learn.grouped_folds`; GPR's kernel by its marginal likelihood);
3. calibrates the stated 90 % band on the folds' out-of-fold residuals (a split-conformal
   band, Lei et al. 2018, "Distribution-free predictive inference for regression", Sec. 2.2:
   the 90 % quantile of ``|residual|``, for GPR of ``|residual| / std``);
4. refits on all tuning groups and scores the held-out groups: MAE, RMSE, R^2 and the band's
   coverage for a regression; balanced accuracy, ROC AUC and the confusion matrix for a
   classification.

Models (scikit-learn): ``linear`` (ridge / logistic regression on standardised features),
``gbm`` (gradient-boosted trees), ``mlp`` (a small multi-layer perceptron), ``gpr``
(Gaussian process, RBF with one length scale per feature plus white noise; regression only;
at most ``max_gpr_points`` training rows, evenly spaced).
"""

from __future__ import annotations

import itertools
import math
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError
from cnctwin.learn.dataset import Dataset, key_of
from cnctwin.learn.splits import grouped_folds, holdout_groups

__all__ = ["BAND_LEVEL", "MODELS", "TrainResult", "leave_one_group_out", "train"]

#: Model kinds.
MODELS = ("gpr", "gbm", "mlp", "linear")
#: Nominal coverage of the stated band.
BAND_LEVEL = 0.9


@dataclass
class TrainResult:
    """A trained model and its report.

    Attributes
    ----------
    estimator
        The fitted scikit-learn estimator (on all tuning groups).
    task
        ``"regression"`` or ``"classification"``.
    classes
        Class labels (classification), in the order of the probability columns.
    y_scale
        GPR, MLP regression: ``(mean, std)`` the target was standardised with; ``(0, 1)``
        otherwise.
    band
        Regression: half-width of the 90 % band in target units (GPR: the factor on the std).
    report
        JSON-ready report (parameters, tuning scores, hold-out metrics, per-group residuals).
    holdout
        Held-out rows: ``y``, ``pred`` (and ``std``, ``proba``) and ``group`` arrays, for the
        figure.
    """

    estimator: Any
    task: str
    classes: list[str]
    y_scale: tuple[float, float]
    band: float
    report: dict[str, Any]
    holdout: dict[str, NDArray[Any]]

    def predict(self, x: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Predictions for rows ``x``: ``prediction`` (target unit; class index for a
        classifier), and ``std`` (GPR) or ``probabilities`` (classifier)."""
        if self.task == "classification":
            proba = self.estimator.predict_proba(x)
            return {"prediction": np.argmax(proba, axis=1).astype(float), "probabilities": proba}
        mean, scale = self.y_scale
        if self.report["model"] == "gpr":
            mu, sd = self.estimator.predict(x, return_std=True)
            return {"prediction": mu * scale + mean, "std": sd * scale}
        pred = self.estimator.predict(_cast(self.report["model"], x))
        return {"prediction": pred * scale + mean}


def _cast(model: str, x: NDArray[np.float64]) -> NDArray[np.float64]:
    """gbm runs in float32 in ONNX; the trees compare float32 inputs in scikit-learn too."""
    return x.astype(np.float32).astype(np.float64) if model == "gbm" else x


def _grid(model: str, task: str, quick: bool) -> list[dict[str, Any]]:
    if model == "linear":
        key = "alpha" if task == "regression" else "C"
        values = [0.1, 10.0] if quick else [0.01, 0.1, 1.0, 10.0, 100.0]
        return [{key: v} for v in values]
    if model == "gbm":
        depths, rates = ([2, 3], [0.1]) if quick else ([2, 3, 4], [0.05, 0.1])
        n = 60 if quick else 150
        return [
            {"max_depth": d, "learning_rate": r, "n_estimators": n}
            for d, r in itertools.product(depths, rates)
        ]
    if model == "mlp":
        sizes = [(16,)] if quick else [(16,), (32, 16)]
        alphas = [1e-2] if quick else [1e-4, 1e-2, 1.0]
        return [{"hidden_layer_sizes": s, "alpha": a} for s, a in itertools.product(sizes, alphas)]
    return [{}]


def _make(model: str, task: str, params: dict[str, Any], n_features: int, seed: int) -> Any:
    from sklearn.ensemble import GradientBoostingClassifier, GradientBoostingRegressor
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, WhiteKernel
    from sklearn.linear_model import LogisticRegression, Ridge
    from sklearn.neural_network import MLPClassifier, MLPRegressor
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    regression = task == "regression"
    if model == "linear":
        est: Any = (
            Ridge(**params)
            if regression
            else LogisticRegression(max_iter=2000, class_weight="balanced", **params)
        )
    elif model == "gbm":
        cls = GradientBoostingRegressor if regression else GradientBoostingClassifier
        return cls(random_state=seed, subsample=0.8, **params)
    elif model == "mlp":
        cls = MLPRegressor if regression else MLPClassifier
        est = cls(solver="lbfgs", max_iter=200, random_state=seed, **params)
    else:
        # no constant kernel and normalize_y=False: the target is standardised by the
        # caller, and the ONNX converter keeps double precision for this form
        kernel = RBF(np.ones(n_features), length_scale_bounds=(1e-2, 1e3)) + WhiteKernel(
            0.1, noise_level_bounds=(1e-6, 1e1)
        )
        est = GaussianProcessRegressor(kernel, normalize_y=False, random_state=seed)
    return make_pipeline(StandardScaler(), est)


def _regression_metrics(y: NDArray[np.float64], pred: NDArray[np.float64]) -> dict[str, float]:
    residual = y - pred
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    return {
        "mae": float(np.mean(np.abs(residual))),
        "rmse": float(math.sqrt(float(np.mean(residual**2)))),
        "r2": 1.0 - float(np.sum(residual**2)) / ss_tot if ss_tot > 0 else math.nan,
        "rows": int(y.size),
    }


def _class_metrics(
    y: NDArray[np.intp], proba: NDArray[np.float64], classes: list[str]
) -> dict[str, Any]:
    from sklearn.metrics import balanced_accuracy_score, confusion_matrix, roc_auc_score

    pred = np.argmax(proba, axis=1)
    present = np.unique(y)
    if present.size < 2:
        auc = math.nan
    elif len(classes) == 2:
        auc = float(roc_auc_score(y, proba[:, 1]))
    else:
        auc = float(roc_auc_score(y, proba, multi_class="ovr", labels=list(range(len(classes)))))
    return {
        "balanced_accuracy": float(balanced_accuracy_score(y, pred)),
        "roc_auc": auc,
        "confusion_matrix": confusion_matrix(y, pred, labels=list(range(len(classes)))).tolist(),
        "confusion_labels": classes,
        "rows": int(y.size),
    }


def _target(data: Dataset, target: str) -> tuple[NDArray[Any], str, list[str], NDArray[np.bool_]]:
    column = data.column(target, "--target")
    if target in data.schema.sources:
        raise InputError(
            f"--target {target!r} is one of the features' source signals; a model would "
            f"read its own answer (remove it from the feature spec)"
        )
    try:
        values = np.asarray(column, dtype=float)
        return values, "regression", [], np.isfinite(values)
    except (TypeError, ValueError):
        text = np.asarray(column).astype(str)
        known = (text != "") & (text != "nan")
        classes = sorted(set(text[known]))
        if len(classes) < 2:
            raise InputError(
                f"--target {target!r} has {len(classes)} class(es); a classifier needs two"
            ) from None
        index = np.array([classes.index(t) if k else -1 for t, k in zip(text, known, strict=True)])
        return index, "classification", classes, known


def train(
    data: Dataset,
    target: str,
    model: str,
    group_by: str,
    *,
    holdout: float = 0.25,
    folds: int = 3,
    seed: int = 0,
    quick: bool = False,
    max_gpr_points: int = 2000,
    holdout_names: Sequence[str] | None = None,
) -> TrainResult:
    """Tune, calibrate and score ``model`` for ``target`` with groups ``group_by``.

    Parameters
    ----------
    data
        The dataset.
    target
        Column to predict: numbers (regression) or text (classification).
    model
        One of :data:`MODELS`.
    group_by
        Column of groups (runs, experiments, cases); a group is never split.
    holdout
        Fraction of the groups held out for the final score.
    folds
        Grouped folds for tuning and calibration.
    seed
        Seed of the hold-out draw and the models.
    quick
        A smaller grid (for tests and documented examples).
    max_gpr_points
        Most training rows a GPR keeps.
    holdout_names
        The groups to hold out, instead of a draw of ``holdout`` of them.

    Raises
    ------
    cnctwin.errors.InputError
        For an unknown model, a missing column, GPR for a classification, too few groups.
    """
    if model not in MODELS:
        raise InputError(f"--model {model!r}; valid models: {', '.join(MODELS)}")
    started = time.perf_counter()
    y_all, task, classes, known = _target(data, target)
    if model == "gpr" and task == "classification":
        raise InputError(
            f"--model gpr predicts numbers; --target {target!r} holds classes (use gbm, mlp "
            f"or linear)"
        )
    groups_all = np.array([key_of(v) for v in data.column(group_by, "--group-by")], dtype=str)
    x_all = data.features
    x, y, groups = x_all[known], y_all[known], groups_all[known]
    if holdout_names is None:
        held = holdout_groups(groups, holdout, seed, y if task == "classification" else None)
    else:
        held = np.isin(groups, list(holdout_names))
        if not held.any() or held.all():
            raise InputError(
                f"held-out groups {list(holdout_names)!r}: give groups of --group-by "
                f"{group_by!r} that leave others to train on"
            )
    xt, yt, gt = x[~held], y[~held], groups[~held]
    if task == "classification" and np.unique(yt).size < len(classes):
        raise InputError(
            f"--target {target!r}: the groups left for training lack a class; give more "
            f"groups or another --seed"
        )
    if model == "gpr" and xt.shape[0] > max_gpr_points:
        pick = np.unique(np.linspace(0, xt.shape[0] - 1, max_gpr_points).round().astype(int))
        xt, yt, gt = xt[pick], yt[pick], gt[pick]
    # GPR and MLP fit a standardised target (the scale is folded into the ONNX graph)
    scaled = task == "regression" and model in ("gpr", "mlp")
    y_scale = (float(yt.mean()), float(yt.std()) or 1.0) if scaled else (0.0, 1.0)
    fit_y = (yt - y_scale[0]) / y_scale[1] if scaled else yt
    folds_list = list(grouped_folds(gt.astype(object), folds))
    n_features = x.shape[1]

    notes: set[str] = set()

    def fit(params: dict[str, Any], rows: NDArray[np.intp]) -> Any:
        est = _make(model, task, params, n_features, seed)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            est.fit(_cast(model, xt[rows]), fit_y[rows])
        # convergence notes go to the report, not to the user's terminal once per fold
        notes.update(str(w.message).splitlines()[0] for w in caught)
        return est

    tuning = []
    best: tuple[float, dict[str, Any]] | None = None
    grid = _grid(model, task, quick)
    for params in grid:
        scores = []
        for train_rows, val_rows in folds_list if len(grid) > 1 else []:
            if task == "classification" and np.unique(fit_y[train_rows]).size < len(classes):
                continue  # a fold without every class cannot fit a classifier
            est = fit(params, train_rows)
            scores.append(_score(est, model, task, xt[val_rows], fit_y[val_rows]))
        score = float(np.mean(scores)) if scores else -math.inf
        tuning.append({"params": _jsonable(params), "score": score if scores else None})
        if best is None or score > best[0]:
            best = (score, params)
    assert best is not None
    params = best[1]
    # out-of-fold predictions with the chosen parameters: the band's calibration
    oof = np.full(yt.size, np.nan)
    oof_std = np.full(yt.size, np.nan)
    for train_rows, val_rows in folds_list if task == "regression" else []:
        est = fit(params, train_rows)
        if model == "gpr":
            mu, sd = est.predict(xt[val_rows], return_std=True)
            oof[val_rows], oof_std[val_rows] = mu * y_scale[1] + y_scale[0], sd * y_scale[1]
        else:
            oof[val_rows] = est.predict(_cast(model, xt[val_rows])) * y_scale[1] + y_scale[0]
    estimator = fit(params, np.arange(yt.size))
    band = math.nan
    if task == "regression":
        ratio = np.abs(yt - oof) / oof_std if model == "gpr" else np.abs(yt - oof)
        band = float(np.quantile(ratio[np.isfinite(ratio)], BAND_LEVEL))
    result = TrainResult(estimator, task, classes, y_scale, band, {"model": model}, {})
    xh, yh, gh = x[held], y[held], groups[held]
    out = result.predict(xh)
    report: dict[str, Any] = {
        "model": model,
        "task": task,
        "target": target,
        "group_by": group_by,
        "features": list(data.schema.names),
        "schema_sha256": data.schema.sha256,
        "rows": int(y.size),
        "training_rows": int(yt.size),
        "groups_tuning": sorted(set(gt.tolist())),
        "groups_holdout": sorted(set(gh.tolist())),
        "folds": len(folds_list),
        "tuning": tuning,
        "chosen": _jsonable(params),
        "seed": seed,
    }
    result.holdout = {"y": yh, "group": gh, **out}
    if task == "regression":
        pred = out["prediction"]
        half = band * out["std"] if model == "gpr" else np.full(yh.size, band)
        inside = np.abs(yh - pred) <= half
        report["holdout"] = {
            **_regression_metrics(yh, pred),
            "band_level": BAND_LEVEL,
            "band_coverage": float(np.mean(inside)),
        }
        report["calibration"] = {
            "band": "k * std" if model == "gpr" else "+- half_width",
            ("k" if model == "gpr" else "half_width"): band,
            "out_of_fold_coverage": float(
                np.mean(np.abs(yt - oof) <= band * (oof_std if model == "gpr" else 1.0))
            ),
            "out_of_fold": _regression_metrics(yt, oof),
        }
        report["per_group"] = {
            g: {
                "rows": int(np.sum(gh == g)),
                "mean_residual": float(np.mean(yh[gh == g] - pred[gh == g])),
                "mae": float(np.mean(np.abs(yh[gh == g] - pred[gh == g]))),
            }
            for g in sorted(set(gh.tolist()))
        }
    else:
        report["classes"] = classes
        report["holdout"] = _class_metrics(yh.astype(int), out["probabilities"], classes)
        report["per_group"] = {
            g: {
                "rows": int(np.sum(gh == g)),
                "true": classes[int(yh[gh == g][0])],
                "predicted_share": float(
                    np.mean(np.argmax(out["probabilities"][gh == g], axis=1) == yh[gh == g])
                ),
            }
            for g in sorted(set(gh.tolist()))
        }
    report["fit_warnings"] = sorted(notes)
    report["train_wall_s"] = time.perf_counter() - started
    result.report = report
    return result


def _score(est: Any, model: str, task: str, x: NDArray[np.float64], y: NDArray[Any]) -> float:
    """Higher is better: minus the RMSE, or the balanced accuracy."""
    from sklearn.metrics import balanced_accuracy_score

    pred = est.predict(_cast(model, x))
    if task == "regression":  # in the fitted (possibly standardised) target's unit
        return -float(math.sqrt(float(np.mean((y - pred) ** 2))))
    return float(balanced_accuracy_score(y, pred))


def _jsonable(params: dict[str, Any]) -> dict[str, Any]:
    return {k: list(v) if isinstance(v, tuple) else v for k, v in params.items()}


def leave_one_group_out(
    data: Dataset,
    target: str,
    model: str,
    group_by: str,
    *,
    folds: int = 3,
    seed: int = 0,
    quick: bool = False,
    max_gpr_points: int = 2000,
) -> dict[str, Any]:
    """Hold out each group in turn and score it with a model tuned on the others.

    Every group's rows are predicted by a model that never saw the group (tuning folds
    included), so the pooled figures are honest over all groups, not one draw.

    Returns
    -------
    dict
        ``per_group`` (the hold-out metrics of each group's model) and ``pooled``: over all
        rows, MAE, RMSE, R^2 and band coverage (regression), or balanced accuracy and ROC
        AUC over the windows and the share of groups whose majority of windows is right
        (classification).
    """
    _, task, classes, known = _target(data, target)
    names = np.array([key_of(v) for v in data.column(group_by, "--group-by")], dtype=str)
    groups = sorted(set(names[known].tolist()))
    per_group: dict[str, Any] = {}
    ys, preds, probas, halves, of_group = [], [], [], [], []
    for group in groups:
        result = train(
            data,
            target,
            model,
            group_by,
            folds=folds,
            seed=seed,
            quick=quick,
            max_gpr_points=max_gpr_points,
            holdout_names=[group],
        )
        per_group[group] = result.report["holdout"]
        hold = result.holdout
        ys.append(hold["y"])
        of_group.append(hold["group"])
        if task == "classification":
            probas.append(hold["probabilities"])
        else:
            preds.append(hold["prediction"])
            std = hold.get("std")
            halves.append(
                result.band * std if std is not None else np.full(hold["y"].size, result.band)
            )
    y = np.concatenate(ys)
    pooled: dict[str, Any]
    if task == "classification":
        proba = np.concatenate(probas)
        pooled = _class_metrics(y.astype(int), proba, classes)
        group_of_row = np.concatenate(of_group)
        right = [
            float(np.mean(np.argmax(proba[group_of_row == g], axis=1) == y[group_of_row == g]))
            > 0.5
            for g in groups
        ]
        pooled["groups_right_by_majority"] = int(sum(right))
        pooled["groups"] = len(groups)
    else:
        pred, half = np.concatenate(preds), np.concatenate(halves)
        pooled = {
            **_regression_metrics(y, pred),
            "band_level": BAND_LEVEL,
            "band_coverage": float(np.mean(np.abs(y - pred) <= half)),
        }
    return {
        "model": model,
        "target": target,
        "group_by": group_by,
        "schema_sha256": data.schema.sha256,
        "pooled": pooled,
        "per_group": per_group,
    }
