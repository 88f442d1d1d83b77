"""The packaged materials library: milling coefficients and Kienzle values, each with its source.

The data live in ``cnctwin/mechanics/data/materials.toml`` (customary units, named in the
keys); this module reads that file through :mod:`importlib.resources` and converts to SI.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from functools import lru_cache
from importlib.resources import files
from typing import Any, TypeVar

from cnctwin.errors import ConfigError, DataError
from cnctwin.mechanics.coefficients import CuttingCoefficients

__all__ = [
    "KienzleMaterial",
    "MillingMaterial",
    "kienzle_material",
    "kienzle_materials",
    "milling_material",
    "milling_materials",
]

_Entry = TypeVar("_Entry", "MillingMaterial", "KienzleMaterial")

_MILLING_KEYS = (
    "ktc_n_mm2",
    "krc_n_mm2",
    "kac_n_mm2",
    "kte_n_mm",
    "kre_n_mm",
    "kae_n_mm",
)
_TEXT_KEYS = ("source", "note")


@dataclass(frozen=True)
class MillingMaterial:
    """Milling coefficients of one material (or tool-material pair) with their source.

    Attributes
    ----------
    name
        The entry's name in the library.
    coefficients
        The six coefficients in SI units (Pa, N/m).
    source
        Where the values come from.
    note
        Caveats (conventions, missing terms).
    """

    name: str
    coefficients: CuttingCoefficients
    source: str
    note: str


@dataclass(frozen=True)
class KienzleMaterial:
    """Kienzle's specific-cutting-force parameters of one material with their source.

    Attributes
    ----------
    name
        The entry's name in the library.
    kc11_pa
        Specific cutting force at h = b = 1 mm, in Pa.
    mc
        Kienzle exponent (dimensionless).
    source
        Where the values come from.
    checked
        Whether the project compared the values with the printed source.
    note
        Caveats.
    """

    name: str
    kc11_pa: float
    mc: float
    source: str
    checked: bool
    note: str


def milling_materials() -> dict[str, MillingMaterial]:
    """All milling entries of the packaged library, by name."""
    return dict(_library()[0])


def kienzle_materials() -> dict[str, KienzleMaterial]:
    """All Kienzle entries of the packaged library, by name."""
    return dict(_library()[1])


def milling_material(name: str) -> MillingMaterial:
    """The milling entry ``name`` (case-insensitive).

    Raises
    ------
    ConfigError
        If there is no such entry; the message lists the valid names.
    """
    return _lookup(_library()[0], name, "milling")


def kienzle_material(name: str) -> KienzleMaterial:
    """The Kienzle entry ``name`` (case-insensitive).

    Raises
    ------
    ConfigError
        If there is no such entry; the message lists the valid names.
    """
    return _lookup(_library()[1], name, "Kienzle")


def _lookup(table: dict[str, _Entry], name: str, kind: str) -> _Entry:
    for key, entry in table.items():
        if key.casefold() == name.casefold():
            return entry
    raise ConfigError(f"no {kind} material {name!r}; valid: {', '.join(table)}")


@lru_cache(maxsize=1)
def _library() -> tuple[dict[str, MillingMaterial], dict[str, KienzleMaterial]]:
    resource = files("cnctwin.mechanics").joinpath("data", "materials.toml")
    try:
        data = tomllib.loads(resource.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise DataError(f"materials library {resource}: {err}") from None
    unknown = set(data) - {"milling", "kienzle"}
    if unknown:
        raise DataError(
            f"materials library: unknown tables {sorted(unknown)}; valid: milling, kienzle"
        )
    milling = {name: _milling(name, entry) for name, entry in data.get("milling", {}).items()}
    kienzle = {name: _kienzle(name, entry) for name, entry in data.get("kienzle", {}).items()}
    return milling, kienzle


def _milling(name: str, entry: dict[str, Any]) -> MillingMaterial:
    _check_keys(
        name,
        entry,
        (*_MILLING_KEYS, *_TEXT_KEYS),
        required=("ktc_n_mm2", "krc_n_mm2", "source"),
    )
    values = [_number(name, key, entry.get(key, 0.0)) for key in _MILLING_KEYS]
    try:
        coefficients = CuttingCoefficients.from_n_mm(*values)
    except ConfigError as err:
        raise DataError(f"materials library, milling entry {name!r}: {err}") from None
    return MillingMaterial(name, coefficients, entry["source"], entry.get("note", ""))


def _kienzle(name: str, entry: dict[str, Any]) -> KienzleMaterial:
    _check_keys(
        name,
        entry,
        ("kc11_n_mm2", "mc", "checked", *_TEXT_KEYS),
        required=("kc11_n_mm2", "mc", "source"),
    )
    kc11 = _number(name, "kc11_n_mm2", entry["kc11_n_mm2"])
    mc = _number(name, "mc", entry["mc"])
    if kc11 <= 0.0 or not 0.0 <= mc < 1.0:
        raise DataError(
            f"materials library, Kienzle entry {name!r}: kc1.1={kc11}, mc={mc}; "
            "need kc1.1 > 0, 0 <= mc < 1"
        )
    return KienzleMaterial(
        name,
        kc11 * 1e6,
        mc,
        entry["source"],
        bool(entry.get("checked", False)),
        entry.get("note", ""),
    )


def _check_keys(name: str, entry: Any, allowed: tuple[str, ...], required: tuple[str, ...]) -> None:
    if not isinstance(entry, dict):
        raise DataError(f"materials library: entry {name!r} is not a table")
    unknown = set(entry) - set(allowed)
    missing = set(required) - set(entry)
    if unknown or missing:
        raise DataError(
            f"materials library, entry {name!r}: unknown keys {sorted(unknown)}, missing "
            f"{sorted(missing)}; valid keys: {', '.join(allowed)}"
        )


def _number(name: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise DataError(f"materials library, entry {name!r}: {key}={value!r} is not a number")
    return float(value)
