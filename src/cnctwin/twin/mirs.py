"""Step 9e of the cycle: live elastic MIRS prediction and control (Ward 2021, Sec. 3.3, Fig. 3).

Every new sample in contact, the stage predicts the elastic machining-induced residual stress
(:class:`cnctwin.mechanics.ElasticMirsModel`) of the live cut: the edge load per unit width of
Ward's Eq. 1 (``Q = Ktc h + Kte``, ``P = |Krc h + Kre|``) at the largest chip thickness ``h`` of
the twin's engagement (``h_max_mm`` of the cut stage, from the live feed and spindle speed), the
material's coefficients of the force stage, and the elastic constants of ``[twin.mirs]``
``elastic``. The largest ``|sigma_xx|`` over depth is Ward's "maximum elastic MIRS".

**Control** (``control = true``), Ward's Fig. 3 loop with the update rule made explicit: when
the MIRS is above ``max_mpa``, or below ``min_mpa`` while the overrides are under 100 %, the
stage asks for the chip-thickness ratio ``r`` at which the MIRS meets ``max_mpa`` (at most the
ratio that brings the overrides back to 100 %). The MIRS depends on the chip thickness alone
(the loads of Ward's Eq. 1 are affine in ``h``) and grows with it, so the largest chip thickness
``h*`` whose MIRS is at most ``max_mpa`` is found once, by bisection of the model when the stage
is built, and ``r = h* / h`` costs no model evaluation in the cycle. It asks for::

    spindle ratio  s = 1 - spindle_share (1 - r)
    feed ratio     r s                      (so that fz = feed / (n z) changes by r)

``spindle_share = 0`` changes the feed only; ``spindle_share = 1`` lowers the speed by the same
ratio as the chip thickness (Ward's case: 30000 -> 18750 rpm, fz 0.16 -> 0.1024 mm, ratios
0.625 and 0.64). The commands go to the actions stage as decisions of the rule ``mirs``, so they
pass the safety filter (enable switch, ``[control.feed_override]`` and
``[control.spindle_override]`` bounds, rate limits) and the lost-machine policy of
docs/control.md: nothing is commanded while the machine is lost, and after a gap the stage
forgets its last command.

Names it adds to :attr:`CycleState.predicted`: ``mirs_max_mpa`` (largest ``|sigma_xx|``, MPa;
0 without contact), ``mirs_surface_xx_mpa`` and ``mirs_surface_yy_mpa`` (residual stress at the
surface, MPa), ``mirs_target_feed_pct`` and ``mirs_target_spindle_pct`` (the overrides asked
for, %; NaN when none).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cnctwin.config import Section, resolve_file
from cnctwin.control import Decision
from cnctwin.errors import ConfigError
from cnctwin.mechanics import (
    CuttingCoefficients,
    ElasticMirsModel,
    edge_surface_load,
    load_materials,
)
from cnctwin.thread import RunState
from cnctwin.twin.state import CycleState

__all__ = ["MIRS_PREDICTIONS", "MirsConfig", "MirsStage"]

#: The names the MIRS stage adds (units in the names).
MIRS_PREDICTIONS = (
    "mirs_max_mpa",
    "mirs_surface_xx_mpa",
    "mirs_surface_yy_mpa",
    "mirs_target_feed_pct",
    "mirs_target_spindle_pct",
)

#: The rule name of the stage's decisions (historian, safety filter).
RULE = "mirs"

_MPA = 1e6
_MM = 1e-3
#: The search for the chip-thickness ratio stops when its bracket is this narrow, relative
#: The bisection for ``h*`` stops when its bracket is this narrow, relative (far below the 1 %
#: steps of a control's override).
_THICKNESS_TOLERANCE = 1e-6
#: The chip thicknesses, mm, between which ``h*`` is sought: below the first the stage asks for
#: the smallest ratio, above the last (a MIRS band no cut reaches) for no change.
_THICKNESS_RANGE_MM = (1e-5, 10.0)
#: Smallest chip-thickness ratio the stage asks for in one command.
_MIN_RATIO = 0.05


class MirsConfig(Section):
    """Live elastic MIRS prediction and control (``[twin.mirs]``; Ward 2021, Sec. 3.3).

    Attributes
    ----------
    enabled
        Run the stage (off by default).
    elastic
        Elastic entry of the materials library (the workpiece's E, nu, alpha).
    materials_file
        A user's materials file (TOML, docs/materials.md) whose entries ``elastic`` may name,
        relative to the configuration file.
    contact_length_mm
        Contact length of the edge on the new surface, mm.
    depth_um
        Deepest point of the profile, um.
    points
        Depths in the profile.
    control
        Command the overrides to keep the MIRS in the band (only when ``[control]`` is enabled;
        otherwise the decisions are recorded as blocked).
    max_mpa
        Upper edge of the band, MPa: above it the stage lowers the chip load.
    min_mpa
        Lower edge of the band, MPa: below it, with an override under 100 %, the stage raises
        the chip load back toward ``max_mpa`` (never above 100 %); 0 never raises.
    spindle_share
        Share of the chip-load change taken by the spindle speed, 0 (feed only) to 1.
    interval_s
        Least time between two commands, s.
    deadband_pct
        Least change of an override worth a command, %.
    """

    enabled: bool = False
    elastic: str = "AA7050-T7451"
    materials_file: Path | None = None
    contact_length_mm: float = Field(default=0.1, ge=0.001, le=100.0)
    depth_um: float = Field(default=200.0, ge=1.0, le=10_000.0)
    points: int = Field(default=41, ge=2, le=2000)
    control: bool = False
    max_mpa: float | None = Field(default=None, gt=0.0, le=1e5)
    min_mpa: float = Field(default=0.0, ge=0.0, le=1e5)
    spindle_share: float = Field(default=0.0, ge=0.0, le=1.0)
    interval_s: float = Field(default=0.5, ge=0.0, le=600.0)
    deadband_pct: float = Field(default=1.0, ge=0.0, le=50.0)

    @field_validator("materials_file")
    @classmethod
    def _relative_to_file(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        return resolve_file(value, info)

    @model_validator(mode="after")
    def _band(self) -> MirsConfig:
        if self.control and self.max_mpa is None:
            raise PydanticCustomError("mirs_band", "control = true needs max_mpa (MPa)")
        if self.max_mpa is not None and self.min_mpa >= self.max_mpa:
            raise PydanticCustomError(
                "mirs_band",
                "min_mpa = {low} must be below max_mpa = {high}",
                {"low": self.min_mpa, "high": self.max_mpa},
            )
        return self


class MirsStage:
    """The MIRS prediction and controller in the cycle (see the module).

    Parameters
    ----------
    config
        The ``[twin.mirs]`` table.
    coefficients
        The workpiece's cutting coefficients (the force stage's), Pa and N/m.
    feed_bounds_pct, spindle_bounds_pct
        The safety filter's override bounds (``[control.feed_override]``,
        ``[control.spindle_override]``), %.

    Raises
    ------
    cnctwin.errors.ConfigError
        For an unknown elastic material or an unreadable materials file.
    """

    per_sample = True
    name = "mirs"

    def __init__(
        self,
        config: MirsConfig,
        coefficients: CuttingCoefficients,
        feed_bounds_pct: tuple[float, float],
        spindle_bounds_pct: tuple[float, float],
    ) -> None:
        try:
            elastic = load_materials(config.materials_file).elastic_material(config.elastic)
        except ConfigError as err:
            raise ConfigError(f"twin.mirs.elastic: {err}") from None
        self.config = config
        self.coefficients = coefficients
        self.feed_bounds = feed_bounds_pct
        self.spindle_bounds = spindle_bounds_pct
        self.model = ElasticMirsModel(
            elastic,
            config.contact_length_mm * _MM,
            np.linspace(0.0, config.depth_um * 1e-6, config.points),
        )
        self._last_s = -math.inf
        # the model's first call loads its compiled kernel (0.2-0.4 s): here, not in a cycle
        self.mirs_mpa(_THICKNESS_RANGE_MM[0])
        #: ``h*``, mm: the largest chip thickness whose MIRS is at most ``max_mpa``.
        self.limit_thickness_mm = (
            self._limit_thickness_mm(config.max_mpa)
            if config.control and config.max_mpa is not None
            else math.nan
        )

    def forget(self) -> None:
        """After a gap: the next command is not held back by one from before it."""
        self._last_s = -math.inf

    def mirs_mpa(self, chip_thickness_mm: float) -> tuple[float, float, float]:
        """Largest |sigma_xx|, and sigma_xx, sigma_yy at the surface, MPa, at a chip thickness."""
        load = edge_surface_load(
            self.coefficients,
            chip_thickness_mm * _MM,
            self.model.contact_length_m,
        )
        profile = self.model.profile(load.normal_n_m, load.tangential_n_m)
        return (
            profile.max_abs_xx_pa / _MPA,
            float(profile.sigma_xx_pa[0]) / _MPA,
            float(profile.sigma_yy_pa[0]) / _MPA,
        )

    def process(self, state: CycleState) -> CycleState:
        """Add the ``mirs_*`` predictions; append override decisions when controlling."""
        if not state.connected:
            return state
        p = state.predicted
        p.update(mirs_target_feed_pct=math.nan, mirs_target_spindle_pct=math.nan)
        e = state.engagement
        h_mm = e.h_max_mm if e is not None and e.contact else 0.0
        if not (math.isfinite(h_mm) and h_mm > 0.0):
            p.update(mirs_max_mpa=0.0, mirs_surface_xx_mpa=0.0, mirs_surface_yy_mpa=0.0)
            return state
        value, surface_xx, surface_yy = self.mirs_mpa(h_mm)
        p.update(mirs_max_mpa=value, mirs_surface_xx_mpa=surface_xx, mirs_surface_yy_mpa=surface_yy)
        c = self.config
        m = state.measured
        feed = m.get("feed_override_pct", math.nan)
        spindle = m.get("spindle_override_pct", math.nan)
        running = m.get("run_state") == RunState.RUNNING and m.get("feed_mm_min", 0.0) > 0.0
        if not (c.control and c.max_mpa is not None and running):
            return state
        if not (math.isfinite(feed) and math.isfinite(spindle) and feed > 0 and spindle > 0):
            return state
        low_overrides = feed < 100.0 or spindle < 100.0
        if value <= c.max_mpa and not (value < c.min_mpa and low_overrides):
            return state
        if state.time_s - self._last_s < c.interval_s:
            return state
        ratio = self._ratio(h_mm, feed, spindle)
        s = 1.0 - c.spindle_share * (1.0 - ratio)
        feed_target = _clip(feed * ratio * s, self.feed_bounds)
        spindle_target = _clip(spindle * s, self.spindle_bounds)
        p.update(mirs_target_feed_pct=feed_target, mirs_target_spindle_pct=spindle_target)
        why = (
            f"mirs: max |sigma_xx| {value:.0f} MPa vs band {c.min_mpa:g}-{c.max_mpa:g} MPa, "
            f"chip thickness x{ratio:.3f}"
        )
        values = {"mirs_max_mpa": value, "feed_override_pct": feed}
        sent = False
        if abs(feed_target - feed) >= c.deadband_pct:
            state.commands.append(
                Decision(
                    state.time_s,
                    RULE,
                    "feed_override",
                    feed_target,
                    f"{why}: feed override {feed:.0f} -> {feed_target:.0f} %",
                    values,
                )
            )
            sent = True
        if c.spindle_share > 0.0 and abs(spindle_target - spindle) >= c.deadband_pct:
            state.commands.append(
                Decision(
                    state.time_s,
                    RULE,
                    "spindle_override",
                    spindle_target,
                    f"{why}: spindle override {spindle:.0f} -> {spindle_target:.0f} %",
                    {**values, "spindle_override_pct": spindle},
                )
            )
            sent = True
        if sent:
            self._last_s = state.time_s
        return state

    def _limit_thickness_mm(self, limit_mpa: float) -> float:
        """``h*``: the largest chip thickness, mm, whose MIRS is at most ``limit_mpa`` (MPa), to
        ``_THICKNESS_TOLERANCE`` (bisection of the logarithm over ``_THICKNESS_RANGE_MM``);
        0 when even the thinnest chip is above it, ``inf`` when the thickest is not."""
        ok, bad = _THICKNESS_RANGE_MM
        if self.mirs_mpa(bad)[0] <= limit_mpa:
            return math.inf
        if self.mirs_mpa(ok)[0] > limit_mpa:
            return 0.0
        while bad > ok * (1.0 + _THICKNESS_TOLERANCE):
            mid = math.sqrt(ok * bad)
            if self.mirs_mpa(mid)[0] <= limit_mpa:
                ok = mid
            else:
                bad = mid
        return ok

    def _ratio(self, h_mm: float, feed: float, spindle: float) -> float:
        """Chip-thickness ratio to ``h*`` from ``h_mm`` (mm), within ``_MIN_RATIO`` and the one
        that brings both overrides (%) back to 100 %."""
        share = self.config.spindle_share
        # feed ratio r s = 100 / feed with s = 1 - share (1 - r): share r^2 + (1 - share) r
        if share > 0.0:
            root = math.sqrt((1.0 - share) ** 2 + 4.0 * share * 100.0 / feed)
            top = min((root - (1.0 - share)) / (2.0 * share), 1.0 + (100.0 / spindle - 1.0) / share)
        else:
            top = 100.0 / feed
        top = max(top, 1.0)
        return max(_MIN_RATIO, min(top, self.limit_thickness_mm / h_mm))


def _clip(value: float, bounds: tuple[float, float]) -> float:
    return min(max(value, bounds[0]), bounds[1])
