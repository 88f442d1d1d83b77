"""CAMotics project files (``.camotics``) as configuration: tools and the workpiece.

A CAMotics project is JSON with ``units`` (``"metric"`` or ``"imperial"``), ``tools`` by number
(each with its own ``units``, ``shape``, ``diameter`` and ``length``) and ``workpiece.bounds``
(``min``/``max`` in the project's units). Shapes map to cnctwin cutters: ``cylindrical`` is a
flat end mill and ``ballnose`` a ball end mill; ``conical`` and ``snubnose`` are refused with a
clear error. The tool's ``length`` becomes its flute length. As in CAMotics, a T word loads
its tool without M6. Everything else keeps the defaults of :class:`~cnctwin.config.TwinConfig`.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from cnctwin.config.twin import TwinConfig
from cnctwin.errors import ConfigError

__all__ = ["load_camotics_project"]

_MM_PER_INCH = 25.4
_SHAPES = {"cylindrical": "flat", "ballnose": "ball"}


def _scale(units: object, where: str, source: str) -> float:
    if units == "metric":
        return 1.0
    if units == "imperial":
        return _MM_PER_INCH
    raise ConfigError(f"{where}: units {units!r}; expected 'metric' or 'imperial'", source)


def load_camotics_project(path: str | os.PathLike[str]) -> TwinConfig:
    """Read a CAMotics project as a :class:`~cnctwin.config.TwinConfig`.

    Parameters
    ----------
    path
        The ``.camotics`` file.

    Returns
    -------
    TwinConfig
        Tools (diameter and flute length in mm) and a box stock from the workpiece bounds;
        the machine keeps its defaults.

    Raises
    ------
    cnctwin.errors.ConfigError
        One line naming the file and the offending key: unreadable file, invalid JSON, a
        tool shape cnctwin does not model, missing or inverted bounds.
    """
    source = str(path)
    try:
        project = json.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as err:
        raise ConfigError(f"cannot read CAMotics project: {err.strerror}", source) from err
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        raise ConfigError(f"not a CAMotics project (invalid JSON: {err})", source) from err
    if not isinstance(project, dict):
        raise ConfigError("not a CAMotics project (the top level is not an object)", source)
    scale = _scale(project.get("units", "metric"), "units", source)
    tools: list[dict[str, Any]] = []
    for number, tool in sorted((project.get("tools") or {}).items(), key=lambda kv: int(kv[0])):
        where = f"tools.{number}"
        if not isinstance(tool, dict):
            raise ConfigError(f"{where}: expected an object", source)
        shape = tool.get("shape")
        if shape not in _SHAPES:
            raise ConfigError(
                f"{where}.shape: {shape!r} is not supported; cnctwin models "
                + ", ".join(repr(s) for s in _SHAPES)
                + " (flat and ball end mills)",
                source,
            )
        tool_scale = _scale(
            tool.get("units", project.get("units", "metric")), f"{where}.units", source
        )
        entry: dict[str, Any] = {
            "number": int(number),
            "kind": _SHAPES[shape],
            "diameter_mm": float(tool.get("diameter", 0.0)) * tool_scale,
        }
        if tool.get("length"):
            entry["flute_length_mm"] = float(tool["length"]) * tool_scale
        tools.append(entry)
    bounds = (project.get("workpiece") or {}).get("bounds") or {}
    if "min" not in bounds or "max" not in bounds:
        raise ConfigError("workpiece.bounds: needs 'min' and 'max' corners", source)
    stock = {
        "kind": "box",
        "min_mm": [float(v) * scale for v in bounds["min"]],
        "max_mm": [float(v) * scale for v in bounds["max"]],
    }
    try:
        return TwinConfig.model_validate(
            {"tools": tools, "stock": stock, "machine": {"tool_change_on_t": True}}
        )
    except ValidationError as err:
        first = err.errors()[0]
        key = ".".join(str(p) for p in first["loc"])
        raise ConfigError(f"{key}: {first['msg']}; got {first.get('input')!r}", source) from err
