"""Stability configuration files: tool-tip modes, the cut and the lobe diagram (docs/stability.md).

A stability file is TOML with a ``[[modes]]`` array and optional ``[cut]``, ``[lobes]`` and
``[process_damping]`` tables; a modes file holds the ``[[modes]]`` array only. Customary units
in the key names (Hz, N/m, kg, mm, N/mm^2, rpm, degrees); :meth:`StabilityConfig.tool_dynamics`,
:meth:`StabilityConfig.process` and :meth:`StabilityConfig.process_damping_model` convert to
the SI objects of :mod:`cnctwin.dynamics.stability`.
"""

from __future__ import annotations

import math
import os
import tomllib
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

from pydantic import Field, ValidationError, model_validator

from cnctwin.config import MAX_SPINDLE_RPM, Section, describe_validation_error
from cnctwin.dynamics.stability import (
    MillingProcess,
    OrthogonalProcess,
    ProcessDamping,
    ToolDynamics,
    ToolMode,
    _auto_steps,
)
from cnctwin.errors import CnctwinError, ConfigError
from cnctwin.mechanics import CuttingCoefficients
from cnctwin.memory import check_memory

__all__ = [
    "CutSection",
    "LobesSection",
    "ModeEntry",
    "ModesFile",
    "ProcessDampingSection",
    "StabilityConfig",
    "load_modes_file",
    "load_stability_config",
    "load_tool_stability",
]

_DIRECTIONS = {"x": 0.0, "y": 90.0}
#: Most spindle speeds of a lobe diagram (``[lobes] points``, ``--rpm-range``).
MAX_POINTS = 100_000
#: Least radial immersion ae/D (``cut.radial_immersion``, ``--immersion``): below 0.1 % the
#: arc of engagement vanishes numerically.
MIN_IMMERSION = 1e-3
#: A spindle speed of the lobe diagram, rpm (as ``[machine] max_spindle_rpm``).
_Rpm = Annotated[float, Field(gt=0, le=MAX_SPINDLE_RPM)]
_Model = TypeVar("_Model", bound=Section)


class ModeEntry(Section):
    """One tool-tip mode (``[[modes]]``).

    Attributes
    ----------
    direction
        ``"x"`` (feed) or ``"y"`` (normal to the feed); exclusive with ``direction_deg``.
    direction_deg
        Direction in degrees from +x toward +y, for modes not along x or y (-360 to 360).
    fn_hz
        Undamped natural frequency in Hz, 0.1 to 1,000,000.
    damping_ratio
        Viscous damping ratio, 0 <= zeta < 1.
    stiffness_n_m
        Modal stiffness in N/m (1 to 1e12); exclusive with ``mass_kg``.
    mass_kg
        Modal mass in kg (``k = m (2 pi fn)^2``; 1e-6 to 1e6).
    """

    direction: Literal["x", "y"] | None = None
    direction_deg: float | None = Field(default=None, ge=-360, le=360)
    fn_hz: float = Field(ge=0.1, le=1e6)
    damping_ratio: float = Field(ge=0, lt=1)
    stiffness_n_m: float | None = Field(default=None, ge=1, le=1e12)
    mass_kg: float | None = Field(default=None, ge=1e-6, le=1e6)

    @model_validator(mode="after")
    def _one_of_each(self) -> ModeEntry:
        if (self.direction is None) == (self.direction_deg is None):
            raise ValueError("give either direction (x or y) or direction_deg")
        if (self.stiffness_n_m is None) == (self.mass_kg is None):
            raise ValueError("give either stiffness_n_m or mass_kg")
        return self

    def tool_mode(self) -> ToolMode:
        """The SI :class:`~cnctwin.dynamics.stability.ToolMode`."""
        degrees = _DIRECTIONS[self.direction] if self.direction is not None else self.direction_deg
        return ToolMode.from_hz(
            self.fn_hz,
            self.damping_ratio,
            stiffness_n_m=self.stiffness_n_m,
            mass_kg=self.mass_kg,
            direction_rad=math.radians(degrees or 0.0),
        )


