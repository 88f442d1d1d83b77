"""The common base of every configuration section."""

from __future__ import annotations

from pathlib import Path

from pydantic import BaseModel, ConfigDict, ValidationInfo
from pydantic_core import PydanticCustomError

__all__ = ["Section", "Vec3Mm", "resolve_file"]

#: A point or vector (x, y, z) in mm, written in TOML as ``[x, y, z]``.
Vec3Mm = tuple[float, float, float]


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
