"""First-order semi-discretization: kernels, the model of a cut and the depth search.

Used by :mod:`cnctwin.dynamics.stability`.

Insperger T., Stépán G. (2004), Updated semi-discretization method for periodic delay-differential
equations with discrete delay, Int. J. Numer. Meth. Eng. 61, 117-141 (first-order method).

The system is ``y' = A(t) y + B(t) s(t - tau)`` with ``y = [q, q']`` (modal displacements and
velocities) and ``s = U^T Phi q`` the tool-tip displacement in an orthonormal basis ``U`` of the
plane the modes span (``d`` = 1 or 2 components). One period ``T = tau`` is cut into ``m`` steps
``dt_i`` (equal steps ``T / m`` in the paper; here any grid of the period, the same in every
period, so that the node a delay ``T`` earlier is again a node). On step i, ``A`` and ``B`` are
replaced by their means over the step and the delayed displacement by the straight line through
its samples ``s_(i-m)`` and ``s_(i-m+1)``; the step is then solved exactly:

    y_(i+1) = Phi0_i y_i + (Gamma1_i - Gamma2_i) s_(i-m) + Gamma2_i s_(i-m+1),

with ``Phi0 = exp(A dt)``, ``Gamma1 = int_0^dt exp(A (dt - u)) du B`` and
``Gamma2 = int_0^dt exp(A (dt - u)) u / dt du B``, the three blocks of one exponential of an
augmented matrix (Van Loan 1978). The monodromy (Floquet transition) matrix maps
``z_0 = [y_0, s_(-1), ..., s_(-m)]`` to ``z_m``.

Where the directional matrix jumps (a tooth entering or leaving the cut) inside a step, the step
mean of ``H`` smears the jump over the step and the error of the critical depth falls only as
``1 / m`` instead of ``1 / m^2``; the automatic grid of :mod:`cnctwin.dynamics.stability`
therefore puts nodes at the jumps (a variant of the paper's equal steps, not in it).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit
from scipy.optimize import brentq
from scipy.sparse.linalg import ArpackNoConvergence, LinearOperator, eigs

from cnctwin.errors import ConfigError

if TYPE_CHECKING:
    from cnctwin.dynamics.stability import Process, ProcessDamping, ToolDynamics

_TWO_PI = 2.0 * math.pi
_DENSE = 60  # largest monodromy matrix whose eigenvalues LAPACK computes in full
_ARNOLDI = 6  # eigenvalues ARPACK computes of a larger one

# Padé [6/6] coefficients c_k = c_(k-1) (q - k + 1) / (k (2q - k + 1)), q = 6.
_PADE = np.array([1.0, 0.5, 5.0 / 44.0, 1.0 / 66.0, 1.0 / 792.0, 1.0 / 15840.0, 1.0 / 665280.0])


@njit(cache=True)
def expm(a: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Matrix exponential by scaling and squaring with a [6/6] Padé approximant.

    The matrix is scaled to a 1-norm <= 0.5, where the [6/6] approximant's relative error is
    below ``2^(3-2q) (q!)^2 / ((2q)! (2q+1)!)`` = 3.4e-16 (Moler C., Van Loan C. (2003),
    Nineteen dubious ways to compute the exponential of a matrix, twenty-five years later,
    SIAM Review 45, 3-49, Sec. 3).
    """
    n = a.shape[0]
    norm = 0.0
    for j in range(n):
        column = 0.0
        for i in range(n):
            column += abs(a[i, j])
        norm = max(norm, column)
    squarings = 0
    if norm > 0.5:
        squarings = int(math.ceil(math.log2(norm / 0.5)))
    x = a / (2.0**squarings)
    numerator = np.eye(n) * _PADE[0]
    denominator = np.eye(n) * _PADE[0]
    power = np.eye(n)
    sign = 1.0
    for k in range(1, _PADE.size):
        power = _mm(power, x)
        sign = -sign
        numerator += _PADE[k] * power
        denominator += sign * _PADE[k] * power
    result = _solve(denominator, numerator)
    for _ in range(squarings):
        result = _mm(result, result)
    return result