class CutSection(Section):
    """The cut (``[cut]``): milling (the default) or orthogonal cutting.

    Attributes
    ----------
    operation
        ``"milling"`` or ``"orthogonal"`` (turning, boring, shaping: one chip per revolution).
    teeth
        Milling: number of teeth, 1 to 100.
    radial_immersion
        Milling: radial depth over diameter ae/D, 0 < ae/D <= 1 (1 is a slot).
    milling
        Milling: ``"down"`` (climb) or ``"up"`` (conventional).
    material
        Milling: an entry of the materials library (``cnctwin.mechanics.materials``);
        exclusive with ``ktc_n_mm2`` and ``krc_n_mm2``.
    ktc_n_mm2, krc_n_mm2
        Milling: tangential (> 0) and radial cutting coefficients in N/mm^2, magnitudes up
        to 100,000 (hardened steels need about 5,000).
    kf_n_mm2
        Orthogonal: cutting force coefficient Kf in N/mm^2 (> 0, <= 100,000).
    chip_direction_deg
        Orthogonal: direction in which the tool's displacement thickens the chip, degrees
        from +x toward +y (-360 to 360).
    force_angle_deg
        Orthogonal: angle beta of the cutting force from the chip direction, degrees
        (-360 to 360).
    """

    operation: Literal["milling", "orthogonal"] = "milling"
    teeth: int | None = Field(default=None, ge=1, le=100)
    radial_immersion: float = Field(default=1.0, ge=MIN_IMMERSION, le=1)
    milling: Literal["down", "up"] = "down"
    material: str | None = None
    ktc_n_mm2: float | None = Field(default=None, gt=0, le=1e5)
    krc_n_mm2: float | None = Field(default=None, ge=-1e5, le=1e5)
    kf_n_mm2: float | None = Field(default=None, gt=0, le=1e5)
    chip_direction_deg: float = Field(default=90.0, ge=-360, le=360)
    force_angle_deg: float = Field(default=0.0, ge=-360, le=360)


class LobesSection(Section):
    """The lobe diagram to compute (``[lobes]``).

    Attributes
    ----------
    method
        ``"zoa"`` (zero-order approximation) or ``"sdm"`` (semi-discretization).
    rpm
        Lowest and highest spindle speed in rpm, each > 0 and <= 200,000.
    points
        Number of spindle speeds, evenly spaced, 2 to 100,000.
    max_depth_mm
        Semi-discretization: highest depth searched in mm (> 0, <= 1000).
    steps
        Semi-discretization: equal steps per period, 2 to 10,000, or ``"auto"`` (nodes at
        the teeth's entry and exit, 30 steps per cycle of the highest mode in the cut, at
        least 20 in any cut). The work of the whole diagram must fit the work
        limit (:mod:`cnctwin.memory`).
    """

    method: Literal["zoa", "sdm"] = "zoa"
    rpm: tuple[_Rpm, _Rpm] = (2000.0, 20000.0)
    points: int = Field(default=200, ge=2, le=MAX_POINTS)
    max_depth_mm: float = Field(default=10.0, gt=0, le=1000)
    steps: Annotated[int, Field(le=10_000)] | Literal["auto"] = "auto"

    @model_validator(mode="after")
    def _ranges(self) -> LobesSection:
        low, high = self.rpm
        if not 0.0 < low < high:
            raise ValueError(f"rpm must be [low, high] with 0 < low < high; got {list(self.rpm)}")
        if isinstance(self.steps, int) and self.steps < 2:
            raise ValueError(f"steps must be >= 2 or 'auto'; got {self.steps}")
        return self


class ProcessDampingSection(Section):
    """Process damping, Royandi 2026 Eq. 3 (``[process_damping]``).

    Attributes
    ----------
    cpd_n_m2
        Process damping coefficient C_pd in N/m^2, 0 to 1e15.
    chip_thickness_mm
        Chip thickness h in mm: the feed per tooth in milling, per revolution in turning
        (> 0, <= 100).
    diameter_mm
        Cutting diameter in mm (the tool's in milling, the workpiece's in turning), for the
        cutting speed ``V_c`` (0.01 to 10,000).
    """

    cpd_n_m2: float = Field(ge=0, le=1e15)
    chip_thickness_mm: float = Field(gt=0, le=100)
    diameter_mm: float = Field(ge=0.01, le=1e4)


class ModesFile(Section):
    """A modes file: the ``[[modes]]`` array alone."""

    modes: list[ModeEntry] = Field(min_length=1)


