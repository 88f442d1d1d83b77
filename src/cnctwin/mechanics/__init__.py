"""Cutting mechanics: milling and turning forces, torque, power, coefficients, materials.

Public API::

    from cnctwin.mechanics import (
        CuttingCoefficients, EndMill, Engagement, milling_forces, mean_forces,
    )

    cutter = EndMill(diameter_m=0.012, teeth=3, helix_rad=0.52)
    cut = Engagement.from_depths(cutter, width_m=0.003, depth_m=0.005, down_milling=True)
    k = CuttingCoefficients.from_n_mm(745.1, 360.98, 0.0, 31.49, 21.85, 0.0)
    wave = milling_forces(cutter, k, cut, feed_per_tooth_m=5e-5, spindle_rad_s=1047.2)

SI units throughout (m, N, Pa, N/m, rad, rad/s, N m, W). Frame and sign conventions are in
:mod:`cnctwin.mechanics.engagement` and :mod:`cnctwin.mechanics.milling`.
"""

from cnctwin.mechanics.coefficients import CuttingCoefficients
from cnctwin.mechanics.cutter import CutterKind, CutterSlices, EndMill
from cnctwin.mechanics.engagement import Engagement, immersion_angles
from cnctwin.mechanics.milling import (
    ForceWaveform,
    MeanForces,
    flat_end_mill_mean_forces,
    mean_forces,
    milling_forces,
)

__all__ = [
    "CutterKind",
    "CutterSlices",
    "CuttingCoefficients",
    "EndMill",
    "Engagement",
    "ForceWaveform",
    "MeanForces",
    "flat_end_mill_mean_forces",
    "immersion_angles",
    "mean_forces",
    "milling_forces",
]
