"""A Gaussian process as an ONNX graph built by hand: mean and standard deviation in double.

The graph computes, for rows of features ``x`` (``(rows, features)``, the features' units)
and the fitted :class:`~sklearn.pipeline.Pipeline` of a
:class:`~sklearn.preprocessing.StandardScaler` and a
:class:`~sklearn.gaussian_process.GaussianProcessRegressor` with an RBF + white-noise
kernel, what scikit-learn's ``predict(x, return_std=True)`` computes (Rasmussen & Williams
2006, "Gaussian Processes for Machine Learning", Algorithm 2.1, lines 4-6):

- ``z = (x - mean) / scale`` (the scaler), ``k* = exp(-0.5 |z / l - X / l|^2)`` against the
  ``n`` training rows ``X`` (length scales ``l``, eq. 5.1), unitless;
- ``mean = k* . alpha`` with ``alpha = K^-1 y`` (the standardised target's unit);
- ``var = k(x, x) - k*^T K^-1 k*`` with ``K = K_f + s I`` (``K_f`` the RBF part of the
  training kernel matrix, ``s`` the white-noise level ``w`` plus the regressor's ``alpha``
  jitter), ``std = sqrt(max(var, 0))``.

The variance term ``V = k*^T K^-1 k*`` takes one of two forms, whichever holds fewer doubles
(a window reads them all: the time is memory-bound, ``k*`` itself costs about 5 %).

**Low rank, exact to a bound** (:data:`VARIANCE_RTOL`). With ``K_f = Q diag(lambda) Q^T``
(eigenpairs ``lambda_i >= 0``, ``q_i``), ``V = sum_i (q_i . k*)^2 / (lambda_i + s)``. The graph
keeps the ``r`` eigenpairs with ``lambda_i > lambda_cut`` (``Q_r``) and computes

    u = Q_r^T k*,   p = k* - Q_r u,   V_r = sum_i u_i^2 / (lambda_i + s) + |p|^2 / s.

``p`` is ``k*`` without its part in the kept eigenvectors, ``|p|^2 = sum_dropped (q_i .
k*)^2``, so ``V_r - V = sum_dropped c_i (q_i . k*)^2`` with ``c_i = 1 / s - 1 / (lambda_i + s)
= lambda_i / (s (lambda_i + s))``: the dropped eigenpairs enter as if ``lambda_i`` were 0. That
is at most ``g(lambda_cut)`` with ``g(lambda) = lambda^2 / (s (lambda + s))``, for every ``x``:
``c_i (q_i . k*)^2 = g(lambda_i) (q_i . k*)^2 / lambda_i``, ``g`` grows with ``lambda``, and
``sum_i (q_i . k*)^2 / lambda_i = k*^T K_f^+ k* <= k_f(x, x) = 1`` (the Schur complement of
the kernel matrix of ``X`` and ``x``, positive semi-definite). :func:`low_rank_cut` solves
``g(lambda_cut) = VARIANCE_RTOL * w``, so the graph's variance is below scikit-learn's by at
most ``VARIANCE_RTOL * w <= VARIANCE_RTOL * var`` (``var >= w``): the standard deviation by at
most ``VARIANCE_RTOL / 2`` relative, plus rounding.

Rounding decides how ``p`` is formed. ``|p|^2 = |k*|^2 - |u|^2`` costs nothing more, but on
clustered training rows ``|k*|^2 / s`` reaches 1e4 (the twin's example) and the difference
loses the dot products' rounding: 3e-10 relative on the standard deviation, measured. The
graph subtracts as a vector the part in the ``m`` eigenvectors with ``lambda_i > s``
(``Q_m``, at least one) and the rest as squares: ``p_m = k* - Q_m u_m``, ``|p|^2 = |p_m|^2 -
sum_{i > m} u_i^2``, so ``V_r = sum_i a_i u_i^2 + |p_m|^2 / s`` with ``a_i = 1 / (lambda_i +
s)`` for ``i <= m`` and ``-c_i`` after. Both ``|p_m|^2`` and ``sum_{i > m} u_i^2`` are at most
``s`` (the weights' sum above), so their difference costs no more rounding than the kept
terms near ``lambda = s`` do themselves: 3e-13 on the twin's example, with ``m = r`` alike.
The graph reads ``(r + m) n`` doubles. ``r`` and ``m`` depend on the kernel's spectrum, not
on ``x``. It decays fast on correlated features (the twin's force model, 4 features:
``r = 127``, ``m = 47`` of 2,000) and with the long length scales marginal likelihood gives
the features a target does not depend on (``bench_learn.py``'s data, 8 features of which 3
matter, with the kernel its trained GPR fits: ``r = 496``, ``m = 35``); it does not decay for
rough kernels on many independent features (``bench_learn.py``'s fixed kernel, 8 uniform
features at length scale 1: ``r = n``, the blocks below).

**Block-triangular ``L^-1``** otherwise: ``V = |L^-1 k*|^2`` with ``K = L L^T``.
scikit-learn solves ``L v = k*`` per call; an ONNX graph has no triangular solve, so the
graph holds ``L^-1`` (computed once at export, ``solve_triangular(L, I)``) and multiplies.
skl2onnx's conversion holds the full ``K^-1`` (``n x n`` doubles: 32 MB at ``n = 2000``) and
multiplies the row vector ``k*`` from the left, which onnxruntime does several times slower
than a matrix times a column. Here ``L^-1`` is lower triangular: its rows are cut into blocks
of :data:`BLOCK_ROWS` and each block keeps only the columns up to its last row, so a window
reads ``(n / 2 + BLOCK_ROWS / 2) n`` doubles instead of ``n^2``, each block multiplied as a
matrix times the column ``k*^T``.

Either way the result equals scikit-learn's to 1e-9 relative on held-out rows
(``tests/learn/test_gpr_graph.py``). The graph's ``doc_string`` says which form it holds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError

__all__ = ["BLOCK_ROWS", "VARIANCE_RTOL", "gpr_graph", "low_rank_cut"]

#: Rows of ``L^-1`` per block (a block reads its rows up to its last column).
BLOCK_ROWS = 128
#: The most the low-rank form may leave out of the variance, relative to the white-noise
#: level (so to the variance itself): the standard deviation to half of it, relative.
VARIANCE_RTOL = 1e-12
#: onnxruntime's contrib domain (``CDist``: the squared distances as scipy's ``cdist``).
_MS = "com.microsoft"


def _kernel_parts(kernel: Any) -> tuple[NDArray[np.float64], float]:
    """Length scales (one per feature, or one for all; unitless, of the scaled features) and
    white-noise level (the fitted target's unit squared) of an ``RBF + WhiteKernel``."""
    from sklearn.gaussian_process.kernels import RBF, Sum, WhiteKernel

    # type(...) is: Matern is a subclass of RBF with another formula
    if isinstance(kernel, Sum) and type(kernel.k1) is RBF and type(kernel.k2) is WhiteKernel:
        scales = np.atleast_1d(np.asarray(kernel.k1.length_scale, dtype=float))
        return scales, float(kernel.k2.noise_level)
    raise InputError(
        f"GPR kernel {kernel}: the ONNX export supports RBF + WhiteKernel "
        "(the kernel cnctwin.learn.train fits)"
    )


def low_rank_cut(diagonal: float, bound: float) -> float:
    """The eigenvalue ``lambda_cut`` of ``K_f`` at which a dropped eigenpair's share of the
    variance may reach ``bound``: the root of ``lambda^2 / (diagonal (lambda + diagonal)) =
    bound`` (module docstring).

    Parameters
    ----------
    diagonal
        ``s``: what ``K`` adds to ``K_f``'s diagonal (white noise plus jitter; the fitted
        target's unit squared), positive.
    bound
        The variance an eigenpair at ``lambda_cut`` may leave out (the same unit), >= 0.

    Returns
    -------
    float
        ``lambda_cut`` (the same unit; ``K_f`` of an RBF is unitless, its amplitude 1).
    """
    product = bound * diagonal
    return float(0.5 * (product + np.sqrt(product * product + 4.0 * product * diagonal)))


def gpr_graph(
    estimator: Any, n_features: int, opset: dict[str, int], rtol: float = VARIANCE_RTOL
) -> Any:
    """The ONNX model of a fitted ``StandardScaler`` + ``GaussianProcessRegressor`` pipeline.

    Parameters
    ----------
    estimator
        The fitted pipeline (``normalize_y=False``: :func:`cnctwin.learn.train` standardises
        the target itself).
    n_features
        Columns of the input ``features`` (double, ``(rows, n_features)``, feature units).
    opset
        ONNX opsets by domain (``""``: at least 13).
    rtol
        The most the low-rank variance may leave out, relative to the white-noise level
        (:data:`VARIANCE_RTOL`; module docstring).

    Returns
    -------
    onnx.ModelProto
        Outputs ``GPmean`` and ``GPstd`` (``(rows, 1)``, the fitted target's unit); the
        graph's ``doc_string`` names the variance's form (rank or blocks).

    Raises
    ------
    cnctwin.errors.InputError
        For another pipeline or kernel.
    """
    from onnx import TensorProto, helper, numpy_helper
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.preprocessing import StandardScaler

    steps = [step for _, step in getattr(estimator, "steps", [])]
    if (
        len(steps) != 2
        or not isinstance(steps[0], StandardScaler)
        or not isinstance(steps[1], GaussianProcessRegressor)
        or steps[1].normalize_y
    ):
        raise InputError(
            f"{estimator}: the GPR export takes StandardScaler + GaussianProcessRegressor "
            "(normalize_y=False)"
        )
    scaler, gpr = steps
    scales, noise = _kernel_parts(gpr.kernel_)
    x_train = np.asarray(gpr.X_train_, dtype=float)
    n = x_train.shape[0]
    # k(x, x) of a stationary kernel: the RBF's 1 plus the white noise (scikit-learn's diag)
    kss = float(gpr.kernel_.diag(x_train[:1])[0])
    alpha = np.asarray(gpr.alpha_, dtype=float).reshape(n, 1)

    def const(name: str, value: Any, dtype: Any = np.float64) -> Any:
        return numpy_helper.from_array(np.asarray(value, dtype=dtype), name)

    inits = [
        const("gp_x_mean", scaler.mean_),
        const("gp_x_scale", scaler.scale_),
        const("gp_length", scales),
        const("gp_train", x_train / scales),
        const("gp_alpha", alpha),
        const("gp_kss", [kss]),
        const("gp_half", [-0.5]),
        const("gp_zero", [0.0]),
        const("gp_axis0", [0], np.int64),
        const("gp_axis1", [1], np.int64),
    ]
    nodes = [
        helper.make_node("Sub", ["features", "gp_x_mean"], ["gp_centred"]),
        helper.make_node("Div", ["gp_centred", "gp_x_scale"], ["gp_z"]),
        helper.make_node("Div", ["gp_z", "gp_length"], ["gp_zl"]),
        helper.make_node(
            "CDist", ["gp_zl", "gp_train"], ["gp_d2"], domain=_MS, metric="sqeuclidean"
        ),
        helper.make_node("Mul", ["gp_d2", "gp_half"], ["gp_arg"]),
        helper.make_node("Exp", ["gp_arg"], ["gp_k"]),  # (rows, n)
        helper.make_node("MatMul", ["gp_k", "gp_alpha"], ["GPmean"]),
        helper.make_node("Transpose", ["gp_k"], ["gp_kt"], perm=[1, 0]),  # (n, rows)
    ]
    low_rank = _low_rank(gpr, noise, rtol)
    if isinstance(low_rank, _LowRank):
        form = _low_rank_variance(low_rank, inits, nodes, const)
    else:
        form = _blocked_variance(gpr, inits, nodes, const, low_rank)
    nodes += [
        helper.make_node("Max", ["gp_var_raw", "gp_zero"], ["gp_var"]),
        helper.make_node("Sqrt", ["gp_var"], ["gp_std_row"]),
        helper.make_node("Unsqueeze", ["gp_std_row", "gp_axis1"], ["GPstd"]),
    ]
    double = TensorProto.DOUBLE
    graph = helper.make_graph(
        nodes,
        "cnctwin_gpr",
        [helper.make_tensor_value_info("features", double, [None, n_features])],
        [
            helper.make_tensor_value_info("GPmean", double, [None, 1]),
            helper.make_tensor_value_info("GPstd", double, [None, 1]),
        ],
        inits,
        doc_string=f"GPR of {n} points, variance {form}",
    )
    imports = [helper.make_opsetid(domain, version) for domain, version in opset.items()]
    imports.append(helper.make_opsetid(_MS, 1))
    return helper.make_model(graph, opset_imports=imports)


@dataclass(frozen=True)
class _LowRank:
    """The low-rank variance's parts (module docstring): ``q_t`` is ``Q_r^T`` (``(r, n)``, the
    largest eigenvalue first), ``weights`` the ``u_i^2`` weights (``(r, 1)``: ``1 / (lambda_i +
    s)`` for the first ``top``, ``1 / (lambda_i + s) - 1 / s`` after), ``diagonal`` is ``s``,
    ``cut`` is ``lambda_cut``."""

    q_t: NDArray[np.float64]
    weights: NDArray[np.float64]
    top: int
    diagonal: float
    cut: float


def _low_rank(gpr: Any, noise: float, rtol: float) -> _LowRank | str:
    """The low-rank variance's parts, or why not: where they would hold at least as many
    doubles as the blocks of ``L^-1``, where no eigenpair is kept (a white noise far above the
    RBF's eigenvalues) or where ``K``'s jitter is not one number (so ``K`` is not ``K_f +
    s I``)."""
    import scipy.linalg

    if np.ndim(gpr.alpha) != 0:
        return "the regressor's alpha is one per row"
    x_train = np.asarray(gpr.X_train_, dtype=float)
    n = x_train.shape[0]
    k_f = gpr.kernel_.k1(x_train)
    diagonal = noise + float(gpr.alpha)
    cut = low_rank_cut(diagonal, rtol * noise)
    eigenvalues = scipy.linalg.eigvalsh(k_f, check_finite=False)
    rank = int(np.count_nonzero(eigenvalues > cut))
    if rank == 0:
        return f"no eigenvalue of K_f above the cut {cut:.3g}"
    # at least one back-projected (K_f's largest eigenvalue is at least its mean diagonal, 1),
    # at most the kept ones (a loose rtol puts the cut above s)
    top = min(rank, max(1, int(np.count_nonzero(eigenvalues > diagonal))))
    if (rank + top) * n >= _blocked_size(n):
        return f"{rank} + {top} of {n} eigenvectors would hold more"
    kept, vectors = scipy.linalg.eigh(k_f, subset_by_index=[n - rank, n - 1], check_finite=False)
    kept, vectors = kept[::-1], vectors[:, ::-1]
    weights = 1.0 / (kept + diagonal)
    weights[top:] -= 1.0 / diagonal
    return _LowRank(vectors.T.copy(), weights.reshape(-1, 1), top, diagonal, cut)


def _blocked_size(n: int) -> int:
    """Doubles the blocks of ``L^-1`` hold for ``n`` training points."""
    return sum(
        (stop := min(start + BLOCK_ROWS, n)) * (stop - start) for start in range(0, n, BLOCK_ROWS)
    )


def _low_rank_variance(low_rank: _LowRank, inits: list[Any], nodes: list[Any], const: Any) -> str:
    """Append ``gp_var_raw = k(x, x) - V_r`` to the graph (module docstring); its form."""
    from onnx import helper

    rank, n = low_rank.q_t.shape
    inits += [
        const("gp_qt", low_rank.q_t),
        # Q_m, (n, m): a Gemm with transA on a slice of Q_r^T runs slower
        const("gp_q_top", low_rank.q_t[: low_rank.top].T.copy()),
        const("gp_weights", low_rank.weights),
        const("gp_inv_s", [1.0 / low_rank.diagonal]),
        const("gp_top", [low_rank.top], np.int64),
    ]
    nodes += [
        helper.make_node("MatMul", ["gp_qt", "gp_kt"], ["gp_u"]),  # (r, rows)
        helper.make_node("Slice", ["gp_u", "gp_axis0", "gp_top", "gp_axis0"], ["gp_u_top"]),
        helper.make_node("MatMul", ["gp_q_top", "gp_u_top"], ["gp_back"]),  # (n, rows)
        helper.make_node("Sub", ["gp_kt", "gp_back"], ["gp_p"]),
        helper.make_node("Mul", ["gp_p", "gp_p"], ["gp_pp"]),
        helper.make_node("ReduceSum", ["gp_pp", "gp_axis0"], ["gp_p2"], keepdims=0),
        helper.make_node("Mul", ["gp_p2", "gp_inv_s"], ["gp_rest"]),
        helper.make_node("Mul", ["gp_u", "gp_u"], ["gp_uu"]),
        helper.make_node("Mul", ["gp_uu", "gp_weights"], ["gp_uu_w"]),
        helper.make_node("ReduceSum", ["gp_uu_w", "gp_axis0"], ["gp_kept"], keepdims=0),
        helper.make_node("Add", ["gp_kept", "gp_rest"], ["gp_vv"]),
        helper.make_node("Sub", ["gp_kss", "gp_vv"], ["gp_var_raw"]),
    ]
    return (
        f"from {rank} of {n} eigenpairs of K_f (those above {low_rank.cut:.3g}; "
        f"{low_rank.top} above s back-projected), exact to a bound"
    )


def _blocked_variance(gpr: Any, inits: list[Any], nodes: list[Any], const: Any, why: str) -> str:
    """Append ``gp_var_raw = k(x, x) - |L^-1 k*|^2`` (``L^-1`` in blocks) to the graph; its
    form, with ``why`` the low-rank form is not used."""
    import scipy.linalg
    from onnx import helper

    n = gpr.L_.shape[0]
    l_inv = scipy.linalg.solve_triangular(gpr.L_, np.eye(n), lower=True, check_finite=False)
    parts = []
    for b, start in enumerate(range(0, n, BLOCK_ROWS)):
        stop = min(start + BLOCK_ROWS, n)
        inits += [
            const(f"gp_linv{b}", l_inv[start:stop, :stop]),
            const(f"gp_stop{b}", [stop], np.int64),
        ]
        nodes += [
            helper.make_node(
                "Slice", ["gp_kt", "gp_axis0", f"gp_stop{b}", "gp_axis0"], [f"gp_kt{b}"]
            ),
            helper.make_node("MatMul", [f"gp_linv{b}", f"gp_kt{b}"], [f"gp_block{b}"]),
        ]
        parts.append(f"gp_block{b}")
    nodes += [
        helper.make_node("Concat", parts, ["gp_v"], axis=0),  # L^-1 k*^T, (n, rows)
        helper.make_node("Mul", ["gp_v", "gp_v"], ["gp_sq"]),
        helper.make_node("ReduceSum", ["gp_sq", "gp_axis0"], ["gp_vv"], keepdims=0),
        helper.make_node("Sub", ["gp_kss", "gp_vv"], ["gp_var_raw"]),
    ]
    return f"from L^-1 in blocks of {BLOCK_ROWS} rows (low rank: {why})"
