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
- ``var = k(x, x) - |L^-1 k*|^2`` with ``K = L L^T`` (the training kernel matrix, white noise
  and the regressor's ``alpha`` on its diagonal), ``std = sqrt(max(var, 0))``.

scikit-learn solves ``L v = k*`` per call; an ONNX graph has no triangular solve, so the
graph holds ``L^-1`` (computed once at export, ``solve_triangular(L, I)``) and multiplies.
skl2onnx's conversion holds the full ``K^-1`` (``n x n`` doubles: 32 MB at ``n = 2000``) and
multiplies the row vector ``k*`` from the left, which onnxruntime does several times slower
than a matrix times a column. Here ``L^-1`` is lower triangular: its rows are cut into blocks
of :data:`BLOCK_ROWS` and each block keeps only the columns up to its last row, so a window
reads ``(n / 2 + BLOCK_ROWS / 2) n`` doubles instead of ``n^2``, each block multiplied as a
matrix times the column ``k*^T``. The result differs from scikit-learn's by rounding only
(``tests/learn/test_gpr_graph.py``: 1e-9 relative on held-out rows).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError

__all__ = ["BLOCK_ROWS", "gpr_graph"]

#: Rows of ``L^-1`` per block (a block reads its rows up to its last column).
BLOCK_ROWS = 128
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


def gpr_graph(estimator: Any, n_features: int, opset: dict[str, int]) -> Any:
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

    Returns
    -------
    onnx.ModelProto
        Outputs ``GPmean`` and ``GPstd`` (``(rows, 1)``, the fitted target's unit).

    Raises
    ------
    cnctwin.errors.InputError
        For another pipeline or kernel.
    """
    import scipy.linalg
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
    scales, _ = _kernel_parts(gpr.kernel_)
    x_train = np.asarray(gpr.X_train_, dtype=float)
    n = x_train.shape[0]
    # k(x, x) of a stationary kernel: the RBF's 1 plus the white noise (scikit-learn's diag)
    kss = float(gpr.kernel_.diag(x_train[:1])[0])
    l_inv = scipy.linalg.solve_triangular(gpr.L_, np.eye(n), lower=True, check_finite=False)
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
        helper.make_node("Max", ["gp_var_raw", "gp_zero"], ["gp_var"]),
        helper.make_node("Sqrt", ["gp_var"], ["gp_std_row"]),
        helper.make_node("Unsqueeze", ["gp_std_row", "gp_axis1"], ["GPstd"]),
    ]
    inits.append(const("gp_axis1", [1], np.int64))
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
    )
    imports = [helper.make_opsetid(domain, version) for domain, version in opset.items()]
    imports.append(helper.make_opsetid(_MS, 1))
    return helper.make_model(graph, opset_imports=imports)
