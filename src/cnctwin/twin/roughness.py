"""Step 9e of the cycle: the surface roughness the cut is leaving, per sample and per section.

Two predictions, from the live state of every new sample in contact:

- **the Royandi 2026 chain** (vibration -> roughness): the power law
  ``Ra = b0 ap^b1 S^b2 fz^b3 V^b4`` (Royandi 2026, Eq. 23; by default the paper's Eq. 24,
  :data:`cnctwin.quality.ROYANDI_2026_EQ24`, or a model file of ``cnctwin roughness fit
  --json``) of the engagement's depth of cut ``ap_mm``, the measured ``spindle_rpm``, the
  feed per tooth ``feed_per_tooth_mm`` of the actual path speed and spindle speed (so
  overrides included), and a **measured** vibration RMS: the signal named by ``vibration``
  (a sensor signal of ``[mqtt]``, a window feature of ``[twin.windows]`` such as
  ``accel_g_rms``, ... in the model's unit, g for Eq. 24). The twin does not predict the
  vibration itself (no modal model of the tool in the cycle): without ``vibration`` there is
  no Ra of this kind;
- **the kinematic (ideal) roughness** of the feed marks of the tool in the spindle
  (:func:`cnctwin.quality.end_mill_feed_marks`) from the same feed per tooth and the tool's
  geometry (``[[tools]]`` kind, diameter, corner radius; ``dish_angle_deg`` for a flat end
  mill's floor). Runout is not modelled.

A **program section** is a run of samples at one NC line (``program_line``) with one tool,
the unit the adaptive feed's teach-in learns by (:mod:`cnctwin.twin.adaptive_feed`); a line
run again later (a loop) is a new section. Each section's
cutting samples are summarised (:class:`SectionRoughness`, with the largest predicted form
error of the form-error stage where it runs): an event ``roughness_section``
when the section ends, and every section in the run's summary (``stage_results.roughness``,
``cnctwin runs show``).

Names it adds to :attr:`CycleState.predicted` (um; NaN while not cutting, or when an input is
missing): ``roughness_ra_um`` (the power law), ``roughness_kin_ra_um`` and
``roughness_kin_rz_um`` (floor feed marks), ``roughness_kin_wall_rz_um`` (wall feed marks),
and for the section so far ``roughness_section_ra_mean_um``, ``roughness_section_ra_max_um``
and ``roughness_section_kin_rz_max_um``. Rules read them like any prediction (a ``notify``
or ``stop`` when a section's Ra passes a limit); their actions go through the safety filter
and the lost-machine policy like every rule's.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationInfo, field_validator

from cnctwin.config import Section, ToolConfig, resolve_file
from cnctwin.errors import CnctwinError, ConfigError, InputError
from cnctwin.quality import (
    ROYANDI_2026_EQ24,
    PowerLawModel,
    end_mill_feed_marks,
    read_power_law_model,
)
from cnctwin.twin.state import CycleState, TwinEvent

__all__ = [
    "ROUGHNESS_PREDICTIONS",
    "RoughnessConfig",
    "RoughnessStage",
    "SectionRoughness",
    "feature_names",
]

#: The names the roughness stage adds (um).
ROUGHNESS_PREDICTIONS = (
    "roughness_ra_um",
    "roughness_kin_ra_um",
    "roughness_kin_rz_um",
    "roughness_kin_wall_rz_um",
    "roughness_section_ra_mean_um",
    "roughness_section_ra_max_um",
    "roughness_section_kin_rz_max_um",
)

#: The twin's name for each feature of Royandi's law (the default model's feature names).
_DEFAULT_FEATURES = {"ap_mm": "ap_mm", "spindle_rpm": "spindle_rpm", "fz_mm": "feed_per_tooth_mm"}

_KINDS = ("flat", "bull", "ball")


class RoughnessConfig(Section):
    """Roughness prediction (``[twin.roughness]``; :mod:`cnctwin.twin.roughness`).

    Attributes
    ----------
    enabled
        Run the stage (off by default).
    model
        Power-law model file (JSON of ``cnctwin roughness fit --json``), relative to the
        configuration file; ``None``: Royandi 2026 Eq. 24 (AL6061, ap_mm, spindle_rpm, fz_mm,
        vibration_g).
    vibration
        Name of the measured vibration RMS the model's ``vibration_g`` feature reads (a
        signal, ``filtered_*`` signal, window feature or prediction of the twin), in the
        model's unit; ``None``: no power-law Ra (the kinematic roughness only).
    features
        Twin name per model feature, for a model with other features (model feature ->
        twin name); defaults: ``ap_mm`` -> ``ap_mm``, ``spindle_rpm`` -> ``spindle_rpm``,
        ``fz_mm`` -> ``feed_per_tooth_mm``, ``vibration_g`` -> ``vibration``.
    dish_angle_deg
        End-edge dish angle of the flat end mills, deg, 0 to 10 (0: an ideal flat floor).
    """

    enabled: bool = False
    model: Path | None = None
    vibration: str | None = Field(default=None, pattern=r"^[A-Za-z_][A-Za-z0-9_]{0,79}$")
    features: dict[str, str] = Field(default_factory=dict, max_length=16)
    dish_angle_deg: float = Field(default=0.0, ge=0.0, le=10.0)

    @field_validator("model")
    @classmethod
    def _relative_to_file(cls, value: Path | None, info: ValidationInfo) -> Path | None:
        return resolve_file(value, info)


def feature_names(config: RoughnessConfig, model: PowerLawModel) -> dict[str, str]:
    """The twin name each feature of ``model`` reads (model feature -> twin name).

    Raises
    ------
    cnctwin.errors.ConfigError
        For a feature no name is given for (``vibration_g`` without ``vibration``).
    """
    names = dict(_DEFAULT_FEATURES)
    if config.vibration is not None:
        names["vibration_g"] = config.vibration
    names.update(config.features)
    missing = [f for f in model.features if f not in names]
    if missing:
        hint = (
            "set vibration to the measured vibration RMS signal"
            if missing == ["vibration_g"]
            else "map it in [twin.roughness.features]"
        )
        raise ConfigError(
            f"twin.roughness: the model's feature {missing[0]!r} reads no twin name; {hint}"
        )
    return {f: names[f] for f in model.features}


@dataclass
class SectionRoughness:
    """The roughness of one program section's cutting samples (um; NaN where none).

    Attributes
    ----------
    line
        The section's NC line.
    tool
        The tool in the spindle.
    samples
        Samples in contact with a feed.
    ra_samples
        Of them, samples with a power-law Ra (every feature known).
    ra_mean_um, ra_max_um
        Mean and largest power-law Ra, um.
    kin_samples
        Of them, samples with a kinematic roughness (a flat, bull or ball end mill).
    kin_ra_mean_um, kin_rz_max_um
        Mean kinematic Ra and largest kinematic Rz of the floor, um.
    kin_wall_rz_max_um
        Largest kinematic Rz of the wall, um.
    fz_mean_mm
        Mean feed per tooth, mm.
    form_error_max_um
        Largest predicted form error of the wall (``form_error_um`` of the form-error
        stage, :mod:`cnctwin.quality.form_error`), um; NaN with that stage off.
    """

    line: int
    tool: int
    samples: int = 0
    ra_samples: int = 0
    kin_samples: int = 0
    ra_mean_um: float = math.nan
    ra_max_um: float = math.nan
    kin_ra_mean_um: float = math.nan
    kin_rz_max_um: float = math.nan
    kin_wall_rz_max_um: float = math.nan
    fz_mean_mm: float = math.nan
    form_error_max_um: float = math.nan

    def add(
        self,
        fz_mm: float,
        ra_um: float,
        kin_ra_um: float,
        kin_rz_um: float,
        wall_um: float,
        form_error_um: float = math.nan,
    ) -> None:
        """Take one cutting sample's values (NaN where a value is unknown)."""
        self.samples += 1
        self.fz_mean_mm = _mean(self.fz_mean_mm, fz_mm, self.samples)
        if math.isfinite(form_error_um):
            self.form_error_max_um = _max(self.form_error_max_um, form_error_um)
        if math.isfinite(kin_ra_um):
            self.kin_samples += 1
            self.kin_ra_mean_um = _mean(self.kin_ra_mean_um, kin_ra_um, self.kin_samples)
            self.kin_rz_max_um = _max(self.kin_rz_max_um, kin_rz_um)
            self.kin_wall_rz_max_um = _max(self.kin_wall_rz_max_um, wall_um)
        if math.isfinite(ra_um):
            self.ra_samples += 1
            self.ra_mean_um = _mean(self.ra_mean_um, ra_um, self.ra_samples)
            self.ra_max_um = _max(self.ra_max_um, ra_um)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready values (NaN as ``None``)."""
        return {
            k: (None if isinstance(v, float) and math.isnan(v) else v)
            for k, v in asdict(self).items()
        }

    def message(self) -> str:
        """One line for the event log."""
        ra = (
            f"Ra {self.ra_mean_um:.3g} um mean, {self.ra_max_um:.3g} max "
            f"({self.ra_samples} samples)"
            if self.ra_samples
            else "no power-law Ra (no vibration)"
        )
        return (
            f"roughness of line {self.line} (T{self.tool}): {ra}; feed marks Rz "
            f"{self.kin_rz_max_um:.3g} um floor, {self.kin_wall_rz_max_um:.3g} um wall at fz "
            f"{self.fz_mean_mm:.4g} mm ({self.samples} samples)"
            + (
                f"; form error {self.form_error_max_um:.3g} um max"
                if math.isfinite(self.form_error_max_um)
                else ""
            )
        )


def _mean(mean: float, value: float, n: int) -> float:
    """The running mean after the ``n``-th value."""
    return value if n == 1 else mean + (value - mean) / n


def _max(current: float, value: float) -> float:
    return value if not current >= value else current


@dataclass(frozen=True, slots=True)
class _Edge:
    """The geometry of one tool's feed marks (SI)."""

    kind: str
    diameter_m: float
    corner_radius_m: float


