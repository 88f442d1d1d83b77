"""The hand-built GPR graph against scikit-learn's predict(return_std=True) and against the
closed form of the posterior (Rasmussen & Williams 2006, eqs. 2.25-2.26) solved with numpy,
in both of its variance forms (low rank with a bound, blocks of L^-1)."""

from __future__ import annotations

import numpy as np
import pytest

from cnctwin.errors import InputError
from cnctwin.learn.gpr_graph import BLOCK_ROWS, VARIANCE_RTOL, gpr_graph, low_rank_cut

#: Length scales of the smooth kernel (its spectrum decays: the low-rank form) and of the
#: rough one (it does not: the blocks), of the scaled features.
SMOOTH = [3.0, 3.0, 3.0]
ROUGH = [0.7, 1.3, 2.0]


def _rows(points: int, clustered: bool, rng: np.random.Generator) -> np.ndarray:
    """Training inputs of 3 features: uniform, or 10 near-copies of each of ``points / 10``
    centres (then ``|k*|^2 / s`` is large, as on the twin's example)."""
    low, high = np.array([0, 1, 100]), np.array([1, 3, 500])
    if not clustered:
        return rng.uniform(low, high, size=(points, 3))
    centres = rng.uniform(low, high, size=(points // 10, 3)).repeat(10, axis=0)
    return centres + 1e-3 * (high - low) * rng.normal(size=centres.shape)


def _fit(
    points: int,
    lengths: list[float],
    noise: float,
    clustered: bool = False,
    per_row_alpha: bool = False,
    seed: int = 0,
):
    """A scaler + GPR pipeline on a smooth function of 3 inputs (fixed kernel: no fit; the
    regressor's jitter ``alpha`` 1e-10, or one per row)."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, WhiteKernel
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    rng = np.random.default_rng(seed)
    x = _rows(points, clustered, rng)
    y = np.sin(3 * x[:, 0]) * x[:, 1] + 0.002 * x[:, 2] + 0.05 * rng.normal(size=len(x))
    kernel = RBF(lengths) + WhiteKernel(noise)
    alpha = np.linspace(1e-10, 1e-3, len(x)) if per_row_alpha else 1e-10
    gpr = GaussianProcessRegressor(kernel, alpha=alpha, optimizer=None, normalize_y=False)
    return make_pipeline(StandardScaler(), gpr).fit(x, y), x, y


def _run(model, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    import onnxruntime as ort

    session = ort.InferenceSession(model.SerializeToString(), providers=["CPUExecutionProvider"])
    mean, std = session.run(["GPmean", "GPstd"], {"features": x})
    return mean.reshape(-1), std.reshape(-1)


def _closed_form(pipeline, x_train, y, x) -> tuple[np.ndarray, np.ndarray]:
    """Posterior mean and variance by hand: the RBF in numpy, one dense solve."""
    scaler, gpr = pipeline[0], pipeline[-1]
    lengths = np.asarray(gpr.kernel_.k1.length_scale)
    noise = gpr.kernel_.k2.noise_level

    def scaled(a: np.ndarray) -> np.ndarray:
        return (a - scaler.mean_) / scaler.scale_ / lengths

    def rbf(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.exp(-0.5 * np.sum((a[:, None, :] - b[None, :, :]) ** 2, axis=2))

    a, b = scaled(x_train), scaled(x)
    k_mat = rbf(a, a) + np.diag(noise + gpr.alpha * np.ones(len(a)))
    k_star = rbf(b, a)
    solved = np.linalg.solve(k_mat, np.column_stack([y, k_star.T]))
    mean = k_star @ solved[:, 0]
    var = 1.0 + noise - np.sum(k_star.T * solved[:, 1:], axis=0)
    return mean, var


def _held(model, part: str) -> int:
    """Doubles the graph's initializers named with ``part`` hold."""
    return sum(int(np.prod(t.dims)) for t in model.graph.initializer if part in t.name)


def _rank(pipeline, rtol: float = VARIANCE_RTOL) -> tuple[int, int]:
    """Eigenvalues of the training RBF matrix above the cut and above ``s`` (at least one):
    the low-rank form's ``r`` and ``m``."""
    gpr = pipeline[-1]
    noise = gpr.kernel_.k2.noise_level
    eigenvalues = np.linalg.eigvalsh(gpr.kernel_.k1(gpr.X_train_))
    cut = low_rank_cut(noise + gpr.alpha, rtol * noise)
    return int(np.sum(eigenvalues > cut)), max(1, int(np.sum(eigenvalues > noise + gpr.alpha)))


def _blocks(points: int) -> int:
    """Doubles the blocks of L^-1 hold: about half of the n x n matrix."""
    return sum(
        min(s + BLOCK_ROWS, points) * (min(s + BLOCK_ROWS, points) - s)
        for s in range(0, points, BLOCK_ROWS)
    )


@pytest.mark.parametrize(
    ("points", "lengths", "noise", "clustered", "form"),
    [
        (600, SMOOTH, 1e-2, False, "eigenpairs"),
        (400, SMOOTH, 1e-2, True, "eigenpairs"),
        (2 * BLOCK_ROWS + 45, ROUGH, 1e-2, False, "would hold more"),
        (60, ROUGH, 1e-3, False, "would hold more"),
        (60, ROUGH, 1e6, False, "no eigenvalue of K_f above the cut"),  # noise above them all
        (600, SMOOTH, 1e-2, "alpha per row", "alpha is one per row"),  # K is not K_f + s I
    ],
)
def test_graph_equals_sklearn_and_the_closed_form(
    points: int, lengths: list[float], noise: float, clustered: bool | str, form: str
) -> None:
    from cnctwin.learn.onnx_model import _OPSET

    per_row_alpha = clustered == "alpha per row"
    pipeline, x_train, y = _fit(points, lengths, noise, clustered is True, per_row_alpha)
    model = gpr_graph(pipeline, 3, _OPSET)
    assert form in model.graph.doc_string
    # held-out rows: another draw, some beyond the training range; near-copies of training
    # rows (where the variance is smallest and |k*| largest)
    rng = np.random.default_rng(7)
    x = np.vstack(
        [
            rng.uniform([-0.2, 0.8, 80], [1.2, 3.2, 520], size=(200, 3)),
            x_train[:50] * (1 + 1e-4 * rng.normal(size=(50, 3))),
        ]
    )
    mean, std = _run(model, x)
    want_mean, want_std = pipeline.predict(x, return_std=True)
    scale = np.max(np.abs(want_mean))
    np.testing.assert_allclose(mean, want_mean, rtol=1e-9, atol=1e-9 * scale)
    np.testing.assert_allclose(std, want_std, rtol=1e-9)
    form_mean, form_var = _closed_form(pipeline, x_train, y, x)
    np.testing.assert_allclose(mean, form_mean, rtol=1e-8, atol=1e-8 * scale)
    np.testing.assert_allclose(std**2, form_var, rtol=1e-8)
    rank, top = (0, 0) if per_row_alpha else _rank(pipeline)
    if form == "eigenpairs":
        # Q_r and Q_m: r + m of n eigenvectors, fewer doubles than the blocks would hold
        assert f"from {rank} of {points} eigenpairs" in model.graph.doc_string
        assert f"{top} above s back-projected" in model.graph.doc_string
        assert top < rank
        assert _held(model, "gp_q") == (rank + top) * points < _blocks(points)
        assert _held(model, "linv") == 0
    else:
        assert rank == 0 or (rank + top) * points >= _blocks(points)
        if form == "would hold more":
            assert f"{rank} + {top} of {points} eigenvectors" in model.graph.doc_string
        assert _held(model, "linv") == _blocks(points)
        assert _held(model, "gp_q") == 0


@pytest.mark.parametrize("rtol", [1e-4, 60.0])
def test_low_rank_variance_keeps_its_bound(rtol: float) -> None:
    """With a loose tolerance the dropped eigenpairs show: the graph's variance is below the
    exact one by more than rounding, and by no more than rtol * noise (a worst case over every
    x: at 1e-4 about 1e4 times what is left out), on the training rows and held-out rows. At
    60 (a bound of 0.6 against the RBF's amplitude of 1) the cut is above s: every kept
    eigenvector is back-projected."""
    from cnctwin.learn.onnx_model import _OPSET

    noise = 1e-2
    pipeline, x_train, y = _fit(600, SMOOTH, noise)
    model = gpr_graph(pipeline, 3, _OPSET, rtol=rtol)
    rank, top = _rank(pipeline, rtol)
    assert f"from {rank} of 600 eigenpairs" in model.graph.doc_string
    assert f"{min(rank, top)} above s back-projected" in model.graph.doc_string
    assert (rank <= top) == (rtol > 1)
    assert rank < _rank(pipeline)[0]  # the loose tolerance drops more
    rng = np.random.default_rng(3)
    x = np.vstack([x_train, rng.uniform([-0.2, 0.8, 80], [1.2, 3.2, 520], size=(300, 3))])
    _, std = _run(model, x)
    _, exact_var = _closed_form(pipeline, x_train, y, x)
    left_out = exact_var - std**2
    assert np.all(left_out >= -1e-12)
    assert np.all(left_out <= rtol * noise)
    assert np.max(left_out) > 1e-11  # rounding: about 1e-13 (the cases above)


@pytest.mark.parametrize(("diagonal", "bound"), [(0.1, 1e-13), (1e-5, 1e-12), (3.0, 0.5)])
def test_low_rank_cut_solves_its_equation(diagonal: float, bound: float) -> None:
    cut = low_rank_cut(diagonal, bound)
    assert cut > 0
    np.testing.assert_allclose(cut**2 / (diagonal * (cut + diagonal)), bound, rtol=1e-12)


def test_other_kernel_refused() -> None:
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import Matern
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    x = np.linspace(0, 1, 20).reshape(-1, 1)
    pipeline = make_pipeline(StandardScaler(), GaussianProcessRegressor(Matern())).fit(x, x[:, 0])
    with pytest.raises(InputError, match="supports RBF \\+ WhiteKernel"):
        gpr_graph(pipeline, 1, {"": 17})
