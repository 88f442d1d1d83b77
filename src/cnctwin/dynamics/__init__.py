"""Structural dynamics: FRFs from impact tests and modal fitting.

Public API::

    from cnctwin.dynamics import FRF, impact_frf, fit_modes

    frf = impact_frf(force_n, acceleration_m_s2, dt=1 / 51200, tau=0.1).to_receptance()
    fit = fit_modes(frf, n_modes=2, omega_band=(2 * pi * 500, 2 * pi * 3000))
    for mode in fit.modes:
        mode.omega_n, mode.zeta, mode.stiffness, mode.mass, mode.damping

SI units throughout: rad/s, s, N, m/N, kg, N/m, N s/m.
"""

from cnctwin.dynamics.chatter_detection import (
    DEFAULT_THRESHOLD,
    ChatterDetection,
    DetectorSettings,
    StreamingChatterDetector,
    WindowVerdict,
    detect_chatter,
)
from cnctwin.dynamics.config import (
    MAX_POINTS,
    MIN_IMMERSION,
    StabilityConfig,
    load_stability_config,
    load_tool_stability,
)
from cnctwin.dynamics.frf import (
    FRF,
    FRFQuantity,
    accelerance_to_receptance,
    exponential_window,
    force_window,
    impact_frf,
    window_damping_correction,
)
from cnctwin.dynamics.milling_run import (
    CalibratedCut,
    DampingCalibration,
    MillingRun,
    calibrate_damping_cuts,
    run_milling,
)
from cnctwin.dynamics.modal import ModalFit, Mode, default_band, fit_modes, modal_frf
from cnctwin.dynamics.process_damping import (
    CalibrationSetup,
    GammaFit,
    ProcessDampingModel,
    calibrate_cpd,
    cut_process_damping,
    fit_process_damping_model,
    read_damping_model,
)
from cnctwin.dynamics.roadmap import (
    DEFAULT_SDM_POINTS,
    RoadmapSegment,
    StabilityRoadmap,
    program_roadmap,
    stability_roadmap,
)
from cnctwin.dynamics.stability import (
    MillingProcess,
    OrthogonalProcess,
    ProcessDamping,
    SdmCost,
    StabilityLobes,
    ToolDynamics,
    ToolMode,
    floquet_multipliers,
    sdm_cost,
    sdm_lobes,
    zoa_absolute_depth,
    zoa_lobes,
)
from cnctwin.dynamics.time_domain import MillingVibration, simulate_milling
from cnctwin.dynamics.vibration_stream import CutConditions, MillingStream

__all__ = [
    "CutConditions",
    "MillingStream",
    "CalibratedCut",
    "CalibrationSetup",
    "ChatterDetection",
    "DEFAULT_SDM_POINTS",
    "DEFAULT_THRESHOLD",
    "DampingCalibration",
    "DetectorSettings",
    "FRF",
    "FRFQuantity",
    "GammaFit",
    "MAX_POINTS",
    "MIN_IMMERSION",
    "MillingProcess",
    "MillingRun",
    "MillingVibration",
    "ModalFit",
    "Mode",
    "OrthogonalProcess",
    "ProcessDamping",
    "ProcessDampingModel",
    "SdmCost",
    "StabilityConfig",
    "StabilityLobes",
    "RoadmapSegment",
    "StabilityRoadmap",
    "StreamingChatterDetector",
    "WindowVerdict",
    "ToolDynamics",
    "ToolMode",
    "accelerance_to_receptance",
    "calibrate_cpd",
    "calibrate_damping_cuts",
    "cut_process_damping",
    "default_band",
    "detect_chatter",
    "exponential_window",
    "fit_modes",
    "fit_process_damping_model",
    "floquet_multipliers",
    "force_window",
    "impact_frf",
    "load_stability_config",
    "load_tool_stability",
    "modal_frf",
    "program_roadmap",
    "read_damping_model",
    "run_milling",
    "sdm_cost",
    "sdm_lobes",
    "simulate_milling",
    "stability_roadmap",
    "window_damping_correction",
    "zoa_absolute_depth",
    "zoa_lobes",
]
