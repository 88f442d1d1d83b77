"""Benchmark of learned-model inference per window (issue 13, item 8).

Usage: ``python benchmarks/bench_learn.py [--quick]``. Trains each model kind with
:func:`cnctwin.learn.train` on synthetic grouped data (8 features: 5 signals, a window's
mean and RMS, a slope), writes it with :func:`cnctwin.learn.export_onnx`, loads it with
:class:`cnctwin.learn.Predictor` and times one window as the twin will run it:
``predict_window`` on the features :meth:`cnctwin.learn.FeaturePath.update` gives (onnxruntime,
one thread). Prints a Markdown table of the median and 99th percentile per window (wall
time and the thread's CPU time), and the time of the feature path's ``update`` itself.

Targets: gbm and mlp under 0.2 ms, GPR with 2,000 training points under 1 ms (p99, with its
standard deviation in double). ``--quick`` (CI) uses 1,000 rows, a trained GPR of 150 points
and fewer repetitions. The full run's trained GPR fits its kernel on 2,000 points four times
(three folds and the final fit): tens of minutes on a loaded 2-core machine. Both runs also
time a GPR of ``--gpr-fixed`` points (default 2,000) with a fixed kernel (RBF of length scale 1
on each feature: a spectrum that does not decay, so the graph holds ``L^-1`` in blocks) and,
when the trained GPR ran, one of as many points with the trained GPR's kernel (fitted by
marginal likelihood: long length scales on the features the target does not depend on, a
spectrum that decays, so the graph's variance is low-rank; ``cnctwin.learn.gpr_graph``). The
time per window depends on the number of points and on the kernel's spectrum; the lines below
the table say which variance form each GPR's graph holds.
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import onnx

from cnctwin.learn import (
    Dataset,
    FeaturePath,
    FeatureSchema,
    FeatureSpec,
    Predictor,
    TrainResult,
    build_dataset,
    export_onnx,
    load_feature_spec,
    read_runs,
    train,
)

SPEC = FeatureSpec.model_validate(
    {
        "sample_period_s": 0.0125,
        "signals": {
            "feed_mm_min": "mm/min",
            "spindle_rpm": "rpm",
            "ae_mm": "mm",
            "ap_mm": "mm",
            "spindle_power_w": "W",
        },
        "filters": {"spindle_power_w": {"kind": "hampel", "window": 7}},
        "windows": [
            {"signal": "spindle_power_w", "length": 80, "features": ["mean", "rms", "slope"]}
        ],
    }
)


def dataset(rows: int, seed: int = 0) -> Dataset:
    """Rows of a smooth load with group offsets and noise, 10 groups."""
    schema = FeatureSchema.from_spec(SPEC)
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 1.0, size=(rows, len(schema.names)))
    y = 2 * x[:, 0] * x[:, 2] + np.sin(3 * x[:, 3]) + 0.1 * rng.normal(size=rows)
    groups = np.array([f"g{k % 10}" for k in range(rows)], dtype=object)
    return Dataset(schema, x, {"run": groups, "torque_nm": y})


def time_windows(model: Predictor, repeats: int) -> tuple[float, float, float, float, float]:
    """Median and p99 of one ``predict_window``, its CPU-time median and p99 (ms), and the
    CPU p99 of ``update`` (ms). CPU time (``time.thread_time``; onnxruntime runs in the
    calling thread with one intra-op thread) leaves out what the loaded machine's scheduler
    gave to others."""
    path = FeaturePath(model.schema)
    rng = np.random.default_rng(1)
    samples = [
        {name: float(v) for name, v in zip(SPEC.signals, rng.uniform(0, 1, 5), strict=True)}
        for _ in range(repeats)
    ]
    windows = [path.update(s) for s in samples[:100]]
    for features in windows[:50]:
        model.predict_window(features)  # warm-up
    predict, predict_cpu, update = [], [], []
    for k, sample in enumerate(samples):
        c0 = time.thread_time()
        features = path.update(sample, k * 0.0125)
        c1 = time.thread_time()
        t1 = time.perf_counter()
        model.predict_window(features)
        t2 = time.perf_counter()
        c2 = time.thread_time()
        update.append(c1 - c0)
        predict.append(t2 - t1)
        predict_cpu.append(c2 - c1)
    ms = np.array(predict) * 1e3
    return (
        float(np.median(ms)),
        float(np.percentile(ms, 99)),
        float(np.median(np.array(predict_cpu) * 1e3)),
        float(np.percentile(np.array(predict_cpu) * 1e3, 99)),
        float(np.percentile(np.array(update) * 1e3, 99)),
    )


def fixed_kernel_gpr(
    data: Dataset, target: str, points: int, kernel: Any | None = None
) -> TrainResult:
    """A GPR on ``points`` evenly spaced rows of ``data`` with a fixed RBF + white kernel
    (no marginal-likelihood fit, which takes minutes at 2,000 points; by default length scale 1
    on each scaled feature and noise 0.1), in the form :func:`train` gives, for timing."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, WhiteKernel
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    y_all = np.asarray(data.columns[target], dtype=float)
    rows = np.flatnonzero(np.isfinite(y_all) & np.all(np.isfinite(data.features), axis=1))
    if rows.size < points:
        raise SystemExit(f"{points} GPR points asked for, the data has {rows.size} rows")
    pick = rows[np.linspace(0, rows.size - 1, points).round().astype(int)]
    x, y = data.features[pick], y_all[pick]
    if kernel is None:
        kernel = RBF(np.ones(x.shape[1])) + WhiteKernel(0.1)
    gpr = GaussianProcessRegressor(kernel, optimizer=None, normalize_y=False)
    estimator = make_pipeline(StandardScaler(), gpr).fit(x, (y - y.mean()) / y.std())
    report = {"model": "gpr", "target": target, "training_rows": points}
    return TrainResult(estimator, "regression", [], (y.mean(), y.std()), 1.645, report, {})


