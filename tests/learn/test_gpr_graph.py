"""The hand-built GPR graph against scikit-learn's predict(return_std=True) and against the
closed form of the posterior (Rasmussen & Williams 2006, eqs. 2.25-2.26) solved with numpy."""

from __future__ import annotations

import numpy as np
import pytest

from cnctwin.errors import InputError
from cnctwin.learn.gpr_graph import BLOCK_ROWS, gpr_graph


def _fit(points: int, noise: float, seed: int = 0):
    """A scaler + GPR pipeline on a smooth function of 3 inputs (fixed kernel: no fit)."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, WhiteKernel
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    rng = np.random.default_rng(seed)
    x = rng.uniform([0, 1, 100], [1, 3, 500], size=(points, 3))
    y = np.sin(3 * x[:, 0]) * x[:, 1] + 0.002 * x[:, 2] + 0.05 * rng.normal(size=points)
    kernel = RBF([0.7, 1.3, 2.0]) + WhiteKernel(noise)
    gpr = GaussianProcessRegressor(kernel, optimizer=None, normalize_y=False)
    return make_pipeline(StandardScaler(), gpr).fit(x, y), x, y


def _run(model, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    import onnxruntime as ort

    session = ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"])
    mean, std = session.run(["GPmean", "GPstd"], {"features": x})
    return mean.reshape(-1), std.reshape(-1)


def _closed_form(pipeline, x_train, y, x) -> tuple[np.ndarray, np.ndarray]:
    """Posterior mean and variance by hand: the RBF in numpy, one dense solve."""
    scaler, gpr = pipeline[0], pipeline[-1]
    lengths = np.array([0.7, 1.3, 2.0])
    noise = gpr.kernel_.k2.noise_level

    def scaled(a: np.ndarray) -> np.ndarray:
        return (a - scaler.mean_) / scaler.scale_ / lengths

    def rbf(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.exp(-0.5 * np.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=2))

    a, b = scaled(x_train), scaled(x)
    k_mat = rbf(a, a) + (noise + gpr.alpha) * np.eye(len(a))
    k_star = rbf(b, a)
    solved = np.linalg.solve(k_mat, np.column_stack([y, k_star.T]))
    mean = k_star @ solved[:, 0]
    var = 1.0 + noise - np.sum(k_star.T * solved[:, 1:], axis=0)
    return mean, var


@pytest.mark.parametrize(("points", "noise"), [(2 * BLOCK_ROWS + 45, 1e-2), (60, 1e-3)])
def test_graph_equals_sklearn_and_the_closed_form(points: int, noise: float) -> None:
    from cnctwin.learn.onnx_model import _OPSET

    pipeline, x_train, y = _fit(points, noise)
    model = gpr_graph(pipeline, 3, _OPSET)
    # held-out rows: another draw, some beyond the training range
    x = np.random.default_rng(7).uniform([-0.2, 0.8, 80], [1.2, 3.2, 520], size=(200, 3))
    mean, std = _run(model, x)
    want_mean, want_std = pipeline.predict(x, return_std=True)
    scale = np.max(np.abs(want_mean))
    np.testing.assert_allclose(mean, want_mean, rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(std, want_std, rtol=1e-9)
    form_mean, form_var = _closed_form(pipeline, x_train, y, x)
    np.testing.assert_allclose(mean, form_mean, rtol=1e-8, atol=1e-8 * scale)
    np.testing.assert_allclose(std**2, form_var, rtol=1e-8)
    # the graph reads L^-1 in blocks: it holds about half of the n x n matrix
    held = sum(int(np.prod(t.dims)) for t in model.graph.initializer if "linv" in t.name)
    assert held == sum(
        min(s + BLOCK_ROWS, points) * (min(s + BLOCK_ROWS, points) - s)
        for s in range(0, points, BLOCK_ROWS)
    )


def test_other_kernel_refused() -> None:
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import Matern
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    x = np.linspace(0, 1, 20).reshape(-1, 1)
    pipeline = make_pipeline(StandardScaler(), GaussianProcessRegressor(Matern())).fit(x, x[:, 0])
    with pytest.raises(InputError, match="supports RBF \\+ WhiteKernel"):
        gpr_graph(pipeline, 1, {"": 17})
