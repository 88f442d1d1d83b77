"""Tool condition twins: wear estimation from spindle torque, wear stages and remaining life;
wear compensation in turning from part measurements (tool twin, lathe twin, heritage).

Units of the torque-based twins follow their paper, named in every argument: wear in mm,
material in mm^3, torque in N m. The compensation twins (Bolyn 2023) are in SI: deviations and
corrections in m, drifts in m per part.
"""

from cnctwin.wear.compensation import (
    STABILITY_CRITERION,
    EndOfLifeSigns,
    Heritage,
    LatheTwin,
    ManufacturingParameters,
    Observation,
    ToolTwin,
    drift_fit,
    round_to_resolution,
)
from cnctwin.wear.ekf import (
    CHRISTIAND2024,
    EKFPreset,
    EKFStep,
    LogisticWear,
    WearEKF,
    WearTorque,
    material_removed_mm3,
)
from cnctwin.wear.fitting import (
    LogisticFit,
    fit_logistic_wear,
    fit_wear_torque,
    logistic_wear_curve,
)
from cnctwin.wear.lathe_simulator import (
    DEFAULT_PARTS,
    TESTS,
    LatheRun,
    LatheScenario,
    run_test,
    simulate,
)
from cnctwin.wear.stages import RemainingLife, StageEvent, StageMonitor, remaining_life
from cnctwin.wear.torque_series import (
    IDLE_TORQUE_NM,
    EKFRun,
    TorqueSeries,
    run_filter,
    synthetic_session,
)

__all__ = [
    "CHRISTIAND2024",
    "STABILITY_CRITERION",
    "TESTS",
    "EKFPreset",
    "EKFRun",
    "EKFStep",
    "EndOfLifeSigns",
    "Heritage",
    "LatheRun",
    "LatheScenario",
    "LatheTwin",
    "LogisticFit",
    "LogisticWear",
    "ManufacturingParameters",
    "Observation",
    "RemainingLife",
    "StageEvent",
    "StageMonitor",
    "ToolTwin",
    "TorqueSeries",
    "WearEKF",
    "WearTorque",
    "drift_fit",
    "fit_logistic_wear",
    "fit_wear_torque",
    "logistic_wear_curve",
    "material_removed_mm3",
    "remaining_life",
    "round_to_resolution",
    "run_filter",
    "run_test",
    "simulate",
    "synthetic_session",
    "DEFAULT_PARTS",
    "IDLE_TORQUE_NM",
]
