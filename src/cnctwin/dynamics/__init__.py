"""Structural dynamics: FRFs from impact tests and modal fitting.

Public API::

    from cnctwin.dynamics import FRF, impact_frf, fit_modes

    frf = impact_frf(force_n, acceleration_m_s2, dt=1 / 51200, tau=0.1).to_receptance()
    fit = fit_modes(frf, n_modes=2, omega_band=(2 * pi * 500, 2 * pi * 3000))
    for mode in fit.modes:
        mode.omega_n, mode.zeta, mode.stiffness, mode.mass, mode.damping

SI units throughout: rad/s, s, N, m/N, kg, N/m, N s/m.
"""

from cnctwin.dynamics.frf import (
    FRF,
    FRFQuantity,
    accelerance_to_receptance,
    exponential_window,
    force_window,
    impact_frf,
    window_damping_correction,
)
from cnctwin.dynamics.modal import ModalFit, Mode, default_band, fit_modes, modal_frf
from cnctwin.dynamics.stability import (
    MillingProcess,
    OrthogonalProcess,
    ProcessDamping,
    StabilityLobes,
    ToolDynamics,
    ToolMode,
    floquet_multipliers,
    sdm_lobes,
    zoa_absolute_depth,
    zoa_lobes,
)

__all__ = [
    "FRF",
    "FRFQuantity",
    "MillingProcess",
    "ModalFit",
    "Mode",
    "OrthogonalProcess",
    "ProcessDamping",
    "StabilityLobes",
    "ToolDynamics",
    "ToolMode",
    "accelerance_to_receptance",
    "default_band",
    "exponential_window",
    "fit_modes",
    "floquet_multipliers",
    "force_window",
    "impact_frf",
    "modal_frf",
    "sdm_lobes",
    "window_damping_correction",
    "zoa_absolute_depth",
    "zoa_lobes",
]