def write_twin_gpr(points: int, path: Path) -> None:
    """Write a GPR of ``points`` rows with a fixed kernel on the twin's model example
    (``examples/twin_model``: force Y from the spindle power and the feed, 12.5 ms), for
    ``bench_twin_cycle.py --model``."""
    folder = Path(__file__).resolve().parents[1] / "examples" / "twin_model"
    schema = FeatureSchema.from_spec(load_feature_spec(folder / "features.toml"))
    data = build_dataset(read_runs([str(folder)]), schema)
    export_onnx(fixed_kernel_gpr(data, "force_y_n", points), schema, path)
    print(f"wrote {path}: a GPR of {points} points on {folder}")


def main() -> None:
    """Train, export, load and time each model kind; print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small GPR, fewer repetitions")
    parser.add_argument("--models", default="linear,gbm,mlp,gpr", help="comma-separated kinds")
    parser.add_argument(
        "--gpr-fixed",
        type=int,
        default=2000,
        metavar="POINTS",
        help="also time a GPR of POINTS rows with a fixed kernel (0: none)",
    )
    parser.add_argument(
        "--write-twin-gpr",
        type=Path,
        metavar="OUT.onnx",
        help="only write a GPR of --gpr-fixed points on examples/twin_model (for "
        "bench_twin_cycle.py --model) and stop",
    )
    args = parser.parse_args()
    if args.write_twin_gpr is not None:
        write_twin_gpr(args.gpr_fixed, args.write_twin_gpr)
        return
    repeats = 500 if args.quick else 5000
    gpr_points = 150 if args.quick else 2000
    rows = 1000 if args.quick else 4000
    cases = [("linear", rows), ("gbm", rows), ("mlp", rows), ("gpr", int(gpr_points / 0.7) + 10)]
    print(f"machine: {platform.machine()}, {os.cpu_count()} CPUs; loadavg {os.getloadavg()}")
    print()
    print(
        "| model | training rows | train s | predict_window median ms | p99 ms | CPU median ms "
        "| CPU p99 ms | feature update CPU p99 ms |"
    )
    print("|---|---|---|---|---|---|---|---|")
    forms = []
    trained_kernel = None
    with tempfile.TemporaryDirectory() as folder:
        for kind, rows in [c for c in cases if c[0] in args.models.split(",")]:
            data = dataset(rows)
            t0 = time.perf_counter()
            result = train(data, "torque_nm", kind, "run", quick=True, max_gpr_points=gpr_points)
            trained_s = time.perf_counter() - t0
            path = export_onnx(result, data.schema, Path(folder) / f"{kind}.onnx")
            if kind == "gpr":
                trained_kernel = result.estimator[-1].kernel_
                forms.append(f"gpr: {onnx.load(path).graph.doc_string}")
            model = Predictor.load(path)
            median, p99, cpu_median, cpu_p99, update = time_windows(model, repeats)
            print(
                f"| {kind} | {result.report['training_rows']} | {trained_s:.1f} | "
                f"{median:.3f} | {p99:.3f} | {cpu_median:.3f} | {cpu_p99:.3f} | {update:.3f} |"
            )
        kernels = [("fixed kernel", None)] if args.gpr_fixed else []
        if args.gpr_fixed and trained_kernel is not None:
            kernels.append(("trained kernel", trained_kernel))
        for label, kernel in kernels:
            t0 = time.perf_counter()
            data = dataset(args.gpr_fixed)
            result = fixed_kernel_gpr(data, "torque_nm", args.gpr_fixed, kernel)
            trained_s = time.perf_counter() - t0
            path = export_onnx(result, data.schema, Path(folder) / "fixed.onnx")
            forms.append(f"gpr, {label}: {onnx.load(path).graph.doc_string}")
            model = Predictor.load(path)
            median, p99, cpu_median, cpu_p99, update = time_windows(model, repeats)
            print(
                f"| gpr, {label} | {args.gpr_fixed} | {trained_s:.1f} | "
                f"{median:.3f} | {p99:.3f} | {cpu_median:.3f} | {cpu_p99:.3f} | {update:.3f} |"
            )
    print()
    for form in forms:
        print(f"- {form}")


if __name__ == "__main__":
    main()