class RoughnessStage:
    """The roughness predictions in the cycle (see the module).

    Parameters
    ----------
    config
        The ``[twin.roughness]`` table.
    tools
        The ``[[tools]]``: kinds other than flat, bull and ball get no kinematic roughness.
    valid_names
        Every name the twin provides (:func:`cnctwin.twin.pipeline.signal_names` and the
        models' outputs): each feature must read one.

    Raises
    ------
    cnctwin.errors.ConfigError
        For a model file that is not a power-law model, a feature without a twin name or
        reading a name the twin does not provide.
    """

    per_sample = True
    name = "roughness"

    def __init__(
        self, config: RoughnessConfig, tools: Sequence[ToolConfig], valid_names: Iterable[str]
    ) -> None:
        if config.model is None:
            self.model, self.model_source = ROYANDI_2026_EQ24, "Royandi 2026 Eq. 24"
        else:
            try:
                self.model = read_power_law_model(config.model)
            except (CnctwinError, OSError) as err:
                raise ConfigError(f"twin.roughness.model: {err}") from None
            self.model_source = str(config.model)
        unmeasured = config.model is None and config.vibration is None and not config.features
        features = {} if unmeasured else feature_names(config, self.model)
        valid = set(valid_names)
        for feature, name in features.items():
            if name not in valid:
                raise ConfigError(
                    f"twin.roughness: the model's feature {feature!r} reads {name!r}, which "
                    "this twin does not provide (a signal, filtered_* signal, window feature "
                    "or prediction; `cnctwin run` lists them)"
                )
        #: The twin name each model feature reads; empty: no power-law Ra.
        self.features: Mapping[str, str] = features
        self.dish_angle_rad = math.radians(config.dish_angle_deg)
        self.edges = {
            t.number: _Edge(t.kind, t.diameter_mm * 1e-3, (t.corner_radius_mm or 0.0) * 1e-3)
            for t in tools
            if t.kind in _KINDS
        }
        self.sections: list[SectionRoughness] = []
        self._open: SectionRoughness | None = None

    def ra_um(self, state: CycleState) -> float:
        """The power-law Ra of this sample, um (NaN when a feature is missing or not > 0)."""
        if not self.features:
            return math.nan
        values = {}
        for feature, name in self.features.items():
            value = abs(state.value(name))  # a speed's sign is the direction
            if not (value > 0.0 and math.isfinite(value)):
                return math.nan
            values[feature] = value
        return float(self.model.predict(values))

    def feed_marks_um(self, tool: int, fz_mm: float) -> tuple[float, float, float]:
        """Kinematic floor Ra, floor Rz and wall Rz of ``tool`` at ``fz_mm``, um (NaN for a
        tool without feed marks, or a feed the formulas do not hold for)."""
        edge = self.edges.get(tool)
        if edge is None or not fz_mm > 0.0:
            return math.nan, math.nan, math.nan
        try:
            marks = end_mill_feed_marks(
                edge.kind,
                fz_mm * 1e-3,
                edge.diameter_m,
                corner_radius_m=edge.corner_radius_m,
                dish_angle_rad=self.dish_angle_rad,
            )
        except InputError:  # a feed of at least the arc's diameter: no arc-made profile
            return math.nan, math.nan, math.nan
        return float(marks.floor_ra) * 1e6, float(marks.floor_rt) * 1e6, float(marks.wall_rt) * 1e6

    def process(self, state: CycleState) -> CycleState:
        """Add the ``roughness_*`` predictions; close a section when the line changes."""
        if not state.connected:
            return state
        p = state.predicted
        section = self._open
        if section is None or section.line != state.line or section.tool != state.tool:
            self._close(state)
            section = self._open = SectionRoughness(state.line, state.tool)
        fz = p.get("feed_per_tooth_mm", 0.0)
        ra = kin_ra = kin_rz = wall = math.nan
        if p.get("contact", 0.0) and fz > 0.0:
            ra = self.ra_um(state)
            kin_ra, kin_rz, wall = self.feed_marks_um(state.tool, fz)
            form = p.get("form_error_um", math.nan)
            section.add(fz, ra, kin_ra, kin_rz, wall, form)
        p.update(
            roughness_ra_um=ra,
            roughness_kin_ra_um=kin_ra,
            roughness_kin_rz_um=kin_rz,
            roughness_kin_wall_rz_um=wall,
            roughness_section_ra_mean_um=section.ra_mean_um,
            roughness_section_ra_max_um=section.ra_max_um,
            roughness_section_kin_rz_max_um=section.kin_rz_max_um,
        )
        return state

    def _close(self, state: CycleState) -> None:
        """The open section ended: keep it, and say so in an event, when it cut."""
        section, self._open = self._open, None
        if section is None or section.samples == 0:
            return
        self.sections.append(section)
        state.events.append(
            TwinEvent("roughness_section", section.message(), state.received_s, section.to_dict())
        )

    def run_results(self) -> dict[str, Any]:
        """The run's sections that cut, the open one included (for the run's summary)."""
        sections = list(self.sections)
        if self._open is not None and self._open.samples:
            sections.append(self._open)
        return {
            "model": self.model_source if self.features else None,
            "features": dict(self.features),
            "sections": [s.to_dict() for s in sections],
        }
