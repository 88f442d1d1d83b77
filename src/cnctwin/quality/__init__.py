"""Surface quality: roughness from a fitted power law (Royandi 2026) and ideal kinematic profiles.

The power law takes features in the units it was fitted in (named in the features, e.g.
``ap_mm``); the kinematic profiles are in SI units (m, rad).
"""

from cnctwin.quality.form_error import end_mill_stiffness, form_error, wall_normal_force
from cnctwin.quality.roughness import (
    ROYANDI_2026_EQ24,
    FeedMarks,
    FitMetrics,
    PowerLawFit,
    PowerLawModel,
    end_mill_feed_marks,
    fit_metrics,
    fit_power_law,
    flat_end_mill_ra,
    flat_end_mill_rt,
    milling_cusp_height,
    milling_cusp_ra,
    read_power_law_model,
    turning_ra,
    turning_rt,
)

__all__ = [
    "ROYANDI_2026_EQ24",
    "FeedMarks",
    "FitMetrics",
    "PowerLawFit",
    "PowerLawModel",
    "end_mill_feed_marks",
    "end_mill_stiffness",
    "fit_metrics",
    "fit_power_law",
    "flat_end_mill_ra",
    "flat_end_mill_rt",
    "form_error",
    "milling_cusp_height",
    "milling_cusp_ra",
    "read_power_law_model",
    "turning_ra",
    "turning_rt",
    "wall_normal_force",
]