@njit(cache=True)
def _mm(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``a @ b`` as loops: these matrices are small, and BLAS calls compile slowly in numba."""
    out = np.zeros((a.shape[0], b.shape[1]))
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            aik = a[i, k]
            if aik != 0.0:
                for j in range(b.shape[1]):
                    out[i, j] += aik * b[k, j]
    return out


@njit(cache=True)
def _solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``a^-1 b`` by Gaussian elimination with partial pivoting (small, well-conditioned a)."""
    n = a.shape[0]
    lu = a.copy()
    x = b.copy()
    for k in range(n):
        pivot = k
        for i in range(k + 1, n):
            if abs(lu[i, k]) > abs(lu[pivot, k]):
                pivot = i
        if pivot != k:
            for j in range(n):
                lu[k, j], lu[pivot, j] = lu[pivot, j], lu[k, j]
            for j in range(x.shape[1]):
                x[k, j], x[pivot, j] = x[pivot, j], x[k, j]
        for i in range(k + 1, n):
            factor = lu[i, k] / lu[k, k]
            for j in range(k, n):
                lu[i, j] -= factor * lu[k, j]
            for j in range(x.shape[1]):
                x[i, j] -= factor * x[k, j]
    for k in range(n - 1, -1, -1):
        for j in range(x.shape[1]):
            total = x[k, j]
            for i in range(k + 1, n):
                total -= lu[k, i] * x[i, j]
            x[k, j] = total / lu[k, k]
    return x


@njit(cache=True)
def monodromy(
    a0: np.ndarray,
    lq_h: np.ndarray,
    phi: np.ndarray,
    basis: np.ndarray,
    depth: float,
    dts: np.ndarray,
    active: np.ndarray,
) -> np.ndarray:  # pragma: no cover - compiled
    """The Floquet transition matrix of one period.

    Parameters
    ----------
    a0
        ``(2n, 2n)`` state matrix without cutting: ``[[0, I], [-M^-1 K, -M^-1 C]]`` (1/s, 1/s^2).
    lq_h
        ``(m, n, 2)``: ``M^-1 Phi^T H_i`` per step, ``H_i`` the step mean of the directional
        matrix per unit depth (N/m^2), so in 1/(m s^2).
    phi
        ``(2, n)`` mode directions (tool-tip displacement per modal displacement).
    basis
        ``(2, d)`` orthonormal basis of the columns of ``phi``.
    depth
        Depth of cut (chip width) in m.
    dts
        ``(m,)`` step lengths in s.
    active
        ``(m,)``: False where ``H_i`` is zero (no tooth cutting during the step).

    Returns
    -------
    numpy.ndarray
        ``(2n + m d, 2n + m d)`` monodromy matrix in the ordering ``[y, s_(-1), ..., s_(-m)]``.
    """
    m = lq_h.shape[0]
    n = phi.shape[1]
    d = basis.shape[1]
    ny = 2 * n
    size = ny + m * d
    p, g1, g2 = step_maps(a0, lq_h, phi, basis, depth, dts, active)
    cs = _mm(basis.T, phi)  # (d, n): s = cs q
    y = np.zeros((ny, size))
    for i in range(ny):
        y[i, i] = 1.0
    # s_j for j = -m .. m-1 at index j + m; the first m are the unit rows of z_0.
    s = np.zeros((2 * m, d, size))
    for k in range(1, m + 1):
        for c in range(d):
            s[m - k, c, ny + (k - 1) * d + c] = 1.0
    for i in range(m):
        s[i + m] = _mm(cs, y[:n])
        if active[i]:
            y = _mm(p[i], y) + _mm(g1[i], s[i]) + _mm(g2[i], s[i + 1])
        else:
            y = _mm(p[i], y)
    out = np.zeros((size, size))
    out[:ny] = y
    for k in range(1, m + 1):
        out[ny + (k - 1) * d : ny + k * d] = s[2 * m - k]
    return out


@njit(cache=True)
def step_maps(
    a0: np.ndarray,
    lq_h: np.ndarray,
    phi: np.ndarray,
    basis: np.ndarray,
    depth: float,
    dts: np.ndarray,
    active: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """The maps of each step: ``y_(i+1) = P_i y_i + G1_i s_(i-m) + G2_i s_(i-m+1)``.

    Arguments as :func:`monodromy`; returns ``P`` ``(m, 2n, 2n)``, ``G1`` and ``G2``
    ``(m, 2n, d)`` (zero on steps without cutting).
    """
    m = lq_h.shape[0]
    n = phi.shape[1]
    d = basis.shape[1]
    ny = 2 * n
    p = np.zeros((m, ny, ny))
    g1 = np.zeros((m, ny, d))
    g2 = np.zeros((m, ny, d))
    free = np.eye(ny)
    free_dt = -1.0
    big = ny + 2 * d
    augmented = np.zeros((big, big))
    for i in range(m):
        dt = dts[i]
        if not active[i]:
            if dt != free_dt:
                free = expm(a0 * dt)
                free_dt = dt
            p[i] = free
            continue
        augmented[:, :] = 0.0
        augmented[:ny, :ny] = a0
        augmented[n:ny, :n] += depth * _mm(lq_h[i], phi)
        augmented[n:ny, ny : ny + d] = -depth * _mm(lq_h[i], basis)
        for c in range(d):
            augmented[ny + c, ny + d + c] = 1.0 / dt
        x = expm(augmented * dt)
        p[i] = x[:ny, :ny]
        g2[i] = x[:ny, ny + d : ny + 2 * d]
        g1[i] = x[:ny, ny : ny + d] - g2[i]
    return p, g1, g2


@njit(cache=True)
def apply_monodromy(
    p: np.ndarray, g1: np.ndarray, g2: np.ndarray, cs: np.ndarray, z: np.ndarray
) -> np.ndarray:  # pragma: no cover - compiled
    """The monodromy matrix times ``z = [y, s_(-1), ..., s_(-m)]`` without forming it.

    ``p``, ``g1``, ``g2`` from :func:`step_maps`; ``cs`` ``(d, n)``: ``s = cs q``. O(m n^2)
    per product instead of the O(m^2 n^2) of :func:`monodromy`.
    """
    m, ny, _ = p.shape
    d, n = cs.shape
    s = np.zeros((2 * m, d))
    for k in range(1, m + 1):
        for c in range(d):
            s[m - k, c] = z[ny + (k - 1) * d + c]
    y = z[:ny].copy()
    for i in range(m):
        for c in range(d):
            total = 0.0
            for j in range(n):
                total += cs[c, j] * y[j]
            s[i + m, c] = total
        nxt = np.zeros(ny)
        for r in range(ny):
            total = 0.0
            for j in range(ny):
                total += p[i, r, j] * y[j]
            for c in range(d):
                total += g1[i, r, c] * s[i, c] + g2[i, r, c] * s[i + 1, c]
            nxt[r] = total
        y = nxt
    out = np.empty(ny + m * d)
    out[:ny] = y
    for k in range(1, m + 1):
        for c in range(d):
            out[ny + (k - 1) * d + c] = s[2 * m - k, c]
    return out


@dataclass(frozen=True)
class SdmModel:
    """A tool and process discretised on a grid of the period (speed and depth free).

    Arrays in SI units; built by :meth:`build`.
    """

    stiffness: np.ndarray  # (n,) rad^2/s^2: wn^2
    damping: np.ndarray  # (n,) 1/s: 2 zeta wn
    inverse_mass: np.ndarray  # (n,) 1/kg
    phi: np.ndarray  # (2, n)
    basis: np.ndarray  # (2, d)
    lq_h: np.ndarray  # (m, n, 2)
    active: np.ndarray  # (m,) bool
    live: np.ndarray  # indices of the monodromy matrix's columns that are not always zero
    projector: np.ndarray  # (2, 2) process-damping directions
    process: Process
    steps: int
    nodes: np.ndarray  # (m + 1,) the grid as fractions of the period, 0 ... 1

    @classmethod
    def build(cls, tool: ToolDynamics, process: Process, steps: int | np.ndarray) -> SdmModel:
        """Precompute the step matrices and the live columns of ``tool`` cutting ``process``.

        ``steps`` is the number of equal steps per period, or the grid itself: increasing
        fractions of the period from 0 to 1 (``m + 1`` nodes).
        """
        if isinstance(steps, np.ndarray):
            nodes = np.asarray(steps, dtype=np.float64)
            if nodes.ndim != 1 or nodes.size < 3 or nodes[0] != 0.0 or nodes[-1] != 1.0:
                raise ConfigError("semi-discretization grid: give fractions 0 ... 1, >= 3 nodes")
            if np.any(np.diff(nodes) <= 0.0):
                raise ConfigError("semi-discretization grid: give increasing fractions")
        elif isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 2:
            raise ConfigError(f"steps={steps!r}; give an integer >= 2 steps per period")
        else:
            nodes = np.linspace(0.0, 1.0, int(steps) + 1)
        count = nodes.size - 1
        wn = np.array([m.frequency_rad_s for m in tool.modes])
        zeta = np.array([m.damping_ratio for m in tool.modes])
        k = np.array([m.stiffness_n_m for m in tool.modes])
        phi = tool.directions
        u, sv, _ = np.linalg.svd(phi, full_matrices=False)
        basis = np.ascontiguousarray(u[:, sv > 1e-9 * sv.max()])
        inverse_mass = wn * wn / k
        h = process.interval_matrices(nodes)
        lq_h = np.ascontiguousarray((inverse_mass[:, None] * phi.T) @ h)  # (m, n, 2)
        active = np.any(h != 0.0, axis=(1, 2))
        n, d = wn.size, basis.shape[1]
        # Slot s_(-k) is read at step m - k (with s_(i-m)) and m - k - 1 (with s_(i-m+1)).
        slots = np.arange(1, count + 1)
        later = np.where(slots < count, active[(count - slots - 1) % count], False)
        read = active[count - slots] | later
        live = [np.arange(2 * n)]
        live += [2 * n + (kk - 1) * d + np.arange(d) for kk in slots[read]]
        return cls(
            wn * wn,
            2.0 * zeta * wn,
            inverse_mass,
            np.ascontiguousarray(phi),
            basis,
            lq_h,
            active,
            np.concatenate(live),
            process.damping_projector(),
            process,
            count,
            nodes,
        )

    def state_matrix(self, damping_n_s_m: float) -> np.ndarray:
        """``[[0, I], [-M^-1 K, -M^-1 (C + C_pd)]]`` with process damping in N s/m."""
        n = self.stiffness.size
        a0 = np.zeros((2 * n, 2 * n))
        a0[:n, n:] = np.eye(n)
        a0[n:, :n] = -np.diag(self.stiffness)
        a0[n:, n:] = -np.diag(self.damping)
        if damping_n_s_m:
            a0[n:, n:] -= (
                damping_n_s_m
                * (self.inverse_mass[:, None] * self.phi.T)
                @ (self.projector @ self.phi)
            )
        return a0

    def matrix(
        self, speed: float, depth: float, damping: ProcessDamping | None
    ) -> tuple[np.ndarray, float]:
        """The full monodromy matrix and the period in s."""
        extra = 0.0 if damping is None else damping.effective_damping(depth, speed)
        period = float(self.process.delay_s(speed))
        dts = np.diff(self.nodes) * period
        full = monodromy(
            self.state_matrix(extra), self.lq_h, self.phi, self.basis, depth, dts, self.active
        )
        return full, period

    def radius(self, speed: float, depth: float, damping: ProcessDamping | None) -> float:
        """Spectral radius of the monodromy matrix (its always-zero columns deflated).

        Above ``_DENSE`` live columns by ARPACK on the matrix-free product
        (:func:`apply_monodromy`), else (or when ARPACK does not converge) from the matrix.
        """
        if self.live.size > _DENSE:
            try:
                values = self._operator_eigs(speed, depth, damping, vectors=False)
                return float(np.abs(values).max())
            except ArpackNoConvergence:
                pass
        full, _ = self.matrix(speed, depth, damping)
        values = dominant_eigenvalues(full[np.ix_(self.live, self.live)])
        return float(np.abs(values).max())

    def _operator_eigs(
        self, speed: float, depth: float, damping: ProcessDamping | None, vectors: bool
    ) -> Any:
        """ARPACK's largest eigenvalues (and vectors) of the monodromy as an operator."""
        extra = 0.0 if damping is None else damping.effective_damping(depth, speed)
        dts = np.diff(self.nodes) * float(self.process.delay_s(speed))
        maps = step_maps(
            self.state_matrix(extra), self.lq_h, self.phi, self.basis, depth, dts, self.active
        )
        cs = np.ascontiguousarray(self.basis.T @ self.phi)
        size = 2 * self.stiffness.size + self.steps * self.basis.shape[1]

        def product(z: np.ndarray) -> np.ndarray:
            return apply_monodromy(*maps, cs, np.ascontiguousarray(z, dtype=np.float64).ravel())

        operator = LinearOperator((size, size), matvec=product, dtype=np.float64)
        return eigs(operator, k=_ARNOLDI, which="LM", v0=np.ones(size), tol=1e-12,
                    return_eigenvectors=vectors)  # fmt: skip

    def multipliers(self, speed: float, depth: float, damping: ProcessDamping | None) -> np.ndarray:
        """All nonzero Floquet multipliers, largest magnitude first."""
        full, _ = self.matrix(speed, depth, damping)
        values = np.linalg.eigvals(full[np.ix_(self.live, self.live)])
        return values[np.argsort(-np.abs(values), kind="stable")]

    def chatter(
        self, speed: float, depth: float, damping: ProcessDamping | None
    ) -> tuple[float, str]:
        """Chatter frequency in Hz and bifurcation kind of the critical multiplier.

        The critical eigenvector holds the tool-tip displacement at the m nodes ``t_k`` of the
        last period, ``s_k = p(t_k) mu^(t_k / T)`` with ``p`` periodic; the strongest harmonic h
        of ``p`` gives the frequency ``(arg mu + 2 pi h) / T`` (Insperger & Stépán 2004: the
        solution is ``p(t) exp(t ln(mu) / T)``). The harmonics are the trapezoidal-rule Fourier
        coefficients on the nodes, up to the Nyquist limit of the widest step.
        """
        period = float(self.process.delay_s(speed))
        z = None
        if self.live.size > _DENSE:
            try:
                values, vectors = self._operator_eigs(speed, depth, damping, vectors=True)
                j = int(np.argmax(np.abs(values)))
                mu, z = complex(values[j]), np.asarray(vectors[:, j], dtype=np.complex128)
            except ArpackNoConvergence:
                pass
        if z is None:
            full, _ = self.matrix(speed, depth, damping)
            values, vectors = dominant_eigenpairs(full[np.ix_(self.live, self.live)])
            j = int(np.argmax(np.abs(values)))
            mu = complex(values[j])
            z = np.zeros(full.shape[0], dtype=np.complex128)
            z[self.live] = vectors[:, j]
            dead = np.setdiff1d(np.arange(full.shape[0]), self.live)
            z[dead] = full[np.ix_(dead, self.live)] @ vectors[:, j] / mu
        m, d = self.steps, self.basis.shape[1]
        ny = 2 * self.stiffness.size
        samples = z[ny:].reshape(m, d)  # s_(-1), ..., s_(-m)
        k = np.arange(1, m + 1)
        times = self.nodes[m - k] - 1.0  # fractions of the period, -1 <= t < 0
        periodic = samples * (abs(mu) ** (-times) * np.exp(-1j * np.angle(mu) * times))[:, None]
        widths = np.diff(self.nodes)
        weights = 0.5 * (widths[m - k] + widths[(m - k - 1) % m])  # periodic trapezoid
        top = int(0.5 / widths.max())
        harmonics = np.arange(-top, top + 1)
        kernel = np.exp(-1j * _TWO_PI * np.outer(harmonics, times)) * weights
        energy = (np.abs(kernel @ periodic) ** 2).sum(axis=1)
        h = int(harmonics[int(np.argmax(energy))])
        frequency = abs(np.angle(mu) + _TWO_PI * h) / period / _TWO_PI
        if abs(mu.imag) > 1e-7 * abs(mu):
            kind = "hopf"
        else:
            kind = "flip" if mu.real < 0.0 else "fold"
        return frequency, kind


def dominant_eigenvalues(a: np.ndarray) -> np.ndarray:
    """The largest-magnitude eigenvalues of ``a`` (see :func:`dominant_eigenpairs`)."""
    if a.shape[0] > _DENSE:
        try:
            return np.asarray(_arnoldi(a, vectors=False))
        except ArpackNoConvergence:
            pass
    return np.linalg.eigvals(a)


def dominant_eigenpairs(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The largest-magnitude eigenvalues of ``a`` and their eigenvectors (columns).

    All of them by LAPACK for matrices up to ``_DENSE`` rows; above, the ``_ARNOLDI`` largest
    by ARPACK's implicitly restarted Arnoldi method (a fixed start vector, so results repeat),
    several times faster there, with LAPACK as the fallback when ARPACK does not converge.
    """
    if a.shape[0] > _DENSE:
        try:
            values, vectors = _arnoldi(a, vectors=True)
            return values, vectors
        except ArpackNoConvergence:
            pass
    values, vectors = np.linalg.eig(a)
    return values, vectors


def _arnoldi(a: np.ndarray, vectors: bool) -> Any:
    return eigs(a, k=_ARNOLDI, which="LM", v0=np.ones(a.shape[0]), tol=1e-12,
                return_eigenvectors=vectors)  # fmt: skip


def first_crossing(
    excess: Callable[[float], float], top: float, step: float, tol: float
) -> float | None:
    """Lowest ``a`` in ``[0, top]`` where ``excess`` turns >= 0, or None; see sdm_lobes."""
    low, value = 0.0, excess(0.0)
    if value >= 0.0:
        return 0.0
    while low < top:
        high = min(low + step, top)
        value = excess(high)
        if value >= 0.0:
            return float(brentq(excess, low, high, xtol=tol, rtol=1e-4))
        low = high
    return None
