"""Modal fitting: natural frequencies, damping ratios and modal constants from a measured FRF.

The model of one direction's receptance is a sum of real (proportionally damped) modes, each
the single-degree-of-freedom FRF of Royandi 2026, Eq. 13, ``1 / (k - m w^2 + j c w)``, written
with its modal constant ``r = 1/m`` (1/kg):

    H(w) = sum_k r_k / (w_k^2 - w^2 + 2 j zeta_k w_k w)  +  U  -  L / w^2

``w_k`` is the natural frequency (rad/s), ``zeta_k`` the damping ratio; the *residuals* ``U``
(m/N, the static compliance of the modes above the band) and ``L`` (1/kg, the inertia of the
modes below it) absorb what lies outside the band (Ewins, *Modal Testing*, 2nd ed. 2000,
section 4.4). Each mode's modal mass, stiffness and damping follow: ``m = 1/r``,
``k = w_k^2 / r``, ``c = 2 zeta_k w_k / r``; these are the m, c, k a stability or vibration
model takes for that mode in that direction (fit the x and y FRFs separately).

:func:`fit_modes` picks the ``n`` most prominent peaks of ``|H|`` in the band, takes their
half-power bandwidths as first damping ratios (``zeta = (w_2 - w_1) / (2 w_n)``, Schmitz and
Smith, *Machining Dynamics*, 2nd ed. 2019, section 2.6), then refines all poles together by
nonlinear least squares on the complex FRF. The modal constants and residuals enter linearly,
so for any set of poles they are solved exactly by linear least squares and only the poles are
searched (variable projection; Golub and Pereyra, SIAM J. Numer. Anal. 10(2), 1973). Each
frequency is weighted by its coherence when the FRF has one.

Units: SI. rad/s, m/N, kg, N/m, N s/m.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.signal import find_peaks

from cnctwin.dynamics.frf import FRF, window_damping_correction
from cnctwin.errors import DataError

__all__ = ["DEFAULT_LOW_HZ", "ModalFit", "Mode", "default_band", "fit_modes", "modal_frf"]

_log = logging.getLogger(__name__)

#: Most modes one fit takes: each mode adds parameters, beyond 20 the fit is ill-posed.
MAX_MODES = 20
#: Low edge of the default fitted band, Hz: below it an accelerometer's receptance is noise.
DEFAULT_LOW_HZ = 100.0
_ZETA_MIN = 1e-5
_ZETA_MAX = 0.7
_ZETA_FALLBACK = 0.02


@dataclass(frozen=True)
class Mode:
    """One real mode of a direction's receptance (Royandi 2026, Eq. 13).

    Attributes
    ----------
    omega_n
        Undamped natural frequency, rad/s.
    zeta
        Viscous damping ratio (dimensionless).
    residue
        Modal constant ``r = 1/m``, 1/kg: the mode's receptance is
        ``r / (omega_n^2 - w^2 + 2 j zeta omega_n w)``. Positive at a driving point (force and
        response at the same place and direction); negative for a mode that moves a cross
        point against the force.
    """

    omega_n: float
    zeta: float
    residue: float

    @classmethod
    def from_mck(cls, mass: float, damping: float, stiffness: float) -> Mode:
        """The mode of ``1 / (k - m w^2 + j c w)`` (Royandi 2026, Eq. 13).

        Parameters
        ----------
        mass
            Modal mass m, kg (> 0).
        damping
            Modal viscous damping c, N s/m (>= 0).
        stiffness
            Modal stiffness k, N/m (> 0).
        """
        if not (mass > 0.0 and stiffness > 0.0 and damping >= 0.0):
            raise DataError(
                f"mode: m {mass!r} kg, c {damping!r} N s/m, k {stiffness!r} N/m; give m > 0, "
                "c >= 0, k > 0"
            )
        omega_n = math.sqrt(stiffness / mass)
        return cls(omega_n, damping / (2.0 * math.sqrt(stiffness * mass)), 1.0 / mass)

    @property
    def mass(self) -> float:
        """Modal mass ``m = 1/r``, kg."""
        return 1.0 / self.residue

    @property
    def stiffness(self) -> float:
        """Modal stiffness ``k = w_n^2 / r``, N/m."""
        return self.omega_n**2 / self.residue

    @property
    def damping(self) -> float:
        """Modal viscous damping ``c = 2 zeta w_n / r``, N s/m."""
        return 2.0 * self.zeta * self.omega_n / self.residue

    @property
    def omega_d(self) -> float:
        """Damped natural frequency ``w_n sqrt(1 - zeta^2)``, rad/s."""
        return self.omega_n * math.sqrt(max(1.0 - self.zeta**2, 0.0))


def modal_frf(
    omega: ArrayLike,
    modes: Sequence[Mode],
    *,
    upper_residual: float = 0.0,
    lower_residual: float = 0.0,
) -> NDArray[np.complex128]:
    """The receptance of a sum of modes plus residuals (module docstring; Royandi 2026, Eq. 13).

    Parameters
    ----------
    omega
        Angular frequencies, rad/s (> 0 when ``lower_residual`` is not 0).
    modes
        The modes.
    upper_residual
        ``U``, m/N.
    lower_residual
        ``L``, 1/kg (the term is ``-L / w^2``).

    Returns
    -------
    numpy.ndarray
        Complex receptance, m/N, shaped like ``omega``.
    """
    w = np.asarray(omega, dtype=float)
    h = np.full(w.shape, complex(upper_residual))
    for mode in modes:
        h += mode.residue / (mode.omega_n**2 - w**2 + 2j * mode.zeta * mode.omega_n * w)
    if lower_residual:
        h -= lower_residual / w**2
    return h


@dataclass(frozen=True)
class ModalFit:
    """Modes fitted to one receptance, with the quality of the fit.

    Attributes
    ----------
    modes
        The fitted modes, by increasing natural frequency, the exponential window's damping
        removed.
    omega_band
        The fitted band (low, high), rad/s.
    upper_residual
        ``U``, m/N (0 when fitted without residuals).
    lower_residual
        ``L``, 1/kg (0 when fitted without residuals).
    residual_norm
        ``sqrt(sum w |H - H_fit|^2 / sum w |H|^2)`` over the band, w the coherence (1 without
        one): 0 for a perfect fit.
    mode_residual_norms
        The same norm over each mode's half-power band ``w_n (1 +- zeta)`` (at least the three
        nearest frequencies): how well each peak itself is fitted.
    window_decay
        ``1/tau`` of the exponential window removed from the fitted poles, 1/s.
    coherence_weighted
        Whether the frequencies were weighted by coherence.
    n_frequencies
        Number of frequencies fitted.
    """

    modes: tuple[Mode, ...]
    omega_band: tuple[float, float]
    upper_residual: float
    lower_residual: float
    residual_norm: float
    mode_residual_norms: tuple[float, ...]
    window_decay: float
    coherence_weighted: bool
    n_frequencies: int

    def evaluate(self, omega: ArrayLike, *, windowed: bool = False) -> NDArray[np.complex128]:
        """The fitted receptance at ``omega`` (rad/s), m/N.

        Without ``windowed``, the structure's (the window's damping removed); with it, the
        model as fitted to the windowed FRF: each mode ``r / (s^2 + 2 zeta w_n s + w_n^2)`` at
        ``s = j w + window_decay``, the residuals as fitted. Compare the latter with the
        measured (windowed) FRF.
        """
        if not windowed or self.window_decay == 0.0:
            return modal_frf(
                omega,
                self.modes,
                upper_residual=self.upper_residual,
                lower_residual=self.lower_residual,
            )
        w = np.asarray(omega, dtype=float)
        s = 1j * w + self.window_decay
        h = self.upper_residual - self.lower_residual / w**2 + 0j
        for mode in self.modes:
            h = h + mode.residue / (s**2 + 2.0 * mode.zeta * mode.omega_n * s + mode.omega_n**2)
        return np.asarray(h, dtype=complex)


def default_band(receptance: FRF, excited_omega: float | None = None) -> tuple[float, float]:
    """The band a tap test is fitted over unless told otherwise, rad/s.

    From :data:`DEFAULT_LOW_HZ` to the FRF's last frequency, or, for an impact record, to the
    highest frequency the hammer excites (its force spectrum within 40 dB of the peak:
    :attr:`cnctwin.measurements.TapTest.excited_omega`).

    Parameters
    ----------
    receptance
        The measured FRF; only its frequencies are used.
    excited_omega
        Highest excited angular frequency of an impact record, rad/s; None for an FRF file.

    Returns
    -------
    tuple of float
        ``(low, high)`` in rad/s.

    Raises
    ------
    DataError
        When the data end at or below :data:`DEFAULT_LOW_HZ`: give the band explicitly.
    """
    high = float(receptance.omega[-1]) if excited_omega is None else float(excited_omega)
    low = 2.0 * math.pi * DEFAULT_LOW_HZ
    if high <= low:
        raise DataError(
            f"the default band starts at {DEFAULT_LOW_HZ:g} Hz, above the data "
            f"({high / (2.0 * math.pi):g} Hz); give the band"
        )
    return low, high


def fit_modes(
    frf: FRF,
    n_modes: int = 1,
    *,
    omega_band: tuple[float, float] | None = None,
    residuals: bool = True,
    use_coherence: bool = True,
    initial_omega: Sequence[float] | None = None,
) -> ModalFit:
    """Fit ``n_modes`` real modes (and residuals) to a measured FRF.

    Parameters
    ----------
    frf
        The FRF; a mobility or an accelerance is first turned into a receptance
        (:meth:`~cnctwin.dynamics.frf.FRF.to_receptance`).
    n_modes
        Number of modes in the band, >= 1.
    omega_band
        Fitted band (low, high), rad/s; None for the whole FRF above 0 rad/s.
    residuals
        Fit the upper and lower residuals ``U`` and ``L`` (module docstring) along.
    use_coherence
        Weight each frequency by the FRF's coherence (when it has one).
    initial_omega
        First guesses of the ``n_modes`` natural frequencies, rad/s, instead of the most
        prominent peaks.

    Returns
    -------
    ModalFit
        The modes (the exponential window's damping removed) and the fit's quality.

    Raises
    ------
    DataError
        When the band holds fewer frequencies than the model has parameters, or fewer than
        ``n_modes`` peaks.
    """
    if not (isinstance(n_modes, int) and 1 <= n_modes <= MAX_MODES):
        raise DataError(f"fit_modes: n_modes {n_modes!r}; give an integer from 1 to {MAX_MODES}")
    x = frf.to_receptance()
    x = x.band(x.omega[0] if x.omega[0] > 0.0 else x.omega[1], x.omega[-1])
    if omega_band is not None:
        low, high = omega_band
        if not (0.0 <= low < high < math.inf):
            raise DataError(f"fit_modes: band {low:g}..{high:g} rad/s; give finite 0 <= low < high")
        x = x.band(max(low, x.omega[0]), high)
    omega, h = x.omega, x.h
    n_linear = n_modes + (2 if residuals else 0)
    if omega.size < 2 * n_modes + n_linear:
        raise DataError(
            f"fit_modes: {omega.size} frequencies in the band for {n_modes} mode(s); give a "
            "wider band or fewer modes"
        )
    if not np.all(np.isfinite(h)):
        raise DataError("fit_modes: the FRF holds NaN or infinite values in the band")
    weighted = use_coherence and x.coherence is not None
    weight = np.clip(x.coherence, 0.0, 1.0) if weighted else np.ones(omega.size)  # type: ignore[arg-type]
    if not np.any(weight > 0.0):
        raise DataError("fit_modes: the coherence is 0 at every frequency of the band")
    scale = float(np.max(np.abs(h)))
    if scale == 0.0:
        raise DataError("fit_modes: the FRF is zero over the band")
    y = h / scale
    if initial_omega is None:
        omega0, zeta0 = _peaks(omega, y, n_modes)
    else:
        omega0 = np.asarray(initial_omega, dtype=float)
        if omega0.shape != (n_modes,) or np.any(omega0 <= 0.0):
            raise DataError(
                f"fit_modes: initial_omega {list(omega0.ravel())!r}; give {n_modes} frequencies "
                "> 0 rad/s"
            )
        zeta0 = np.array([_half_power_zeta(omega, y, int(np.argmin(np.abs(omega - w))))
                          for w in omega0])  # fmt: skip
    problem = _Problem(omega, y, np.sqrt(weight), residuals)
    start = np.concatenate([np.log(omega0), np.log(np.clip(zeta0, 2 * _ZETA_MIN, _ZETA_MAX / 2))])
    lower = np.concatenate(
        [np.full(n_modes, np.log(omega[0] / 2.0)), np.full(n_modes, np.log(_ZETA_MIN))]
    )
    upper = np.concatenate(
        [np.full(n_modes, np.log(omega[-1] * 2.0)), np.full(n_modes, np.log(_ZETA_MAX))]
    )
    start = np.clip(start, lower + 1e-9, upper - 1e-9)
    solution = least_squares(
        problem.residual, start, jac=problem.jacobian, bounds=(lower, upper), method="trf",
        xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200 * (2 * n_modes + 1),
    )  # fmt: skip
    omega_w = np.exp(solution.x[:n_modes])
    zeta_w = np.exp(solution.x[n_modes:])
    coefficients = problem.linear(solution.x)
    residue_w = coefficients[:n_modes] * omega_w**2 * scale
    upper_residual = float(coefficients[n_modes] * scale) if residuals else 0.0
    lower_residual = float(coefficients[n_modes + 1] * scale * omega[0] ** 2) if residuals else 0.0
    windowed = [
        Mode(float(w), float(z), float(r))
        for w, z, r in zip(omega_w, zeta_w, residue_w, strict=True)
    ]
    fitted = modal_frf(
        omega, windowed, upper_residual=upper_residual, lower_residual=lower_residual
    )
    omega_n, zeta = window_damping_correction(omega_w, zeta_w, x.window_decay)
    # r / (w_n^2 - w^2 + 2 j zeta w_n w) = r / ((j w - p)(j w - conj p)): the shift of the pole
    # leaves w_d and the pole residue r / (2 j w_d) unchanged, hence r.
    order = np.argsort(omega_n)
    modes = tuple(Mode(float(omega_n[i]), float(zeta[i]), float(residue_w[i])) for i in order)
    norm = _norm(h, fitted, weight)
    mode_norms = tuple(
        _norm(*_near(omega, h, fitted, weight, omega_w[i], zeta_w[i])) for i in order
    )
    if np.min(np.diff(np.sort(omega_w)), initial=np.inf) < 1e-3 * omega_w.max():
        _log.warning("two fitted modes share a natural frequency: fit fewer modes")
    _log.debug("modal fit: %d modes, residual norm %.3g, %d evaluations",
               n_modes, norm, solution.nfev)  # fmt: skip
    return ModalFit(
        modes=modes,
        omega_band=(float(omega[0]), float(omega[-1])),
        upper_residual=upper_residual,
        lower_residual=lower_residual,
        residual_norm=norm,
        mode_residual_norms=mode_norms,
        window_decay=x.window_decay,
        coherence_weighted=weighted,
        n_frequencies=int(omega.size),
    )


class _Problem:
    """Variable projection: poles are searched, modal constants and residuals solved.

    The parameters are ``ln w_n`` and ``ln zeta`` of every mode. The Jacobian is Kaufman's
    approximation ``P_perp (dB/dp) c`` (Golub and Pereyra 2003, Inverse Problems 19, R1), exact
    at a zero-residual solution.
    """

    def __init__(
        self,
        omega: NDArray[np.float64],
        y: NDArray[np.complex128],
        sqrt_weight: NDArray[np.float64],
        residuals: bool,
    ) -> None:
        self.omega = omega
        self.sqrt_weight = np.concatenate([sqrt_weight, sqrt_weight])
        self.target = np.concatenate([y.real, y.imag]) * self.sqrt_weight
        self.extra = None
        if residuals:
            extra = np.stack([np.ones(omega.size), -((omega[0] / omega) ** 2)], axis=1)
            self.extra = np.concatenate([extra, np.zeros_like(extra)]) * self.sqrt_weight[:, None]
        self._cache: tuple[bytes, NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                           NDArray[np.float64]] | None = None  # fmt: skip

    def _solve(
        self, params: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Basis columns' derivatives, Q of the basis, coefficients and residual at ``params``."""
        key = params.tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1:]
        half = params.size // 2
        w_n = np.exp(params[:half])
        zeta = np.exp(params[half:])
        w = self.omega[:, None]
        denominator = w_n**2 - w**2 + 2j * zeta * w_n * w
        # Each mode's column is scaled by w_n^2, so its coefficient is r / w_n^2 = 1/k.
        columns = w_n**2 / denominator
        d_log_wn = 2.0 * columns - columns**2 * (2.0 + 2j * zeta * w / w_n)
        d_log_zeta = -(columns**2) * 2j * zeta * w / w_n
        derivatives = np.concatenate([d_log_wn, d_log_zeta], axis=1)
        weight = self.sqrt_weight[:, None]
        basis = np.concatenate([columns.real, columns.imag]) * weight
        if self.extra is not None:
            basis = np.concatenate([basis, self.extra], axis=1)
        d_basis = np.concatenate([derivatives.real, derivatives.imag]) * weight
        q, r = np.linalg.qr(basis)
        coefficients = np.linalg.lstsq(r, q.T @ self.target, rcond=None)[0]
        residual = basis @ coefficients - self.target
        self._cache = (key, d_basis, q, coefficients, residual)
        return d_basis, q, coefficients, residual

    def linear(self, params: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._solve(params)[2]

    def residual(self, params: NDArray[np.float64]) -> NDArray[np.float64]:
        return self._solve(params)[3]

    def jacobian(self, params: NDArray[np.float64]) -> NDArray[np.float64]:
        d_basis, q, coefficients, _ = self._solve(params)
        half = params.size // 2
        scaled = d_basis * np.concatenate([coefficients[:half], coefficients[:half]])
        projected: NDArray[np.float64] = scaled - q @ (q.T @ scaled)
        return projected


def _peaks(
    omega: NDArray[np.float64], y: NDArray[np.complex128], n_modes: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The ``n_modes`` most prominent peaks of ``|y|`` and their half-power damping ratios."""
    magnitude = np.abs(y)
    index, props = find_peaks(magnitude, prominence=0.0)
    if index.size < n_modes:
        raise DataError(
            f"fit_modes: {index.size} peak(s) in the band for {n_modes} mode(s); give fewer "
            "modes, a wider band, or initial frequencies"
        )
    chosen = np.sort(index[np.argsort(props["prominences"])[::-1][:n_modes]])
    zeta = np.array([_half_power_zeta(omega, y, int(i)) for i in chosen])
    return omega[chosen], zeta


def _half_power_zeta(omega: NDArray[np.float64], y: NDArray[np.complex128], peak: int) -> float:
    """``(w_2 - w_1) / (2 w_peak)`` where ``|y|`` falls to ``1/sqrt 2`` of the peak each side."""
    magnitude = np.abs(y)
    level = magnitude[peak] / math.sqrt(2.0)
    edges = []
    for step in (-1, 1):
        i = peak
        while 0 <= i + step < magnitude.size and magnitude[i + step] > level:
            i += step
        j = i + step
        if not 0 <= j < magnitude.size:
            continue
        fraction = (magnitude[i] - level) / (magnitude[i] - magnitude[j])
        edges.append(abs(omega[i] + fraction * (omega[j] - omega[i]) - omega[peak]))
    if not edges:
        return _ZETA_FALLBACK
    half_width = sum(edges) / len(edges)
    return float(np.clip(half_width / omega[peak], 2 * _ZETA_MIN, _ZETA_MAX / 2))


def _near(
    omega: NDArray[np.float64],
    h: NDArray[np.complex128],
    fitted: NDArray[np.complex128],
    weight: NDArray[np.float64],
    omega_n: float,
    zeta: float,
) -> tuple[NDArray[np.complex128], NDArray[np.complex128], NDArray[np.float64]]:
    """The samples within ``omega_n (1 +- zeta)``, at least the three nearest to ``omega_n``."""
    keep = np.abs(omega - omega_n) <= zeta * omega_n
    if np.count_nonzero(keep) < 3:
        keep = np.zeros(omega.size, dtype=bool)
        keep[np.argsort(np.abs(omega - omega_n))[:3]] = True
    return h[keep], fitted[keep], weight[keep]


def _norm(
    h: NDArray[np.complex128], fitted: NDArray[np.complex128], weight: NDArray[np.float64]
) -> float:
    """``sqrt(sum w |h - fitted|^2 / sum w |h|^2)``."""
    total = float(np.sum(weight * np.abs(h) ** 2))
    if total == 0.0:
        return math.inf
    return math.sqrt(float(np.sum(weight * np.abs(h - fitted) ** 2)) / total)
