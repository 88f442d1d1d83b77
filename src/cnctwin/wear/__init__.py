"""Tool condition twins: wear estimation from spindle torque, wear stages and remaining life.

Units follow the papers, named in every argument: wear in mm, material in mm^3, torque in N m.
"""

from cnctwin.wear.ekf import (
    CHRISTIAND2024,
    EKFPreset,
    EKFStep,
    LogisticWear,
    WearEKF,
    WearTorque,
    material_removed_mm3,
)
from cnctwin.wear.fitting import LogisticFit, fit_logistic_wear, logistic_wear_curve
from cnctwin.wear.stages import RemainingLife, StageEvent, StageMonitor, remaining_life

__all__ = [
    "CHRISTIAND2024",
    "EKFPreset",
    "EKFStep",
    "LogisticFit",
    "LogisticWear",
    "RemainingLife",
    "StageEvent",
    "StageMonitor",
    "WearEKF",
    "WearTorque",
    "fit_logistic_wear",
    "logistic_wear_curve",
    "material_removed_mm3",
    "remaining_life",
]
