"""Benchmark: does a gradient-boosting library beat scikit-learn's own? (issue 13, item 3)

On the shipped real-data studies, each group left out in turn (``examples/learn/nasa_wear.toml``:
NASA milling flank wear VB by case; ``examples/learn/umich_load.toml``: UMich X-axis current
by experiment), three regressors, each tuned on grouped folds of the other groups only (the
same grid of depth and learning rate, 150 trees, rows 0.8 subsampled where the library
offers it):

- ``sk_gb``: scikit-learn's ``GradientBoostingRegressor``, the project's ``gbm``;
- ``sk_hgb``: scikit-learn's ``HistGradientBoostingRegressor``;
- ``lgbm``: LightGBM's ``LGBMRegressor`` (one thread), when LightGBM is installed (it is no
  dependency of cnctwin; without it the row is left out and the output says so).

Per library: MAE, RMSE and R^2 over all left-out rows, CPU time, and against ``sk_gb`` the
groups where it is better and the Wilcoxon signed-rank p-value of the per-group MAE
differences ("measurably better": lower pooled MAE and p < 0.05). Inputs are rounded to
float32, as the ONNX trees read them.

Usage: ``python benchmarks/bench_gbm_libraries.py [--quick]`` (the data in ``$CNCTWIN_DATA``
or ``../shared/data``). ``--quick`` (CI): NASA only, two grid points.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.learn import (
    FeatureSchema,
    build_dataset,
    grouped_folds,
    load_feature_spec,
    read_runs,
    read_table,
)

REPO = Path(__file__).resolve().parents[1]
Arrays = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.str_]]


def _data_root() -> Path:
    return Path(os.environ.get("CNCTWIN_DATA") or REPO.parent / "shared" / "data")


def study_data(name: str) -> Arrays:
    """Features (float32-rounded), target and groups of one shipped study."""
    root = _data_root()
    if name == "umich_load":
        folder = root / "umich_cnc_mill_tool_wear"
        labels = folder / "train.csv"
        spec, target, group = "umich_load.toml", "X1_CurrentFeedback", "run"
        runs = read_runs([str(folder)], exclude=[labels])
        table = read_table(labels)
        key: str | None = "No"
    else:
        spec, target, group = "nasa_wear.toml", "VB", "case"
        runs = read_runs([str(root / "nasa_milling" / "labels_with_tool_class.csv")])
        table, key = None, None
    schema = FeatureSchema.from_spec(load_feature_spec(REPO / "examples" / "learn" / spec))
    data = build_dataset(runs, schema, table, key)
    y = np.asarray(data.columns[target], dtype=float)
    g = np.asarray(data.columns[group]).astype(str)
    ok = np.isfinite(y)
    return data.features[ok].astype(np.float32).astype(float), y[ok], g[ok]


def libraries() -> list[str]:
    """The libraries to compare: scikit-learn's two, and LightGBM where installed."""
    try:
        import lightgbm  # noqa: F401
    except ImportError:
        return ["sk_gb", "sk_hgb"]
    return ["sk_gb", "sk_hgb", "lgbm"]


def make(lib: str, depth: int, rate: float) -> Any:
    """One regressor of ``lib`` with tree depth ``depth`` and learning rate ``rate``."""
    if lib == "sk_gb":
        from sklearn.ensemble import GradientBoostingRegressor

        return GradientBoostingRegressor(
            max_depth=depth, learning_rate=rate, n_estimators=150, subsample=0.8, random_state=0
        )
    if lib == "sk_hgb":
        from sklearn.ensemble import HistGradientBoostingRegressor

        return HistGradientBoostingRegressor(
            max_depth=depth, learning_rate=rate, max_iter=150, random_state=0
        )
    import lightgbm

    return lightgbm.LGBMRegressor(
        max_depth=depth, num_leaves=2**depth, learning_rate=rate, n_estimators=150,
        subsample=0.8, subsample_freq=1, min_child_samples=5, random_state=0, verbose=-1,
        n_jobs=1,
    )  # fmt: skip


def leave_one_group_out(lib: str, data: Arrays, grid: list[tuple[int, float]]) -> NDArray[Any]:
    """Each group's predictions by a model tuned (RMSE on 3 grouped folds) without it."""
    x, y, g = data
    pred = np.full(y.size, np.nan)
    for held in sorted(set(g.tolist())):
        train = g != held
        xt, yt, gt = x[train], y[train], g[train]
        scores = []
        for depth, rate in grid:
            errors = []
            for a, b in grouped_folds(gt.astype(object), 3):
                model = make(lib, depth, rate).fit(xt[a], yt[a])
                errors.append(float(np.sqrt(np.mean((model.predict(xt[b]) - yt[b]) ** 2))))
            scores.append(float(np.mean(errors)))
        depth, rate = grid[int(np.argmin(scores))]
        pred[~train] = make(lib, depth, rate).fit(xt, yt).predict(x[~train])
    return pred


def compare(name: str, grid: list[tuple[int, float]]) -> dict[str, Any]:
    """The figures of every library on one study."""
    from scipy.stats import wilcoxon

    data = study_data(name)
    _, y, g = data
    groups = sorted(set(g.tolist()))
    out: dict[str, Any] = {"rows": int(y.size), "groups": len(groups)}
    per_group: dict[str, NDArray[np.float64]] = {}
    for lib in libraries():
        started = time.process_time()
        pred = leave_one_group_out(lib, data, grid)
        residual = y - pred
        per_group[lib] = np.array([np.mean(np.abs(residual[g == k])) for k in groups])
        out[lib] = {
            "mae": float(np.mean(np.abs(residual))),
            "rmse": float(np.sqrt(np.mean(residual**2))),
            "r2": 1.0 - float(np.sum(residual**2) / np.sum((y - y.mean()) ** 2)),
            "cpu_s": time.process_time() - started,
        }
        if lib != "sk_gb":
            diff = per_group[lib] - per_group["sk_gb"]
            out[lib]["groups_better_than_sk_gb"] = int(np.sum(diff < 0))
            out[lib]["wilcoxon_p_vs_sk_gb"] = float(wilcoxon(diff).pvalue)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="CI: NASA only, two grid points")
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    grid = [(2, 0.1), (3, 0.1)] if args.quick else list(itertools.product([2, 3, 4], [0.05, 0.1]))
    studies = ["nasa_wear"] if args.quick else ["nasa_wear", "umich_load"]
    report: dict[str, Any] = {"libraries": libraries(), "grid_depth_rate": grid}
    if "lgbm" not in report["libraries"]:
        report["note"] = "LightGBM is not installed: only scikit-learn's two are compared"
    for name in studies:
        report[name] = compare(name, grid)
    report["load"] = " ".join(f"{v:.1f}" for v in os.getloadavg())
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
