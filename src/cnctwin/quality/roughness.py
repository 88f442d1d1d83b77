"""Surface roughness: the empirical power law of Royandi 2026 and the ideal (kinematic) profiles.

Two kinds of model live here.

- The power law ``Ra = b0 ap^b1 S^b2 fz^b3 V^b4`` of Royandi et al. 2026 (Eq. 23-25), fitted by
  least squares on the logarithms: the measured roughness of a set of cuts against their cutting
  parameters and a vibration feature (the RMS acceleration, measured or predicted by a dynamic
  model). It takes any set of positive features by name. A power law with a free constant is not
  dimensionally homogeneous: ``b0`` absorbs the units of every feature and of the target, so a
  model is valid only in the units it was fitted in. The library never converts them; name the
  features with their units (``ap_mm``, ``spindle_rpm``, ``fz_mm``, ``vibration_g``, target
  ``ra_um``), as the CLI does.
- The ideal roughness left by the tool's geometry and feed alone (no vibration, wear, built-up
  edge or side flow), in SI units: a nose radius in turning, the cusps between the arcs of a
  ball or bull-nose end mill, the saw-tooth of a flat end mill's dished end edge.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import CnctwinError, ConfigError, DataError, InputError

__all__ = [
    "ROYANDI_2026_EQ24",
    "FeedMarks",
    "FitMetrics",
    "PowerLawFit",
    "PowerLawModel",
    "fit_metrics",
    "fit_power_law",
    "end_mill_feed_marks",
    "flat_end_mill_ra",
    "flat_end_mill_rt",
    "milling_cusp_height",
    "milling_cusp_ra",
    "read_power_law_model",
    "turning_ra",
    "turning_rt",
]

FloatOrArray = float | NDArray[np.float64]


def _positive_samples(name: str, values: ArrayLike) -> NDArray[np.float64]:
    """``values`` as a 1-D float array, each finite and > 0, else a :class:`DataError`."""
    array = np.asarray(values, dtype=float)
    if array.ndim != 1:
        raise DataError(f"'{name}' has shape {array.shape}; give one value per sample (1-D)")
    bad = np.flatnonzero(~(np.isfinite(array) & (array > 0)))
    if bad.size:
        i = int(bad[0])
        raise DataError(
            f"'{name}' sample {i} is {float(array[i])!r}; a power law needs finite values > 0"
        )
    return array


@dataclass(frozen=True, slots=True)
class FitMetrics:
    """How well predictions match measurements, in the measured quantity's units.

    Attributes
    ----------
    r2
        Coefficient of determination ``1 - SS_res / SS_tot`` of the target itself (not its
        logarithm): the share of the target's variance the model explains.
    r2_correlation
        Squared Pearson correlation of measured and predicted values: the ``R^2`` of a linear
        trend line through a measured-vs-predicted plot. This is what Royandi 2026 reports as
        ``R^2`` (their vibration figures 0.9332 for Table 3 and 0.9283 for Table 4 are this
        quantity, not ``r2``). Equal to ``r2`` only for an unbiased linear fit.
    mape_percent
        Mean absolute percentage error ``100 mean(|y - y_hat| / |y|)``, %.
    rmse
        Root-mean-square error ``sqrt(mean((y - y_hat)^2))``, in the target's unit.
    samples
        Number of samples compared.
    """

    r2: float
    r2_correlation: float
    mape_percent: float
    rmse: float
    samples: int


def fit_metrics(measured: ArrayLike, predicted: ArrayLike) -> FitMetrics:
    """R^2, MAPE and RMSE of predictions against measurements (Royandi 2026, section 6.6).

    Parameters
    ----------
    measured
        Measured values, 1-D, finite and non-zero (MAPE divides by them); any unit.
    predicted
        Predicted values in the same unit, same length.

    Returns
    -------
    FitMetrics

    Raises
    ------
    cnctwin.errors.DataError
        For different lengths, fewer than 2 samples, non-finite values, a zero measurement or
        measurements that are all equal (R^2 undefined).
    """
    y = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    if y.ndim != 1 or y.shape != p.shape:
        raise DataError(
            f"measured has shape {y.shape} and predicted {p.shape}; give two 1-D arrays of "
            "equal length"
        )
    if y.size < 2:
        raise DataError(f"metrics need at least 2 samples; got {y.size}")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(p))):
        raise DataError("measured and predicted values must be finite")
    if np.any(y == 0):
        raise DataError(f"measured sample {int(np.flatnonzero(y == 0)[0])} is 0; MAPE needs y != 0")
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    if ss_tot == 0.0:
        raise DataError(
            f"all {y.size} measured values are {float(y[0])!r}; R^2 needs some variation"
        )
    residual = y - p
    spread = float(np.std(p))
    correlation = 0.0 if spread == 0.0 else float(np.corrcoef(y, p)[0, 1])
    return FitMetrics(
        r2=1.0 - float(np.sum(residual**2)) / ss_tot,
        r2_correlation=correlation**2,
        mape_percent=100.0 * float(np.mean(np.abs(residual / y))),
        rmse=float(np.sqrt(np.mean(residual**2))),
        samples=int(y.size),
    )


@dataclass(frozen=True, slots=True)
class PowerLawModel:
    """``target = b0 * prod_i x_i ** b_i`` (Royandi 2026, Eq. 23).

    Attributes
    ----------
    b0
        Leading constant, in the target's unit divided by the product of the features' units
        raised to their exponents (valid only in the units it was fitted in). Royandi 2026 prints
        ``ln(b0)`` in this place in Eq. 24-25 (``1.216292`` is ``b0 = e^1.216292 = 3.37``); see
        :attr:`ln_b0`.
    exponents
        Exponent of each feature, by the feature's name, in fitting order; dimensionless.
    target
        Name of the predicted quantity, with its unit (e.g. ``"ra_um"``).
    """

    b0: float
    exponents: Mapping[str, float]
    target: str = "ra"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.b0) and self.b0 > 0):
            raise ConfigError(f"b0={self.b0!r}; give a finite constant > 0")
        if not self.exponents:
            raise ConfigError("a power law needs at least one feature exponent; got none")
        for name, value in self.exponents.items():
            if not math.isfinite(value):
                raise ConfigError(f"exponent of '{name}' is {value!r}; give a finite number")

    @property
    def ln_b0(self) -> float:
        """``ln(b0)``: the intercept of the log-linear regression (what Royandi prints)."""
        return math.log(self.b0)

    @property
    def features(self) -> tuple[str, ...]:
        """Feature names, in fitting order."""
        return tuple(self.exponents)

    def predict(self, features: Mapping[str, ArrayLike]) -> NDArray[np.float64]:
        """Evaluate the power law.

        Parameters
        ----------
        features
            Value(s) of every feature of the model, by name, in the units of the fit; each
            finite and > 0. Extra names are ignored.

        Returns
        -------
        numpy.ndarray
            Predicted target, in the target's unit, broadcast over the features' shapes.

        Raises
        ------
        cnctwin.errors.DataError
            For a missing feature or a value that is not finite and > 0.
        """
        missing = [name for name in self.exponents if name not in features]
        if missing:
            raise DataError(
                f"no value for feature(s) {', '.join(missing)}; the model needs "
                f"{', '.join(self.exponents)}"
            )
        log_y = np.full((), math.log(self.b0))
        for name, exponent in self.exponents.items():
            x = np.asarray(features[name], dtype=float)
            if not np.all(np.isfinite(x) & (x > 0)):
                bad = float(x[~(np.isfinite(x) & (x > 0))].flat[0])
                raise DataError(f"'{name}' is {bad!r}; the power law needs finite values > 0")
            log_y = log_y + exponent * np.log(x)
        roughness: NDArray[np.float64] = np.exp(log_y)
        return roughness


#: Royandi 2026 Eq. 24: Ra (um) of full-slot milling of AL6061 with a 4-flute carbide end
#: mill from ``ap_mm`` (mm), ``spindle_rpm`` (rpm), ``fz_mm`` (mm) and the measured RMS
#: vibration acceleration ``vibration_g`` (g), fitted on the paper's 56 cuts (ap 1-4 mm,
#: 3000-9500 rpm, fz 0.05-0.1 mm, V 0.8-5.6 g). The paper prints ``ln(b0)`` = 1.216292 in
#: ``b0``'s place (docs/validation.md, "Surface roughness"); the exponents are printed as
#: they are, all positive (checked against the refit of Tables 3 and 4).
ROYANDI_2026_EQ24 = PowerLawModel(
    b0=math.exp(1.216292),
    exponents={
        "ap_mm": 0.389456,
        "spindle_rpm": 0.004973,
        "fz_mm": 0.551936,
        "vibration_g": 0.173492,
    },
    target="ra_um",
)


def read_power_law_model(path: Path, default_target: str = "ra_um") -> PowerLawModel:
    """Read a power-law model from a JSON file: an object with ``b0`` (a number), ``exponents``
    (a number per feature name) and optionally ``target`` (a name, ``default_target`` if absent),
    as ``cnctwin roughness fit --json`` writes it; other keys are ignored. The numbers are in the
    units the model was fitted in (see :class:`PowerLawModel`).

    Raises
    ------
    cnctwin.errors.DataError
        ``"FILE: ..."`` for a file that is not JSON or not such a model.
    OSError
        If the file cannot be read.
    """
    try:
        document = json.loads(Path(path).read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise DataError(f"{path}: not a JSON model file ({err})") from None
    if not isinstance(document, dict):
        raise DataError(f"{path}: not a roughness model; give the JSON of 'roughness fit --json'")
    b0, exponents = document.get("b0"), document.get("exponents")
    target = document.get("target", default_target)
    if not isinstance(b0, int | float) or isinstance(b0, bool):
        raise DataError(f"{path}: b0 is {b0!r}; give a number (the JSON of 'roughness fit --json')")
    if not isinstance(exponents, dict) or not all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in exponents.values()
    ):
        raise DataError(f"{path}: exponents is {exponents!r}; give a number per feature name")
    if not isinstance(target, str):
        raise DataError(f"{path}: target is {target!r}; give a name such as 'ra_um'")
    try:
        return PowerLawModel(
            b0=float(b0), exponents={str(k): float(v) for k, v in exponents.items()}, target=target
        )
    except CnctwinError as err:
        raise DataError(f"{path}: {err}") from None


@dataclass(frozen=True, slots=True)
class PowerLawFit:
    """A power law fitted to samples, with its in-sample metrics.

    Attributes
    ----------
    model
        The fitted law.
    metrics
        R^2, MAPE and RMSE of the model on the samples it was fitted to, in the target's unit.
    """

    model: PowerLawModel
    metrics: FitMetrics


def fit_power_law(
    features: Mapping[str, ArrayLike], target: ArrayLike, *, target_name: str = "ra"
) -> PowerLawFit:
    """Fit ``target = b0 prod x_i^b_i`` by least squares on the logarithms (Royandi 2026, Eq. 23).

    ``ln(target) = ln(b0) + sum_i b_i ln(x_i)`` is linear in ``ln(b0)`` and the exponents, and
    is solved by ordinary least squares, as in the paper (section 6.6 (b)): the fit minimises
    the squared error of ``ln(target)``, not of the target.

    Parameters
    ----------
    features
        Samples of each feature by name (e.g. ``{"ap_mm": ..., "spindle_rpm": ..., "fz_mm": ...,
        "vibration_g": ...}``), 1-D, equal lengths, finite and > 0, in any units (the fitted
        ``b0`` is valid in those units only).
    target
        Measured target per sample (e.g. Ra in um), finite and > 0.
    target_name
        Name of the target, with its unit, kept in the model.

    Returns
    -------
    PowerLawFit
        The model and its in-sample :class:`FitMetrics` (in the target's unit).

    Raises
    ------
    cnctwin.errors.DataError
        For no features, arrays of different lengths, a value that is not finite and > 0,
        no more samples than coefficients (features + 1), or a constant or collinear feature
        whose exponent the samples cannot determine.
    """
    if not features:
        raise DataError("a power law needs at least one feature; got none")
    y = _positive_samples(target_name, target)
    columns = {name: _positive_samples(name, values) for name, values in features.items()}
    for name, column in columns.items():
        if column.size != y.size:
            raise DataError(
                f"'{name}' has {column.size} samples but '{target_name}' has {y.size}; "
                "give one value per sample"
            )
    unknowns = len(columns) + 1
    if y.size <= unknowns:
        raise DataError(
            f"{y.size} samples for {unknowns} coefficients (b0 and {len(columns)} exponents); "
            f"give at least {unknowns + 1}"
        )
    for name, column in columns.items():
        if np.all(column == column[0]):
            raise DataError(
                f"'{name}' is {float(column[0])!r} in every sample; its exponent cannot be fitted "
                "(drop the feature or vary it)"
            )
    design = np.column_stack([np.ones(y.size), *(np.log(c) for c in columns.values())])
    coefficients, _, rank, _ = np.linalg.lstsq(design, np.log(y), rcond=None)
    if rank < unknowns:
        raise DataError(
            f"the logarithms of {', '.join(columns)} are collinear (rank {rank} of {unknowns}); "
            "drop a feature that is a power-law combination of the others"
        )
    model = PowerLawModel(
        b0=math.exp(float(coefficients[0])),
        exponents={name: float(b) for name, b in zip(columns, coefficients[1:], strict=True)},
        target=target_name,
    )
    return PowerLawFit(model=model, metrics=fit_metrics(y, model.predict(columns)))


def _lengths(**values: ArrayLike) -> list[NDArray[np.float64]]:
    """Each named length (m) as an array, checked finite and > 0, else an :class:`InputError`."""
    arrays = []
    for name, value in values.items():
        array = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(array) & (array > 0)):
            raise InputError(f"{name}={value!r}; give finite lengths > 0 m")
        arrays.append(array)
    return arrays


def _scalar_or_array(value: NDArray[np.float64]) -> FloatOrArray:
    return float(value) if value.ndim == 0 else value


def _check_feed_below_diameter(feed: NDArray[np.float64], radius: NDArray[np.float64]) -> None:
    too_far = feed >= 2.0 * radius
    if np.any(too_far):
        f, r = (float(np.broadcast_to(a, too_far.shape)[too_far].flat[0]) for a in (feed, radius))
        raise InputError(
            f"feed {f!r} m >= 2 x radius {r!r} m: consecutive arcs do not overlap and the "
            "profile is not made by the arc alone; give a feed below the arc's diameter"
        )


def turning_rt(feed_per_rev_m: ArrayLike, nose_radius_m: ArrayLike) -> FloatOrArray:
    """Ideal peak-to-valley roughness of a turned surface, ``Rt = f^2 / (8 r)``, m.

    The profile left by a round nose of radius ``r`` fed ``f`` per revolution is a row of arcs
    ``f`` apart; its exact height is ``r - sqrt(r^2 - f^2/4)``, and ``f^2/(8 r)`` is its
    parabolic approximation (within 1 % for ``f < 0.4 r``; Qu and Shih 2003, Machining
    Science and Technology 7(2) 281-294). Valid while the nose alone makes the profile (feed
    below the nose diameter, and small enough that the straight edges do not cut it).

    Parameters
    ----------
    feed_per_rev_m
        Feed per revolution f, m, > 0.
    nose_radius_m
        Tool nose (corner) radius r, m, > 0 and > f/2.

    Returns
    -------
    float or numpy.ndarray
        Rt, m.

    Raises
    ------
    cnctwin.errors.InputError
        For a feed or radius that is not finite and > 0, or a feed of at least 2 r.
    """
    f, r = _lengths(feed_per_rev_m=feed_per_rev_m, nose_radius_m=nose_radius_m)
    _check_feed_below_diameter(f, r)
    return _scalar_or_array(f**2 / (8.0 * r))


def turning_ra(feed_per_rev_m: ArrayLike, nose_radius_m: ArrayLike) -> FloatOrArray:
    """Ideal arithmetic-mean roughness of a turned surface, ``Ra = f^2 / (32 r)``, m.

    The textbook ideal roughness of a round-nosed tool (Groover, Fundamentals of Modern
    Manufacturing, surface finish in machining: ideal roughness ``Ri = f^2 / (32 NR)``), i.e.
    ``Rt / 4`` of :func:`turning_rt`. The parabolic profile's exact Ra is
    ``f^2 / (18 sqrt(3) r) = 0.0321 f^2 / r`` (Boothroyd and Knight, Fundamentals of Machining
    and Machine Tools), 2.6 % above this; real surfaces are rougher than either.

    Parameters
    ----------
    feed_per_rev_m
        Feed per revolution f, m, > 0.
    nose_radius_m
        Tool nose (corner) radius r, m, > 0 and > f/2.

    Returns
    -------
    float or numpy.ndarray
        Ra, m.

    Raises
    ------
    cnctwin.errors.InputError
        For a feed or radius that is not finite and > 0, or a feed of at least 2 r.
    """
    f, r = _lengths(feed_per_rev_m=feed_per_rev_m, nose_radius_m=nose_radius_m)
    _check_feed_below_diameter(f, r)
    return _scalar_or_array(f**2 / (32.0 * r))


def milling_cusp_height(feed_per_tooth_m: ArrayLike, radius_m: ArrayLike) -> FloatOrArray:
    """Height of the feed-mark cusps between the arcs of a ball or bull-nose end mill, m.

    Successive teeth leave arcs of the cutting edge's radius ``R`` spaced by the feed per tooth
    ``fz`` along the feed; two such arcs meet ``fz/2`` from each arc's lowest point, at a height
    ``h = R - sqrt(R^2 - fz^2/4)`` (exact for circular arcs; ``~ fz^2/(8 R)``; Qu and Shih
    2003). ``R`` is the ball radius of a ball-end mill whose contact point is off the tool axis
    (a tilted tool, or a wall), or the corner radius of a bull-nose mill where the corner makes
    the surface. The same formula gives the step-over scallop between passes with the
    step-over ``ae`` in place of ``fz``.

    Parameters
    ----------
    feed_per_tooth_m
        Feed per tooth fz (or step-over), m, > 0.
    radius_m
        Radius R of the arc the cutting edge leaves, m, > 0 and > fz/2.

    Returns
    -------
    float or numpy.ndarray
        Cusp height (the profile's Rt), m.

    Raises
    ------
    cnctwin.errors.InputError
        For a feed or radius that is not finite and > 0, or a feed of at least 2 R.
    """
    f, r = _lengths(feed_per_tooth_m=feed_per_tooth_m, radius_m=radius_m)
    _check_feed_below_diameter(f, r)
    half = 0.5 * f
    # r - sqrt(r^2 - h^2) written without cancellation for small feeds.
    return _scalar_or_array(half**2 / (r + np.sqrt(r**2 - half**2)))


def milling_cusp_ra(feed_per_tooth_m: ArrayLike, radius_m: ArrayLike) -> FloatOrArray:
    """Ideal Ra of the feed marks of a ball or bull-nose end mill, ``fz^2 / (32 R)``, m.

    The turning formula (:func:`turning_ra`) with the feed per tooth for the feed and the
    radius of the generating arc for the nose radius; see :func:`milling_cusp_height` for
    which radius applies.

    Parameters
    ----------
    feed_per_tooth_m
        Feed per tooth fz (or step-over), m, > 0.
    radius_m
        Radius R of the arc the cutting edge leaves, m, > 0 and > fz/2.

    Returns
    -------
    float or numpy.ndarray
        Ra, m.

    Raises
    ------
    cnctwin.errors.InputError
        For a feed or radius that is not finite and > 0, or a feed of at least 2 R.
    """
    f, r = _lengths(feed_per_tooth_m=feed_per_tooth_m, radius_m=radius_m)
    _check_feed_below_diameter(f, r)
    return _scalar_or_array(f**2 / (32.0 * r))


def _dish_tangent(dish_angle_rad: ArrayLike) -> NDArray[np.float64]:
    angle = np.asarray(dish_angle_rad, dtype=float)
    if not np.all(np.isfinite(angle) & (angle >= 0) & (angle < 0.5 * math.pi)):
        raise InputError(f"dish_angle_rad={dish_angle_rad!r}; give 0 <= angle < pi/2 rad")
    tangent: NDArray[np.float64] = np.tan(angle)
    return tangent


def flat_end_mill_rt(feed_per_tooth_m: ArrayLike, dish_angle_rad: ArrayLike) -> FloatOrArray:
    """Ideal peak-to-valley roughness of a floor cut by a sharp-cornered flat end mill, m.

    A sharp corner leaves a saw-tooth of pitch ``fz`` whose flanks are the two cutting edges;
    for edges at approach angles ``kr`` and ``kr'`` its height is ``fz / (cot kr + cot kr')``
    (Boothroyd and Knight, Fundamentals of Machining and Machine Tools, the sharp-tool
    formula). For an end mill the peripheral edge is square to the floor (``kr = 90 deg``) and
    ``kr'`` is the end edge's dish (concavity) angle, so ``Rt = fz tan(kr')``, along the path's
    centre line. With no dish the end edge sweeps the floor flat: the theoretical value is 0,
    and the measured roughness comes from everything else (runout, vibration, wear, the
    material), which is what the power law models.

    Parameters
    ----------
    feed_per_tooth_m
        Feed per tooth fz, m, > 0.
    dish_angle_rad
        Dish angle of the end cutting edge kr', rad, in [0, pi/2) (typically 1-3 deg).

    Returns
    -------
    float or numpy.ndarray
        Rt, m.

    Raises
    ------
    cnctwin.errors.InputError
        For a feed that is not finite and > 0 or an angle outside [0, pi/2).
    """
    (f,) = _lengths(feed_per_tooth_m=feed_per_tooth_m)
    return _scalar_or_array(f * _dish_tangent(dish_angle_rad))


def flat_end_mill_ra(feed_per_tooth_m: ArrayLike, dish_angle_rad: ArrayLike) -> FloatOrArray:
    """Ideal Ra of a floor cut by a sharp-cornered flat end mill, ``fz tan(kr') / 4``, m.

    The saw-tooth of :func:`flat_end_mill_rt` has ``Ra = Rt / 4`` exactly (a triangle wave's
    mean absolute deviation is a quarter of its height).

    Parameters
    ----------
    feed_per_tooth_m
        Feed per tooth fz, m, > 0.
    dish_angle_rad
        Dish angle of the end cutting edge kr', rad, in [0, pi/2).

    Returns
    -------
    float or numpy.ndarray
        Ra, m.

    Raises
    ------
    cnctwin.errors.InputError
        For a feed that is not finite and > 0 or an angle outside [0, pi/2).
    """
    (f,) = _lengths(feed_per_tooth_m=feed_per_tooth_m)
    return _scalar_or_array(0.25 * f * _dish_tangent(dish_angle_rad))


@dataclass(frozen=True, slots=True)
class FeedMarks:
    """Ideal roughness of the feed marks an end mill leaves, m.

    Attributes
    ----------
    floor_ra, floor_rt
        Ra and Rt (peak to valley) of the floor (the surface the tool's end makes), m. The
        profile is periodic with one identical mark per tooth, so its Rz (mean of the
        peak-to-valley heights of the sampling lengths) equals Rt.
    wall_rt
        Rt of a wall the tool's periphery makes (arcs of the tool radius ``D/2``, spaced by
        the feed per tooth: the circular-path approximation of the tooth's trochoid, whose
        marks are ``fz^2 / (8 (R +- z fz / pi))`` in up and down milling, Martellotti 1941,
        Trans. ASME 63: within 1 % of it for ``fz < 0.03 R / z``), m.
    """

    floor_ra: FloatOrArray
    floor_rt: FloatOrArray
    wall_rt: FloatOrArray


def end_mill_feed_marks(
    kind: str,
    feed_per_tooth_m: ArrayLike,
    diameter_m: float,
    *,
    corner_radius_m: float = 0.0,
    dish_angle_rad: float = 0.0,
) -> FeedMarks:
    """Ideal (kinematic) roughness of the floor and wall of an end mill's cut, m.

    The floor of a ``"flat"`` end mill is the saw-tooth of its dished end edge
    (:func:`flat_end_mill_rt`, :func:`flat_end_mill_ra`: 0 without a dish); that of a
    ``"bull"`` (corner radius) or ``"ball"`` end mill the cusps of the arcs of its corner or
    ball radius (:func:`milling_cusp_height`, :func:`milling_cusp_ra`; for a ball, where the
    contact point is off the tool axis). The wall of any of them is the cusps of the arcs of
    its radius ``D/2`` (:func:`milling_cusp_height`). Runout, vibration, wear and side flow
    are not in these figures.

    Parameters
    ----------
    kind
        ``"flat"``, ``"bull"`` or ``"ball"`` (the :class:`cnctwin.config.ToolConfig` kinds).
    feed_per_tooth_m
        Feed per tooth fz, m, > 0 and below twice the radius of the arc that makes the mark.
    diameter_m
        Tool diameter D, m, > 0.
    corner_radius_m
        Corner radius, m, > 0 for ``"bull"`` (ignored otherwise).
    dish_angle_rad
        End-edge dish angle of a ``"flat"`` end mill, rad, in [0, pi/2).

    Returns
    -------
    FeedMarks

    Raises
    ------
    cnctwin.errors.InputError
        For another kind, or a feed, radius or angle outside the ranges above.
    """
    radius = 0.5 * diameter_m
    if kind == "flat":
        floor_ra = flat_end_mill_ra(feed_per_tooth_m, dish_angle_rad)
        floor_rt = flat_end_mill_rt(feed_per_tooth_m, dish_angle_rad)
    elif kind in ("bull", "ball"):
        arc = corner_radius_m if kind == "bull" else radius
        floor_ra = milling_cusp_ra(feed_per_tooth_m, arc)
        floor_rt = milling_cusp_height(feed_per_tooth_m, arc)
    else:
        raise InputError(f"kind={kind!r}; the feed marks are those of 'flat', 'bull' or 'ball'")
    return FeedMarks(floor_ra, floor_rt, milling_cusp_height(feed_per_tooth_m, radius))
