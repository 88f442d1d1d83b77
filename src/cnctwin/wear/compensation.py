"""Tool wear compensation from part measurements: the tool twin and the lathe twin (Bolyn 2023).

In turning mass production the wear of the tool shows as a linear drift of the measured
dimension from part to part. The *tool twin* (:class:`ToolTwin`) receives the deviation of
each measured part from its target, adds back the tool-offset corrections already applied so
that all points share the origin set at calibration (Bolyn 2023, section III.C), fits the
drift ``b`` by least squares through the origin together with the scatter ``sigma`` about it
(their Table 1), trusts the slope once its relative change from one part to the next falls
below a criterion (5 % in the paper), and then corrects the tool offset so that the next part
lands on target, in steps of the lathe's resolution.

The *lathe twin* (:class:`LatheTwin`) holds the active tool twins and the retired ones with
their manufacturing parameters. A new tool inherits ("heritage") the drift of the most similar
retired twin, and uses it as long as its own slope is not yet trusted, so that corrections are
right from the first part.

Sign convention: a correction is the signed change it makes to the produced dimension (m);
the cumulative correction in force is the ``offset``. A measured deviation ``m`` of part ``i``
made under offset ``C`` is stored as the uncorrected deviation ``d_i = m - C``, the drift the
tool would have shown without any correction.

All lengths are in metres, drifts in metres per part; part numbers count the parts produced
since the calibration that set the origin (the first part after it is part 1).

Every state object is a plain dataclass with ``to_dict``/``from_dict`` (JSON-ready values
only), so a registry can store and restore twins.
"""

from __future__ import annotations

import math
import numbers
import operator
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, SupportsIndex

import numpy as np

from cnctwin.errors import ConfigError, DataError, InputError

__all__ = [
    "STABILITY_CRITERION",
    "EndOfLifeSigns",
    "Heritage",
    "LatheTwin",
    "ManufacturingParameters",
    "Observation",
    "ToolTwin",
    "drift_fit",
    "round_to_resolution",
]

#: Largest relative change of the slope between two parts for the slope to be trusted
#: (Bolyn 2023, section III.C: "we obtained satisfactory results with a value of 5%").
STABILITY_CRITERION = 0.05

#: Largest relative difference of the numeric manufacturing parameters for a retired twin to
#: serve as heritage. The paper asks only that the parameters "do not change significantly";
#: 10 % is our choice.
MAX_PARAMETER_DISTANCE = 0.10

#: Where the drift a correction is based on comes from.
Source = Literal["own", "heritage", "none"]


def round_to_resolution(value: float, resolution: float) -> float:
    """Round a length to the nearest multiple of a resolution.

    This is how the lathe applies a correction (only in multiples of its resolution: a
    proposed 2 um correction is not applied by a 5 um lathe, Bolyn 2023 section IV) and how a
    gauge reports a dimension.

    Parameters
    ----------
    value
        The length, m.
    resolution
        The step, m; 0 leaves ``value`` unrounded.

    Returns
    -------
    float
        ``resolution * floor(value / resolution + 1/2)``, m.

    Raises
    ------
    InputError
        If ``value`` is not finite, or ``resolution`` is negative or not finite.
    """
    if not (isinstance(value, int | float) and math.isfinite(value)):
        raise InputError(f"value {value!r}: give a finite length in metres")
    _check_resolution(resolution, "resolution")
    if resolution == 0.0:
        return value
    return resolution * math.floor(value / resolution + 0.5)


