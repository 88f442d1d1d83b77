"""Cutting mechanics: milling, turning and drilling forces, torque, power, coefficients,
materials, elastic machining-induced residual stress (Ward 2021, Eq. 3-5).

Public API::

    from cnctwin.geometry import Cutter
    from cnctwin.mechanics import (
        CuttingCoefficients, ImmersionIntervals, milling_forces, mean_forces,
    )

    cutter = Cutter.flat(diameter_mm=12.0, flute_length_mm=25.0, flutes=3, helix_rad=0.52)
    cut = ImmersionIntervals.from_depths(cutter, width_m=0.003, depth_m=0.005, down_milling=True)
    k = CuttingCoefficients.from_n_mm(745.1, 360.98, 0.0, 31.49, 21.85, 0.0)
    wave = milling_forces(cutter, k, cut, feed_per_tooth_m=5e-5, spindle_rad_s=1047.2)

SI units throughout (m, N, Pa, N/m, rad, rad/s, N m, W); the cutter
(:class:`cnctwin.geometry.Cutter`, mm) is read through its SI views. Frame and sign
conventions are in :mod:`cnctwin.mechanics.engagement` and :mod:`cnctwin.mechanics.milling`.
"""

from cnctwin.mechanics.coefficients import CuttingCoefficients
from cnctwin.mechanics.drilling import (
    DrillingLoad,
    DrillingMaterial,
    drilling_load,
    drilling_material,
    drilling_materials,
    tapping_torque,
)
from cnctwin.mechanics.engagement import ImmersionIntervals, immersion_angles
from cnctwin.mechanics.identification import identify_coefficients
from cnctwin.mechanics.materials import (
    ElasticMaterial,
    MaterialsLibrary,
    elastic_material,
    kienzle_material,
    kienzle_milling_coefficients,
    load_materials,
    milling_entry_toml,
    milling_material,
)
from cnctwin.mechanics.milling import (
    ForceWaveform,
    MeanForces,
    flat_end_mill_mean_forces,
    mean_forces,
    milling_forces,
)
from cnctwin.mechanics.residual_stress import (
    ElasticMirsModel,
    LoadingStresses,
    ResidualStressProfile,
    SurfaceLoad,
    edge_surface_load,
    elastic_mirs,
    elastic_release,
    loading_stresses,
    milling_surface_load,
)
from cnctwin.mechanics.turning import (
    TurningCoefficients,
    edge_force_turning,
    kienzle_cutting_force,
    oblique_coefficients,
    turning_chip,
)

__all__ = [
    "CuttingCoefficients",
    "DrillingLoad",
    "DrillingMaterial",
    "ElasticMaterial",
    "ElasticMirsModel",
    "ForceWaveform",
    "ImmersionIntervals",
    "LoadingStresses",
    "MaterialsLibrary",
    "MeanForces",
    "ResidualStressProfile",
    "SurfaceLoad",
    "TurningCoefficients",
    "drilling_load",
    "drilling_material",
    "drilling_materials",
    "edge_force_turning",
    "edge_surface_load",
    "elastic_material",
    "elastic_mirs",
    "elastic_release",
    "flat_end_mill_mean_forces",
    "identify_coefficients",
    "immersion_angles",
    "kienzle_cutting_force",
    "kienzle_material",
    "kienzle_milling_coefficients",
    "load_materials",
    "loading_stresses",
    "mean_forces",
    "milling_forces",
    "milling_entry_toml",
    "milling_material",
    "milling_surface_load",
    "oblique_coefficients",
    "tapping_torque",
    "turning_chip",
]