class StabilityConfig(Section):
    """A whole stability file.

    Attributes
    ----------
    modes
        Tool-tip modes, at least one.
    cut
        The cut.
    lobes
        The lobe diagram.
    process_damping
        Optional process damping.
    """

    modes: list[ModeEntry] = Field(min_length=1)
    cut: CutSection = Field(default_factory=CutSection)
    lobes: LobesSection = Field(default_factory=LobesSection)
    process_damping: ProcessDampingSection | None = None

    def tool_dynamics(self) -> ToolDynamics:
        """The modes as :class:`~cnctwin.dynamics.stability.ToolDynamics` (SI)."""
        return ToolDynamics(tuple(mode.tool_mode() for mode in self.modes))

    def process(self) -> MillingProcess | OrthogonalProcess:
        """The cut as a process of :mod:`cnctwin.dynamics.stability` (SI).

        Raises
        ------
        ConfigError
            If the keys the operation needs are missing or contradict each other.
        """
        cut = self.cut
        if cut.operation == "orthogonal":
            if cut.kf_n_mm2 is None:
                raise ConfigError("cut.kf_n_mm2: orthogonal cutting needs Kf in N/mm^2")
            return OrthogonalProcess(
                cut.kf_n_mm2 * 1e6,
                math.radians(cut.chip_direction_deg),
                math.radians(cut.force_angle_deg),
            )
        if cut.teeth is None:
            raise ConfigError("cut.teeth: milling needs the number of teeth")
        return MillingProcess.from_immersion(
            cut.teeth,
            self.coefficients(),
            cut.radial_immersion,
            down_milling=cut.milling == "down",
        )

    def coefficients(self) -> CuttingCoefficients:
        """Milling coefficients from ``material`` or ``ktc_n_mm2`` and ``krc_n_mm2``."""
        from cnctwin.mechanics import milling_material

        cut = self.cut
        given = cut.ktc_n_mm2 is not None or cut.krc_n_mm2 is not None
        if cut.material is not None and not given:
            return milling_material(cut.material).coefficients
        if cut.material is None and cut.ktc_n_mm2 is not None and cut.krc_n_mm2 is not None:
            return CuttingCoefficients.from_n_mm(cut.ktc_n_mm2, cut.krc_n_mm2)
        raise ConfigError("cut: give either material or both ktc_n_mm2 and krc_n_mm2")

    def milling_coefficients(self, material: str) -> CuttingCoefficients:
        """The milling coefficients of ``[cut]`` (:meth:`coefficients`) where it gives any,
        else those of ``material``: an entry of the materials library
        (``cnctwin.mechanics.materials``), such as a machining configuration's ``[material]``.

        Raises
        ------
        ConfigError
            For an orthogonal cut, for a ``[cut]`` that gives coefficients inconsistently, and
            when it gives none and ``material`` is not in the library.
        """
        from cnctwin.mechanics import milling_material

        cut = self.cut
        if cut.operation != "milling":
            raise ConfigError(
                "stability file: cut.operation is 'orthogonal'; a roadmap needs milling"
            )
        if cut.material is not None or cut.ktc_n_mm2 is not None or cut.krc_n_mm2 is not None:
            return self.coefficients()
        try:
            return milling_material(material).coefficients
        except CnctwinError:
            raise ConfigError(
                f"no cutting coefficients: the stability file's [cut] names none and the "
                f"configuration's material {material!r} is not in the library; give "
                "cut.material or cut.ktc_n_mm2 and cut.krc_n_mm2"
            ) from None

    def check_work(self, lowest_rpm: float) -> None:
        """Refuse a semi-discretization whose transition matrix exceeds the memory limit.

        The monodromy matrix of ``m`` steps per period is ``2 n + 2 m`` square (``n`` modes,
        two tool-tip directions), built from ``2 m`` blocks of its width: about
        ``8 (2 m)^2 3`` bytes, largest at the lowest speed (the longest period).

        Parameters
        ----------
        lowest_rpm
            The lowest spindle speed of the diagram, rpm.

        Raises
        ------
        ConfigError
            Naming the steps, the matrix and what would fit (:mod:`cnctwin.memory`).
        """
        if self.lobes.method != "sdm":
            return
        steps = self.lobes.steps
        if steps == "auto":
            steps = _auto_steps(self.tool_dynamics(), self.process(), lowest_rpm * math.pi / 30)
        size = 2 * len(self.modes) + 2 * steps
        check_memory(
            f"semi-discretization with {steps} steps per period at {lowest_rpm:g} rpm is a "
            f"{size} x {size} transition matrix",
            8.0 * size * (size + 4 * steps),
            lambda fraction: (
                f"use lobes.steps (--steps) <= {int(steps * math.sqrt(fraction))}, a higher "
                "lowest speed, or method zoa"
            ),
        )

    def process_damping_model(self) -> ProcessDamping | None:
        """The ``[process_damping]`` table as a :class:`~cnctwin.dynamics.ProcessDamping`."""
        section = self.process_damping
        if section is None:
            return None
        return ProcessDamping(
            section.cpd_n_m2, section.chip_thickness_mm * 1e-3, section.diameter_mm * 1e-3
        )