def drift_fit(parts: Sequence[float], deviations: Sequence[float]) -> tuple[float, float | None]:
    """Drift and scatter by least squares through the origin (Bolyn 2023, Table 1).

    ``b = sum(i d_i) / sum(i^2)`` and ``sigma = sqrt((sum(d_i^2) - b^2 sum(i^2)) / (n - 2))``.

    Parameters
    ----------
    parts
        Part numbers ``i`` counted from the calibration, dimensionless.
    deviations
        Uncorrected deviations ``d_i`` from the target, m.

    Returns
    -------
    tuple
        The slope ``b`` (m per part) and the scatter ``sigma`` (m), ``None`` below 3 points.

    Raises
    ------
    DataError
        If the sequences differ in length, are empty, or all part numbers are 0.

    Notes
    -----
    Table 1 divides by ``n - 2``, the degrees of freedom of a line with an intercept. The fit
    has one parameter, so ``sigma**2`` overestimates the variance of the scatter by the factor
    ``(n - 1) / (n - 2)`` (1.06 at 18 parts); it is kept as published.
    """
    if len(parts) != len(deviations) or not parts:
        raise DataError(
            f"drift_fit needs as many deviations as parts, at least one; "
            f"got {len(parts)} parts and {len(deviations)} deviations"
        )
    s_id = math.fsum(i * d for i, d in zip(parts, deviations, strict=True))
    s_ii = math.fsum(i * i for i in parts)
    s_dd = math.fsum(d * d for d in deviations)
    if s_ii == 0.0:
        raise DataError("drift_fit needs a part number other than 0")
    return s_id / s_ii, _scatter(s_dd, s_id / s_ii, s_ii, len(parts))


def _scatter(s_dd: float, slope: float, s_ii: float, n: int) -> float | None:
    """Table 1's scatter from the sums, m; None below 3 points."""
    if n < 3:
        return None
    return math.sqrt(max(s_dd - slope * slope * s_ii, 0.0) / (n - 2))


