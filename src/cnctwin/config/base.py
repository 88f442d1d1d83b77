"""The common base of every configuration section."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo
from pydantic_core import PydanticCustomError

__all__ = ["COORDINATE_LIMIT_MM", "CoordinateMm", "Section", "Vec3Mm", "resolve_file"]

#: Largest magnitude of a coordinate in a configuration, mm: 100 m, beyond the travel of any
#: machine tool, and far inside the range where float64 positions keep micrometres.
COORDINATE_LIMIT_MM = 100_000.0

#: A machine coordinate in mm, within +-:data:`COORDINATE_LIMIT_MM`.
CoordinateMm = Annotated[float, Field(ge=-COORDINATE_LIMIT_MM, le=COORDINATE_LIMIT_MM)]

#: A point or vector (x, y, z) in mm, written in TOML as ``[x, y, z]``.
Vec3Mm = tuple[CoordinateMm, CoordinateMm, CoordinateMm]


class Section(BaseModel):
    """A configuration table: unknown keys, NaN and infinities are errors; values are frozen."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


def resolve_file(value: Path | None, info: ValidationInfo) -> Path | None:
    """A file named in a configuration, relative to that file's folder.

    The folder is the ``base_dir`` of the validation context (the working directory for a
    configuration built in code). For a field validator of a path to an existing file.

    Raises
    ------
    pydantic_core.PydanticCustomError
        When no such file exists (reported with the key path by the loader).
    """
    if value is None:
        return None
    base = (info.context or {}).get("base_dir", Path.cwd())
    path = (Path(base) / value).resolve()
    if not path.is_file():
        raise PydanticCustomError(
            "missing_file",
            "no such file {path} (a relative path is relative to the configuration file)",
            {"path": str(path)},
        )
    return path