def load_stability_config(
    path: str | os.PathLike[str],
    overrides: dict[str, dict[str, Any]] | None = None,
    *,
    modes_only: bool = False,
) -> StabilityConfig:
    """Read and validate a stability file, or a modes file completed by ``overrides``.

    Parameters
    ----------
    path
        The TOML file.
    overrides
        Values replacing the file's, by table and key (``{"cut": {"teeth": 4}}``): the
        command line's options.
    modes_only
        The file is a modes file (only ``[[modes]]``); the other tables come from
        ``overrides`` and their defaults.

    Raises
    ------
    ConfigError
        ``"FILE: key.path: what is wrong; got VALUE"`` for an unreadable file, invalid TOML or
        an invalid value.
    """
    data = _read(path)
    if modes_only:
        _validate(ModesFile, data, str(path))
        data = {"modes": data["modes"]}
    for table, values in (overrides or {}).items():
        section = data.setdefault(table, {})
        if not isinstance(section, dict):
            raise ConfigError(f"{table}: must be a table", str(path))
        section.update(values)
    return _validate(StabilityConfig, data, str(path))


def load_tool_stability(
    path: str | os.PathLike[str],
) -> StabilityConfig | dict[int, StabilityConfig]:
    """Read a stability file, or a tool map: stability files by tool number.

    A tool map is TOML with a ``[tools]`` table only: ``T1 = "end_mill.toml"`` (or ``1 =``)
    per tool, each path relative to the map's folder; the tools it does not name have no
    modes (:func:`cnctwin.dynamics.program_roadmap`).

    Raises
    ------
    ConfigError
        ``"FILE: ..."`` for a bad key, a value that is not a path, an empty map, and what
        :func:`load_stability_config` refuses in the files it names.
    """
    data = _read(path)
    if "tools" not in data or "modes" in data:
        return load_stability_config(path)
    source = str(path)
    tools = data["tools"]
    if set(data) != {"tools"} or not isinstance(tools, dict) or not tools:
        raise ConfigError(
            'a tool map holds one [tools] table of T<n> = "FILE" entries and nothing else',
            source,
        )
    files: dict[int, StabilityConfig] = {}
    for key, value in tools.items():
        digits = key[1:] if key[:1] in ("T", "t") else key
        if not digits.isdigit() or not isinstance(value, str) or not value:
            raise ConfigError(
                f'tools.{key} = {value!r}: give T<n> = "FILE" (a stability file per tool)',
                source,
            )
        if int(digits) in files:
            raise ConfigError(f"tools.{key}: tool T{int(digits)} given twice", source)
        files[int(digits)] = load_stability_config(Path(path).parent / value)
    return files


def load_modes_file(path: str | os.PathLike[str]) -> list[ModeEntry]:
    """Read the ``[[modes]]`` array of a modes file (no other keys).

    Raises
    ------
    ConfigError
        As :func:`load_stability_config`.
    """
    return _validate(ModesFile, _read(path), str(path)).modes


def _read(path: str | os.PathLike[str]) -> dict[str, Any]:
    source = str(path)
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except OSError as err:
        raise ConfigError(f"cannot read: {err.strerror}", source) from err
    except UnicodeDecodeError as err:
        raise ConfigError(f"not UTF-8 text (byte {err.start}): {err.reason}", source) from err
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"invalid TOML: {err}", source) from err


def _validate(model: type[_Model], data: dict[str, Any], source: str) -> _Model:
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise ConfigError(describe_validation_error(err, model), source) from err