@dataclass(frozen=True, slots=True)
class ManufacturingParameters:
    """The conditions a tool works in, which decide which retired twin a new tool inherits.

    Attributes
    ----------
    material
        Workpiece material (e.g. ``"C45"``); must match exactly.
    tool_reference
        Insert or tool reference (e.g. ``"CNMG 120408"``); must match exactly.
    cutting_speed
        Cutting speed, m/s, > 0.
    feed_per_rev
        Feed per revolution, m, > 0.
    depth_of_cut
        Depth of cut, m, > 0.
    """

    material: str
    tool_reference: str
    cutting_speed: float
    feed_per_rev: float
    depth_of_cut: float

    def __post_init__(self) -> None:
        for name in ("material", "tool_reference"):
            if not str(getattr(self, name)).strip():
                raise ConfigError(f"{name} must be a non-empty name; got {getattr(self, name)!r}")
        for name in ("cutting_speed", "feed_per_rev", "depth_of_cut"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ConfigError(f"{name} must be a positive number (SI); got {value!r}")

    def distance(self, other: ManufacturingParameters) -> float:
        """How different two sets of conditions are, dimensionless.

        Parameters
        ----------
        other
            The conditions to compare with.

        Returns
        -------
        float
            ``inf`` when the material or tool reference differ, else the largest relative
            difference ``|a - b| / max(a, b)`` of cutting speed, feed and depth of cut.
        """
        if (self.material, self.tool_reference) != (other.material, other.tool_reference):
            return math.inf
        pairs = (
            (self.cutting_speed, other.cutting_speed),
            (self.feed_per_rev, other.feed_per_rev),
            (self.depth_of_cut, other.depth_of_cut),
        )
        return max(abs(a - b) / max(a, b) for a, b in pairs)

    def to_dict(self) -> dict[str, Any]:
        """The parameters as a JSON-ready dict (SI values)."""
        return {
            "material": self.material,
            "tool_reference": self.tool_reference,
            "cutting_speed": self.cutting_speed,
            "feed_per_rev": self.feed_per_rev,
            "depth_of_cut": self.depth_of_cut,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ManufacturingParameters:
        """Rebuild from :meth:`to_dict`; ConfigError on a missing or bad value."""
        return cls(**_pick(data, cls.__name__, _PARAMETER_KEYS))


_PARAMETER_KEYS = ("material", "tool_reference", "cutting_speed", "feed_per_rev", "depth_of_cut")


@dataclass(frozen=True, slots=True)
class Heritage:
    """What a new tool twin inherits from a retired one (Bolyn 2023, section III.B).

    Attributes
    ----------
    tool_id
        The retired tool it comes from.
    slope
        Its last trusted drift, m per part.
    sigma
        Its scatter at that part (Table 1), m, or None.
    parts
        How many parts it measured in its life.
    distance
        :meth:`ManufacturingParameters.distance` between the two tools' conditions.
    """

    tool_id: str
    slope: float
    sigma: float | None
    parts: int
    distance: float

    def to_dict(self) -> dict[str, Any]:
        """The heritage as a JSON-ready dict (SI values)."""
        return {
            "tool_id": self.tool_id,
            "slope": self.slope,
            "sigma": self.sigma,
            "parts": self.parts,
            "distance": self.distance,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Heritage:
        """Rebuild from :meth:`to_dict`."""
        return cls(**_pick(data, cls.__name__, ("tool_id", "slope", "sigma", "parts", "distance")))


@dataclass(frozen=True, slots=True)
class Observation:
    """What the tool twin concluded from one measured part.

    Attributes
    ----------
    part
        Part number since calibration.
    measured_deviation
        Measured dimension minus target, m.
    deviation
        The same without the corrections applied so far (``measured - offset``), m.
    slope
        Drift fitted through the origin over all parts so far (Table 1), m per part.
    relative_change
        ``|b_n - b_(n-1)| / |b_n|``, dimensionless; None at the first part or a zero slope.
    sigma
        Scatter about the drift (Table 1), m; None below 3 parts.
    trusted
        True when ``relative_change`` is below the criterion.
    slope_in_use
        The drift the correction is based on: the own slope when trusted, else the
        inherited one, else None (no correction).
    source
        ``"own"``, ``"heritage"`` or ``"none"``: where ``slope_in_use`` comes from.
    correction
        Change of the tool offset to apply before the next part, m (a multiple of the
        lathe's resolution; positive makes the part larger).
    offset
        Cumulative correction in force for the next part, m.
    """

    part: int
    measured_deviation: float
    deviation: float
    slope: float
    relative_change: float | None
    sigma: float | None
    trusted: bool
    slope_in_use: float | None
    source: Source
    correction: float
    offset: float


@dataclass(frozen=True, slots=True)
class EndOfLifeSigns:
    """Signs that the tool approaches the end of its life (Bolyn 2023, section III.C).

    "If the slope begins to change faster and/or the standard deviation begins to increase,
    it might signify an advanced wear of the tool." The recent parts (a window) are compared
    with the parts before them (the reference).

    Attributes
    ----------
    reference_slope
        Drift through the origin over the reference parts, m per part.
    recent_slope
        Drift of the window by least squares with an intercept, m per part.
    slope_t
        ``(recent - reference) / standard error``, signed so that positive means the drift
        grows in its own direction; Student's t with ``reference parts - 1`` degrees of freedom
        under a constant drift.
    reference_sigma
        Scatter of the reference about its drift (one-parameter fit, ``n - 1``), m.
    recent_sigma
        Scatter of the window about its own line (``n - 2``), m.
    accelerating
        ``slope_t`` above Student's quantile at the confidence.
    scatter_growing
        ``(recent_sigma / reference_sigma)**2`` above the F quantile at the confidence.
    """

    reference_slope: float
    recent_slope: float
    slope_t: float
    reference_sigma: float
    recent_sigma: float
    accelerating: bool
    scatter_growing: bool


@dataclass
class ToolTwin:
    """The digital twin of one tool: drift, trust, corrections (Bolyn 2023, section III).

    Create tool twins with :meth:`LatheTwin.mount`, which sets the resolution and heritage
    and applies the first correction; feed each measured part to :meth:`observe`.

    Attributes
    ----------
    tool_id
        Name of the physical tool (insert).
    parameters
        Manufacturing conditions it works in, if known.
    resolution
        Smallest tool-offset step of the lathe, m (0: any correction).
    criterion
        Stability criterion on the relative change of the slope, dimensionless.
    heritage
        What it inherited, if anything.
    initial_correction
        Correction applied before the first part (from the heritage), m.
    parts, measured, slopes, relative_changes, sigmas, trusted, corrections
        History, one entry a measured part: part number; measured deviation (m); slope
        (m/part); relative change; scatter (m); trusted flag; correction applied after it (m).
    """

    tool_id: str
    parameters: ManufacturingParameters | None = None
    resolution: float = 0.0
    criterion: float = STABILITY_CRITERION
    heritage: Heritage | None = None
    initial_correction: float = 0.0
    parts: list[int] = field(default_factory=list)
    measured: list[float] = field(default_factory=list)
    slopes: list[float] = field(default_factory=list)
    relative_changes: list[float | None] = field(default_factory=list)
    sigmas: list[float | None] = field(default_factory=list)
    trusted: list[bool] = field(default_factory=list)
    corrections: list[float] = field(default_factory=list)
    _offsets: list[float] = field(default_factory=list, init=False, repr=False)
    _offset: float = field(default=0.0, init=False, repr=False)
    _s_id: float = field(default=0.0, init=False, repr=False)
    _s_ii: float = field(default=0.0, init=False, repr=False)
    _s_dd: float = field(default=0.0, init=False, repr=False)

    def __post_init__(self) -> None:
        if not str(self.tool_id).strip():
            raise ConfigError(f"tool_id must be a non-empty name; got {self.tool_id!r}")
        _check_resolution(self.resolution, "resolution")
        if not (math.isfinite(self.criterion) and self.criterion > 0):
            raise ConfigError(f"criterion must be a positive fraction; got {self.criterion!r}")
        history = (
            self.measured,
            self.slopes,
            self.relative_changes,
            self.sigmas,
            self.trusted,
            self.corrections,
        )
        if any(len(column) != len(self.parts) for column in history):
            raise DataError(f"tool twin {self.tool_id!r}: history columns differ in length")
        self._offset = self.initial_correction
        for part, measured, correction in zip(
            self.parts, self.measured, self.corrections, strict=True
        ):
            self._offsets.append(self._offset)
            self._accumulate(part, measured - self._offset)
            self._offset += correction

    # -- state ------------------------------------------------------------------------------

    @property
    def count(self) -> int:
        """Number of measured parts."""
        return len(self.parts)

    @property
    def offset(self) -> float:
        """Cumulative correction in force for the next part, m."""
        return self._offset

    @property
    def deviations(self) -> list[float]:
        """Uncorrected deviations ``measured - offset in force``, m, one a measured part."""
        return [m - c for m, c in zip(self.measured, self._offsets, strict=True)]

    @property
    def slope(self) -> float | None:
        """Current drift (Table 1), m per part; None before the first part."""
        return self.slopes[-1] if self.slopes else None

    @property
    def sigma(self) -> float | None:
        """Current scatter (Table 1), m; None below 3 parts."""
        return self.sigmas[-1] if self.sigmas else None

    @property
    def is_trusted(self) -> bool:
        """Whether the current slope meets the stability criterion."""
        return bool(self.trusted) and self.trusted[-1]

    @property
    def last_trusted_slope(self) -> float | None:
        """The latest slope that met the criterion, m per part; what a successor inherits."""
        index = self._last_trusted_index()
        return None if index is None else self.slopes[index]

    def _last_trusted_index(self) -> int | None:
        for index in range(self.count - 1, -1, -1):
            if self.trusted[index]:
                return index
        return None

    @property
    def slope_in_use(self) -> float | None:
        """The drift corrections are based on now: own if trusted, else inherited, else None."""
        return self._slope_in_use()[0]

    def _slope_in_use(self) -> tuple[float | None, Source]:
        if self.is_trusted:
            return self.slopes[-1], "own"
        if self.heritage is not None:
            return self.heritage.slope, "heritage"
        return None, "none"

    # -- behaviour --------------------------------------------------------------------------

    def start(self) -> float:
        """Apply the correction for the first part from the heritage, before any measurement.

        Returns
        -------
        float
            The correction applied, m (0 without heritage).

        Raises
        ------
        DataError
            If parts were already measured.
        """
        if self.parts:
            raise DataError(
                f"tool twin {self.tool_id!r} already measured {self.count} parts; "
                "start() is for a new tool"
            )
        correction = self._correction_for(1)
        self.initial_correction += correction
        self._offset += correction
        return correction

    def observe(self, measured_deviation: float, part: SupportsIndex | None = None) -> Observation:
        """Take one measured part, update the drift and return the correction to apply.

        The correction returned is counted as applied: the lathe applies it before the
        next part (part + 1), which it puts on the predicted drift's target.

        Parameters
        ----------
        measured_deviation
            Measured dimension minus target dimension, m.
        part
            Its number since calibration; default the previous one + 1 (1 for the first).
            Unmeasured parts may be skipped.

        Returns
        -------
        Observation
            Drift, scatter, trust and the correction.

        Raises
        ------
        DataError
            If the deviation is not a finite number or the part number does not increase.
        """
        value = _finite(measured_deviation, "measured deviation (m)")
        last = self.parts[-1] if self.parts else 0
        try:
            number = last + 1 if part is None else operator.index(part)
        except TypeError:
            number = last
        if number <= last:
            raise DataError(
                f"tool twin {self.tool_id!r}: part number must be an integer above {last}; "
                f"got {part!r}"
            )
        offset = self.offset
        deviation = value - offset
        self._accumulate(number, deviation)
        slope = self._s_id / self._s_ii
        previous = self.slopes[-1] if self.slopes else None
        change = None if previous is None or slope == 0.0 else abs(slope - previous) / abs(slope)
        self.parts.append(number)
        self.measured.append(value)
        self._offsets.append(offset)
        self.slopes.append(slope)
        self.relative_changes.append(change)
        self.sigmas.append(_scatter(self._s_dd, slope, self._s_ii, self.count))
        self.trusted.append(change is not None and change < self.criterion)
        correction = self._correction_for(number + 1)
        self.corrections.append(correction)
        self._offset += correction
        in_use, source = self._slope_in_use()
        return Observation(
            part=number,
            measured_deviation=value,
            deviation=deviation,
            slope=slope,
            relative_change=change,
            sigma=self.sigmas[-1],
            trusted=self.trusted[-1],
            slope_in_use=in_use,
            source=source,
            correction=correction,
            offset=self._offset,
        )

    def end_of_life(self, window: int = 10, confidence: float = 0.99) -> EndOfLifeSigns | None:
        """Compare the last ``window`` parts with the parts before them.

        Parameters
        ----------
        window
            Number of recent parts, >= 4.
        confidence
            One-sided confidence of both tests, in (0.5, 1).

        Returns
        -------
        EndOfLifeSigns or None
            None until at least ``2 * window`` parts are measured.

        Raises
        ------
        InputError
            If ``window`` or ``confidence`` is out of range.
        """
        from scipy import stats  # only this method needs scipy

        if not (isinstance(window, int) and window >= 4):
            raise InputError(f"end-of-life window must be an integer >= 4; got {window!r}")
        if not 0.5 < confidence < 1.0:
            raise InputError(f"end-of-life confidence must be in (0.5, 1); got {confidence!r}")
        if self.count < 2 * window:
            return None
        x = np.asarray(self.parts, dtype=float)
        d = np.asarray(self.measured) - np.asarray(self._offsets)
        ref_x, ref_d, win_x, win_d = x[:-window], d[:-window], x[-window:], d[-window:]
        ref_ii = float(ref_x @ ref_x)
        ref_slope = float(ref_x @ ref_d) / ref_ii
        ref_dof = ref_x.size - 1
        ref_sigma = math.sqrt(float(np.sum((ref_d - ref_slope * ref_x) ** 2)) / ref_dof)
        dx, dd = win_x - win_x.mean(), win_d - win_d.mean()
        sxx = float(dx @ dx)
        recent = float(dx @ dd) / sxx
        recent_sigma = math.sqrt(float(np.sum((dd - recent * dx) ** 2)) / (window - 2))
        direction = 1.0 if ref_slope >= 0 else -1.0
        if ref_sigma > 0:
            t = direction * (recent - ref_slope) / (ref_sigma * math.sqrt(1 / sxx + 1 / ref_ii))
            ratio = (recent_sigma / ref_sigma) ** 2
        else:
            t = math.inf if direction * (recent - ref_slope) > 0 else 0.0
            ratio = math.inf if recent_sigma > 0 else 1.0
        return EndOfLifeSigns(
            reference_slope=ref_slope,
            recent_slope=recent,
            slope_t=t,
            reference_sigma=ref_sigma,
            recent_sigma=recent_sigma,
            accelerating=bool(t > stats.t.ppf(confidence, ref_dof)),
            scatter_growing=bool(ratio > stats.f.ppf(confidence, window - 2, ref_dof)),
        )

    def _correction_for(self, part: int) -> float:
        """Offset change putting ``part`` on target under the slope in use, rounded, m."""
        slope, _ = self._slope_in_use()
        if slope is None:
            return 0.0
        return round_to_resolution(-slope * part - self.offset, self.resolution)

    def _accumulate(self, part: int, deviation: float) -> None:
        self._s_id += part * deviation
        self._s_ii += float(part) * part
        self._s_dd += deviation * deviation

    # -- serialisation ----------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        """The twin's state as a JSON-ready dict (SI values); :meth:`from_dict` inverts it."""
        return {
            "tool_id": self.tool_id,
            "parameters": None if self.parameters is None else self.parameters.to_dict(),
            "resolution": self.resolution,
            "criterion": self.criterion,
            "heritage": None if self.heritage is None else self.heritage.to_dict(),
            "initial_correction": self.initial_correction,
            "parts": list(self.parts),
            "measured": list(self.measured),
            "slopes": list(self.slopes),
            "relative_changes": list(self.relative_changes),
            "sigmas": list(self.sigmas),
            "trusted": list(self.trusted),
            "corrections": list(self.corrections),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ToolTwin:
        """Rebuild a twin from :meth:`to_dict`.

        Raises
        ------
        ConfigError, DataError
            On a missing key, a bad setting or inconsistent history.
        """
        values = _pick(data, cls.__name__, _TWIN_KEYS)
        parameters, heritage = values["parameters"], values["heritage"]
        values["parameters"] = (
            None if parameters is None else ManufacturingParameters.from_dict(parameters)
        )
        values["heritage"] = None if heritage is None else Heritage.from_dict(heritage)
        for key in _TWIN_KEYS[6:]:
            values[key] = list(values[key])
        return cls(**values)


_TWIN_KEYS = (
    "tool_id",
    "parameters",
    "resolution",
    "criterion",
    "heritage",
    "initial_correction",
    "parts",
    "measured",
    "slopes",
    "relative_changes",
    "sigmas",
    "trusted",
    "corrections",
)


@dataclass
class LatheTwin:
    """The digital twin of a lathe: its active tool twins and the retired ones (Bolyn 2023).

    Attributes
    ----------
    resolution
        Smallest tool-offset step of the lathe, m (0: any correction).
    criterion
        Stability criterion given to each new tool twin.
    max_parameter_distance
        Largest :meth:`ManufacturingParameters.distance` for a retired twin to be inherited.
    active
        Tool twins in use, by tool id.
    retired
        Retired tool twins, oldest first.
    """

    resolution: float = 0.0
    criterion: float = STABILITY_CRITERION
    max_parameter_distance: float = MAX_PARAMETER_DISTANCE
    active: dict[str, ToolTwin] = field(default_factory=dict)
    retired: list[ToolTwin] = field(default_factory=list)

    def __post_init__(self) -> None:
        _check_resolution(self.resolution, "lathe resolution")
        if not (self.max_parameter_distance >= 0 and not math.isnan(self.max_parameter_distance)):
            raise ConfigError(
                f"max_parameter_distance must be >= 0; got {self.max_parameter_distance!r}"
            )

    def select_heritage(self, parameters: ManufacturingParameters) -> Heritage | None:
        """The retired twin closest in conditions that ever trusted its slope.

        Parameters
        ----------
        parameters
            Conditions of the new tool.

        Returns
        -------
        Heritage or None
            From the retired twin of smallest distance (the most recent among equals), if
            within ``max_parameter_distance``.
        """
        best: Heritage | None = None
        for twin in self.retired:
            index = twin._last_trusted_index()
            if twin.parameters is None or index is None:
                continue
            distance = parameters.distance(twin.parameters)
            if distance > self.max_parameter_distance:
                continue
            if best is None or distance <= best.distance:
                best = Heritage(
                    twin.tool_id, twin.slopes[index], twin.sigmas[index], twin.count, distance
                )
        return best

    def mount(
        self,
        tool_id: str,
        parameters: ManufacturingParameters | None = None,
        *,
        inherit: bool = True,
    ) -> ToolTwin:
        """Create the twin of a new tool, with heritage, and apply its first correction.

        Parameters
        ----------
        tool_id
            Name of the physical tool; not already active.
        parameters
            Its manufacturing conditions (without them it inherits nothing).
        inherit
            False starts from scratch even when a similar retired twin exists.

        Returns
        -------
        ToolTwin
            The new twin; its ``offset`` is the correction to apply before the first part.

        Raises
        ------
        InputError
            If ``tool_id`` is already active.
        """
        if tool_id in self.active:
            raise InputError(f"tool {tool_id!r} is already mounted; retire it first")
        heritage = self.select_heritage(parameters) if inherit and parameters is not None else None
        twin = ToolTwin(
            tool_id,
            parameters,
            resolution=self.resolution,
            criterion=self.criterion,
            heritage=heritage,
        )
        twin.start()
        self.active[tool_id] = twin
        return twin

    def measure(
        self, tool_id: str, measured_deviation: float, part: SupportsIndex | None = None
    ) -> Observation:
        """Feed a measured part to the tool's twin (see :meth:`ToolTwin.observe`).

        Raises
        ------
        DataError
            If ``tool_id`` is not an active tool, or the measurement is bad.
        """
        return self._active(tool_id).observe(measured_deviation, part)

    def retire(self, tool_id: str) -> ToolTwin:
        """Retire an active tool; its twin joins the history that heritage draws on.

        Raises
        ------
        DataError
            If ``tool_id`` is not an active tool.
        """
        twin = self._active(tool_id)
        del self.active[tool_id]
        self.retired.append(twin)
        return twin

    def _active(self, tool_id: str) -> ToolTwin:
        try:
            return self.active[tool_id]
        except KeyError:
            known = ", ".join(sorted(self.active)) or "none"
            raise DataError(f"tool {tool_id!r} is not mounted (active: {known})") from None

    def to_dict(self) -> dict[str, Any]:
        """The lathe's state as a JSON-ready dict; :meth:`from_dict` inverts it."""
        return {
            "resolution": self.resolution,
            "criterion": self.criterion,
            "max_parameter_distance": self.max_parameter_distance,
            "active": [twin.to_dict() for twin in self.active.values()],
            "retired": [twin.to_dict() for twin in self.retired],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> LatheTwin:
        """Rebuild a lathe twin from :meth:`to_dict`."""
        values = _pick(
            data,
            cls.__name__,
            ("resolution", "criterion", "max_parameter_distance", "active", "retired"),
        )
        active = [ToolTwin.from_dict(item) for item in values.pop("active")]
        retired = [ToolTwin.from_dict(item) for item in values.pop("retired")]
        return cls(**values, active={t.tool_id: t for t in active}, retired=retired)


def _check_resolution(value: float, name: str) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
        raise InputError(f"{name} must be a length >= 0 in metres; got {value!r}")


def _finite(value: object, what: str) -> float:
    """``value`` as a finite float; DataError naming ``what`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise DataError(f"{what} must be a finite number; got {value!r}")
    number = float(value)
    if not math.isfinite(number):
        raise DataError(f"{what} must be a finite number; got {value!r}")
    return number


def _pick(data: Mapping[str, Any], what: str, keys: Sequence[str]) -> dict[str, Any]:
    """The values of exactly ``keys`` from ``data``; ConfigError on a missing or extra key."""
    missing = [key for key in keys if key not in data]
    extra = [key for key in data if key not in keys]
    if missing or extra:
        raise ConfigError(
            f"{what} record: missing keys {missing}, unknown keys {extra}; expected {list(keys)}"
        )
    return {key: data[key] for key in keys}
