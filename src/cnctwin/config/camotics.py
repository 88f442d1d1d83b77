"""CAMotics project files (``.camotics``) as configuration: tools and the workpiece.

A CAMotics project is JSON with ``units`` (``"metric"`` or ``"imperial"``), ``tools`` by number
(each with its own ``units``, ``shape``, ``diameter``, ``length`` and, for a snub nose,
``snub_diameter``) and ``workpiece.bounds`` (``min``/``max`` in the project's units).

Shapes, as CAMotics models them (its ``ConicSweep`` over the tool's ``length``):

===============  ============  ===============================================
CAMotics shape   cnctwin kind  envelope
===============  ============  ===============================================
``cylindrical``  ``flat``      cylinder of ``diameter`` over ``length``
``ballnose``     ``ball``      ball of ``diameter``, ``length`` fluted
``conical``      ``conical``   cone from the tip to ``diameter`` at ``length``
``snubnose``     ``snub``      cone from ``snub_diameter`` to ``diameter``
===============  ============  ===============================================

:func:`camotics_tools` gives every tool (:class:`CamoticsTool`, mm and degrees), from which
``cnctwin.geometry.Cutter`` builds the envelope. :func:`load_camotics_project` builds a
:class:`~cnctwin.config.MachiningConfig` whose ``tools`` hold every tool as a ``[[tools]]``
entry (a cone spanning the tool's length, as in CAMotics: no ``tip_angle_deg``); as in
CAMotics, a T word loads its tool without M6, and the workpiece bounds become a box stock.
Everything else keeps the defaults of :class:`~cnctwin.config.MachiningConfig`.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from cnctwin.config.loading import describe_validation_error
from cnctwin.config.machining import MachiningConfig
from cnctwin.errors import ConfigError

__all__ = ["CamoticsTool", "camotics_tools", "load_camotics_project"]


_MM_PER_INCH = 25.4
_SHAPES = {"cylindrical": "flat", "ballnose": "ball", "conical": "conical", "snubnose": "snub"}
#: Kinds the ``[[tools]]`` configuration model describes.


def _scale(units: object, where: str, source: str) -> float:
    if units == "metric":
        return 1.0
    if units == "imperial":
        return _MM_PER_INCH
    raise ConfigError(f"{where}: units {units!r}; expected 'metric' or 'imperial'", source)


def _read(path: str | os.PathLike[str]) -> tuple[dict[str, Any], str]:
    source = str(path)
    try:
        project = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as err:
        raise ConfigError(f"cannot read CAMotics project: {err.strerror}", source) from err
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ConfigError(f"not a CAMotics project (invalid JSON: {err})", source) from err
    if not isinstance(project, dict):
        raise ConfigError("not a CAMotics project (the top level is not an object)", source)
    return project, source


def _number(value: object, where: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where}: {value!r} is not a number", source)
    return float(value)


@dataclass(frozen=True, slots=True)
class CamoticsTool:
    """One tool of a CAMotics project, in cnctwin's terms (mm, degrees).

    Attributes
    ----------
    number
        Tool number (the T word).
    kind
        ``"flat"`` (CAMotics ``cylindrical``), ``"ball"`` (``ballnose``), ``"conical"`` or
        ``"snub"`` (``snubnose``).
    diameter_mm
        Largest cutting diameter, mm.
    flute_length_mm
        The tool's ``length``, mm, if given: the fluted length, and for a conical or snub
        tool the height of its cone.
    tip_diameter_mm
        Diameter of a snub nose's flat tip (CAMotics ``snub_diameter``), mm; 0 otherwise.
    """

    number: int
    kind: str
    diameter_mm: float
    flute_length_mm: float | None
    tip_diameter_mm: float = 0.0

    @property
    def tip_angle_deg(self) -> float | None:
        """Included tip angle in degrees of a conical or snub tool, whose cone spans its whole
        length as in CAMotics' ``ConicSweep``: ``2 atan((D - d_t) / (2 L))``; ``None`` for the
        other kinds or without a length."""
        if self.kind not in ("conical", "snub") or not self.flute_length_mm:
            return None
        half = 0.5 * (self.diameter_mm - self.tip_diameter_mm)
        return math.degrees(2.0 * math.atan2(half, self.flute_length_mm))


def camotics_tools(path: str | os.PathLike[str]) -> dict[int, CamoticsTool]:
    """Every tool of a CAMotics project, by number, lengths in mm.

    Parameters
    ----------
    path
        The ``.camotics`` file.

    Returns
    -------
    dict
        Tool number to :class:`CamoticsTool`, for all four CAMotics shapes (a geometry model
        builds its cutter from it, e.g. ``cnctwin.geometry.Cutter.conical(tool.diameter_mm,
        tool.flute_length_mm)``).

    Raises
    ------
    cnctwin.errors.ConfigError
        One line naming the file and the offending key: unreadable file, invalid JSON, a
        shape CAMotics does not have, a tool number or dimension that is not a number.
    """
    project, source = _read(path)
    return {tool.number: tool for tool in _tools(project, source)}


def _tools(project: dict[str, Any], source: str) -> list[CamoticsTool]:
    tools = project.get("tools") or {}
    if not isinstance(tools, dict):
        raise ConfigError("tools: expected an object of tools by number", source)
    out = []
    for key, tool in tools.items():
        where = f"tools.{key}"
        try:
            number = int(key)
        except ValueError:
            raise ConfigError(f"{where}: tool number {key!r} is not an integer", source) from None
        if not isinstance(tool, dict):
            raise ConfigError(f"{where}: expected an object", source)
        shape = tool.get("shape", "cylindrical")
        if shape not in _SHAPES:
            raise ConfigError(
                f"{where}.shape: {shape!r} is not a CAMotics tool shape; give "
                + ", ".join(repr(s) for s in _SHAPES),
                source,
            )
        scale = _scale(tool.get("units", project.get("units", "metric")), f"{where}.units", source)
        length = None
        if tool.get("length"):
            length = _number(tool["length"], f"{where}.length", source) * scale
        tip = 0.0
        if shape == "snubnose":
            tip = _number(tool.get("snub_diameter", 0.0), f"{where}.snub_diameter", source)
        out.append(
            CamoticsTool(
                number=number,
                kind=_SHAPES[shape],
                diameter_mm=_number(tool.get("diameter", 0.0), f"{where}.diameter", source) * scale,
                flute_length_mm=length,
                tip_diameter_mm=tip * scale,
            )
        )
    return sorted(out, key=lambda entry: entry.number)


def load_camotics_project(path: str | os.PathLike[str]) -> MachiningConfig:
    """Read a CAMotics project as a :class:`~cnctwin.config.MachiningConfig`.

    Parameters
    ----------
    path
        The ``.camotics`` file.

    Returns
    -------
    MachiningConfig
        Every tool as ``tools`` (kind, diameter, flute length and a snub nose's tip diameter
        in mm, as :func:`camotics_tools` reads them) and a box stock from the workpiece
        bounds; T loads a tool without M6; the rest keeps its defaults.

    Raises
    ------
    cnctwin.errors.ConfigError
        One line naming the file and the offending key: unreadable file, invalid JSON, a
        tool shape CAMotics does not have, missing or inverted bounds.
    """
    project, source = _read(path)
    scale = _scale(project.get("units", "metric"), "units", source)
    tools: list[dict[str, Any]] = []
    for tool in _tools(project, source):
        entry: dict[str, Any] = {
            "number": tool.number,
            "kind": tool.kind,
            "diameter_mm": tool.diameter_mm,
        }
        if tool.flute_length_mm is not None:
            entry["flute_length_mm"] = tool.flute_length_mm
        if tool.kind == "snub":
            entry["tip_diameter_mm"] = tool.tip_diameter_mm
        tools.append(entry)
    bounds = (project.get("workpiece") or {}).get("bounds") or {}
    if "min" not in bounds or "max" not in bounds:
        raise ConfigError("workpiece.bounds: needs 'min' and 'max' corners", source)
    corners = {}
    for corner in ("min", "max"):
        values = bounds[corner]
        if not isinstance(values, list) or len(values) != 3:
            raise ConfigError(
                f"workpiece.bounds.{corner}: {values!r}; give three numbers [x, y, z]", source
            )
        corners[corner] = [
            _number(v, f"workpiece.bounds.{corner}[{i}]", source) * scale
            for i, v in enumerate(values)
        ]
    stock = {"kind": "box", "min_mm": corners["min"], "max_mm": corners["max"]}
    try:
        return MachiningConfig.model_validate(
            {"tools": tools, "stock": stock, "machine": {"tool_change_on_t": True}}
        )
    except ValidationError as err:
        raise ConfigError(describe_validation_error(err, MachiningConfig), source) from err
