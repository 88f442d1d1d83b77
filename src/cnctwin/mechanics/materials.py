"""The materials library: milling coefficients, Kienzle values and elastic constants, each with
its source.

The packaged data live in ``cnctwin/mechanics/data/materials.toml`` (customary units, named in
the keys); this module reads that file through :mod:`importlib.resources` and converts to SI.
A user's own file of the same schema (:func:`load_materials`) adds entries, typically those
``cnctwin materials identify`` writes from measured mean forces. The schema and the sources
are documented in ``docs/materials.md``.

A milling entry may be *derived* from a Kienzle entry (``from_kienzle``): Kienzle's law
``Fc = kc1.1 b h^(1 - mc)`` (h, b in mm) is replaced by its tangent at a reference chip
thickness ``h_ref``, which the linear edge-force model can carry
(:func:`kienzle_milling_coefficients`). Kienzle gives the cutting (tangential) force only, so a
derived entry's radial and axial coefficients are 0.

Elastic entries (``[elastic."NAME"]``: Young's modulus, Poisson's ratio, thermal expansion) feed
the residual stress model (:mod:`cnctwin.mechanics.residual_stress`).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from functools import lru_cache
from importlib.resources import files
from pathlib import Path
from typing import Any, TypeVar

from cnctwin.errors import ConfigError, DataError
from cnctwin.mechanics.coefficients import CuttingCoefficients

__all__ = [
    "ElasticMaterial",
    "KienzleMaterial",
    "MaterialsLibrary",
    "MillingMaterial",
    "kienzle_material",
    "kienzle_materials",
    "elastic_material",
    "kienzle_milling_coefficients",
    "load_materials",
    "milling_entry_toml",
    "milling_material",
    "milling_materials",
    "packaged_materials",
]

_Entry = TypeVar("_Entry", "MillingMaterial", "KienzleMaterial", "ElasticMaterial")

#: Valid ranges of the numeric keys: (low, high, low is open, unit). Wide on purpose: they
#: catch a unit slip (Pa for N/mm^2, m for mm), not an unusual material.
_RANGES: dict[str, tuple[float, float, bool, str]] = {
    "ktc_n_mm2": (0.0, 20_000.0, True, "N/mm^2"),
    "krc_n_mm2": (-20_000.0, 20_000.0, False, "N/mm^2"),
    "kac_n_mm2": (-20_000.0, 20_000.0, False, "N/mm^2"),
    "kte_n_mm": (-1_000.0, 1_000.0, False, "N/mm"),
    "kre_n_mm": (-1_000.0, 1_000.0, False, "N/mm"),
    "kae_n_mm": (-1_000.0, 1_000.0, False, "N/mm"),
    "kc11_n_mm2": (0.0, 20_000.0, True, "N/mm^2"),
    "mc": (0.0, 0.99, False, ""),
    "h_ref_mm": (0.0, 1.0, True, "mm"),
    "youngs_modulus_gpa": (0.0, 1500.0, True, "GPa"),
    "poisson_ratio": (0.0, 0.5, False, ""),
    "expansion_um_m_k": (0.0, 100.0, False, "um/(m K)"),
}
_MILLING_KEYS = ("ktc_n_mm2", "krc_n_mm2", "kac_n_mm2", "kte_n_mm", "kre_n_mm", "kae_n_mm")
_TEXT_KEYS = ("source", "conditions", "note", "derived")
_MILLING_ALLOWED = (*_MILLING_KEYS, *_TEXT_KEYS, "checked", "from_kienzle", "h_ref_mm")
_KIENZLE_ALLOWED = ("kc11_n_mm2", "mc", "source", "conditions", "note", "checked")
_ELASTIC_KEYS = ("youngs_modulus_gpa", "poisson_ratio", "expansion_um_m_k")
_ELASTIC_ALLOWED = (*_ELASTIC_KEYS, "source", "note", "checked")
_MM = 1e-3  # m per mm


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
        Where the values come from (author, year, title, table).
    note
        Caveats (conventions, missing terms).
    conditions
        The cutting conditions the values hold for (tool, rake, helix, speed range, coolant).
    checked
        Whether the values were compared with the printed source (False: taken second-hand).
    derived
        How the values were derived from other data ("" when taken as published or
        identified from measurements).
    """

    name: str
    coefficients: CuttingCoefficients
    source: str
    note: str
    conditions: str = ""
    checked: bool = False
    derived: str = ""


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
    conditions
        The cutting conditions the values hold for.
    """

    name: str
    kc11_pa: float
    mc: float
    source: str
    checked: bool
    note: str
    conditions: str = ""


@dataclass(frozen=True)
class ElasticMaterial:
    """Isotropic linear-elastic constants of one workpiece material with their source.

    Attributes
    ----------
    name
        The entry's name in the library.
    youngs_modulus_pa
        Young's modulus E, Pa.
    poisson_ratio
        Poisson's ratio nu (dimensionless, 0 <= nu < 0.5).
    expansion_per_k
        Linear thermal expansion coefficient alpha, 1/K.
    source
        Where the values come from.
    checked
        Whether the project compared the values with the printed source.
    note
        Caveats.
    """

    name: str
    youngs_modulus_pa: float
    poisson_ratio: float
    expansion_per_k: float
    source: str
    checked: bool
    note: str


@dataclass(frozen=True)
class MaterialsLibrary:
    """Milling and Kienzle entries by name: the packaged library, with a user's file if given.

    Attributes
    ----------
    milling
        Milling entries by name.
    kienzle
        Kienzle entries by name.
    elastic
        Elastic entries by name.
    """

    milling: dict[str, MillingMaterial]
    kienzle: dict[str, KienzleMaterial]
    elastic: dict[str, ElasticMaterial] = field(default_factory=dict)

    def milling_material(self, name: str) -> MillingMaterial:
        """The milling entry ``name`` (case-insensitive).

        Raises
        ------
        ConfigError
            If there is no such entry; the message lists the valid names.
        """
        return _lookup(self.milling, name, "milling")

    def kienzle_material(self, name: str) -> KienzleMaterial:
        """The Kienzle entry ``name`` (case-insensitive).

        Raises
        ------
        ConfigError
            If there is no such entry; the message lists the valid names.
        """
        return _lookup(self.kienzle, name, "Kienzle")

    def elastic_material(self, name: str) -> ElasticMaterial:
        """The elastic entry ``name`` (case-insensitive).

        Raises
        ------
        ConfigError
            If there is no such entry; the message lists the valid names.
        """
        return _lookup(self.elastic, name, "elastic")


def kienzle_milling_coefficients(kc11_pa: float, mc: float, h_ref_m: float) -> CuttingCoefficients:
    """Linear edge-force coefficients equal to Kienzle's law at and near a chip thickness.

    Kienzle's cutting force per unit chip width, ``f(h) = kc1.1 h0 (h / h0)^(1 - mc)`` with
    ``h0 = 1 mm`` (Kienzle and Victor 1957; Koenig and Klocke, *Fertigungsverfahren 1*), is
    replaced by its tangent at ``h_ref``: ``f(h) ~ Ktc h + Kte`` with

        Ktc = (1 - mc) kc1.1 (h_ref / h0)^(-mc),    Kte = mc kc1.1 h0 (h_ref / h0)^(1 - mc).

    The tangent equals Kienzle's force at ``h_ref`` (so a milling cut whose mean chip
    thickness is ``h_ref`` has Kienzle's mean cutting force, the mean-chip-thickness rule of
    Sandvik Coromant's and Tschaetsch's handbooks) and its slope; for mc <= 0.3 it stays
    within 6 % of Kienzle's law from h_ref / 2 to 2 h_ref.

    Parameters
    ----------
    kc11_pa
        Specific cutting force at h = b = 1 mm, Pa (> 0).
    mc
        Kienzle exponent, 0 <= mc < 1.
    h_ref_m
        Reference (mean) chip thickness, m (> 0).

    Returns
    -------
    CuttingCoefficients
        Ktc (Pa) and Kte (N/m); the radial and axial terms are 0 (Kienzle's cutting force
        says nothing of them).

    Raises
    ------
    ConfigError
        For a value out of range.
    """
    if not (math.isfinite(kc11_pa) and kc11_pa > 0.0):
        raise ConfigError(f"kc1.1 = {kc11_pa!r} Pa; give a finite value > 0")
    if not (math.isfinite(mc) and 0.0 <= mc < 1.0):
        raise ConfigError(f"mc = {mc!r}; give 0 <= mc < 1")
    if not (math.isfinite(h_ref_m) and h_ref_m > 0.0):
        raise ConfigError(f"h_ref = {h_ref_m!r} m; give a finite value > 0")
    ratio = h_ref_m / _MM
    return CuttingCoefficients(
        ktc=(1.0 - mc) * kc11_pa * ratio**-mc,
        krc=0.0,
        kte=mc * kc11_pa * _MM * ratio ** (1.0 - mc),
    )


def packaged_materials() -> MaterialsLibrary:
    """The packaged library (``cnctwin/mechanics/data/materials.toml``)."""
    return _packaged()


def load_materials(path: str | Path | None) -> MaterialsLibrary:
    """The packaged library with the entries of a user's materials file added.

    Parameters
    ----------
    path
        A TOML file of ``[milling."NAME"]`` and ``[kienzle."NAME"]`` tables in the packaged
        schema (docs/materials.md); ``None`` gives the packaged library alone. A derived
        milling entry may name a Kienzle entry of either file.

    Raises
    ------
    ConfigError
        If the file cannot be read, an entry is invalid (one line: the file, the entry, the
        key, the value and what is valid) or a name is already in the packaged library.
    """
    packaged = _packaged()
    if path is None:
        return packaged
    where = Path(path)
    try:
        data = tomllib.loads(where.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as err:
        raise ConfigError(f"materials file {where}: {err}") from None
    return _build(data, str(where), ConfigError, base=packaged)


def milling_materials() -> dict[str, MillingMaterial]:
    """All milling entries of the packaged library, by name."""
    return dict(_packaged().milling)


def kienzle_materials() -> dict[str, KienzleMaterial]:
    """All Kienzle entries of the packaged library, by name."""
    return dict(_packaged().kienzle)


def milling_material(name: str) -> MillingMaterial:
    """The packaged milling entry ``name`` (case-insensitive).

    Raises
    ------
    ConfigError
        If there is no such entry; the message lists the valid names.
    """
    return _packaged().milling_material(name)


def elastic_material(name: str) -> ElasticMaterial:
    """The packaged elastic entry ``name`` (case-insensitive).

    Raises
    ------
    ConfigError
        If there is no such entry; the message lists the valid names.
    """
    return _packaged().elastic_material(name)


def kienzle_material(name: str) -> KienzleMaterial:
    """The packaged Kienzle entry ``name`` (case-insensitive).

    Raises
    ------
    ConfigError
        If there is no such entry; the message lists the valid names.
    """
    return _packaged().kienzle_material(name)


def milling_entry_toml(
    name: str,
    coefficients: CuttingCoefficients,
    *,
    source: str,
    conditions: str,
    note: str = "",
) -> str:
    """A ``[milling."NAME"]`` table of the materials schema, as :func:`load_materials` reads it.

    Parameters
    ----------
    name
        The entry's name.
    coefficients
        The coefficients (Pa, N/m); written in N/mm^2 and N/mm with 6 significant digits.
    source, conditions, note
        The entry's texts (where the values come from, the cutting conditions, caveats).

    Returns
    -------
    str
        The table, ending in a newline; ``checked = true`` (the values are the user's own).
    """
    lines = [f"[milling.{_toml_string(name)}]"]
    for key, value in coefficients.to_n_mm().items():
        lines.append(f"{key} = {value:.6g}")
    lines.append(f"source = {_toml_string(source)}")
    lines.append(f"conditions = {_toml_string(conditions)}")
    if note:
        lines.append(f"note = {_toml_string(note)}")
    lines.append("checked = true")
    return "\n".join(lines) + "\n"


def _toml_string(text: str) -> str:
    escaped = text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
    return f'"{escaped}"'


def _lookup(table: dict[str, _Entry], name: str, kind: str) -> _Entry:
    for key, entry in table.items():
        if key.casefold() == name.casefold():
            return entry
    raise ConfigError(f"no {kind} material {name!r}; valid: {', '.join(table)}")


@lru_cache(maxsize=1)
def _packaged() -> MaterialsLibrary:
    resource = files("cnctwin.mechanics").joinpath("data", "materials.toml")
    try:
        data = tomllib.loads(resource.read_text(encoding="utf-8"))
    except (OSError, tomllib.TOMLDecodeError) as err:
        raise DataError(f"materials library {resource}: {err}") from None
    return _build(data, "materials library", DataError, base=None)


def _build(
    data: dict[str, Any],
    where: str,
    error: type[DataError] | type[ConfigError],
    base: MaterialsLibrary | None,
) -> MaterialsLibrary:
    unknown = sorted(set(data) - {"milling", "kienzle", "elastic"})
    if unknown:
        raise error(f"{where}: unknown tables {unknown}; valid: milling, kienzle, elastic")
    tables = {kind: data.get(kind, {}) for kind in ("milling", "kienzle", "elastic")}
    for kind, table in tables.items():
        if not isinstance(table, dict):
            raise error(f'{where}: {kind} is not a table; write [{kind}."NAME"] tables')
    kienzle = dict(base.kienzle) if base else {}
    milling = dict(base.milling) if base else {}
    for name, entry in tables["kienzle"].items():
        _check_new(name, kienzle, "kienzle", where, error)
        kienzle[name] = _kienzle(name, entry, where, error)
    for name, entry in tables["milling"].items():
        _check_new(name, milling, "milling", where, error)
        milling[name] = _milling(name, entry, where, error, kienzle)
    elastic = dict(base.elastic) if base else {}
    for name, entry in tables["elastic"].items():
        _check_new(name, elastic, "elastic", where, error)
        elastic[name] = _elastic(name, entry, where, error)
    return MaterialsLibrary(milling, kienzle, elastic)


def _check_new(
    name: str,
    table: dict[str, Any],
    kind: str,
    where: str,
    error: type[DataError] | type[ConfigError],
) -> None:
    if any(key.casefold() == name.casefold() for key in table):
        raise error(
            f"{where}: [{kind}.{_toml_string(name)}] is already in the library; "
            "give your entry another name"
        )


def _milling(
    name: str,
    entry: Any,
    where: str,
    error: type[DataError] | type[ConfigError],
    kienzle: dict[str, KienzleMaterial],
) -> MillingMaterial:
    place = f"{where}: [milling.{_toml_string(name)}]"
    if isinstance(entry, dict) and "from_kienzle" in entry:
        return _derived(name, entry, place, error, kienzle)
    _check_keys(place, entry, _MILLING_ALLOWED, ("ktc_n_mm2", "krc_n_mm2", "source"), error)
    if "h_ref_mm" in entry:
        raise error(f"{place} h_ref_mm is only for an entry derived with from_kienzle")
    values = [_number(place, key, entry.get(key, 0.0), error) for key in _MILLING_KEYS]
    return MillingMaterial(
        name,
        CuttingCoefficients.from_n_mm(*values),
        _text(place, entry, "source", error),
        _text(place, entry, "note", error),
        _text(place, entry, "conditions", error),
        _flag(place, entry, error),
        _text(place, entry, "derived", error),
    )


def _derived(
    name: str,
    entry: dict[str, Any],
    place: str,
    error: type[DataError] | type[ConfigError],
    kienzle: dict[str, KienzleMaterial],
) -> MillingMaterial:
    _check_keys(
        place,
        entry,
        ("from_kienzle", "h_ref_mm", "note", "conditions"),
        ("from_kienzle", "h_ref_mm"),
        error,
    )
    parent_name = _text(place, entry, "from_kienzle", error)
    try:
        parent = _lookup(kienzle, parent_name, "Kienzle")
    except ConfigError as err:
        raise error(f"{place} from_kienzle: {err}") from None
    h_ref_mm = _number(place, "h_ref_mm", entry["h_ref_mm"], error)
    coefficients = kienzle_milling_coefficients(parent.kc11_pa, parent.mc, h_ref_mm * _MM)
    how = (
        f"from Kienzle entry {parent.name!r} (kc1.1 = {parent.kc11_pa / 1e6:g} N/mm^2, "
        f"mc = {parent.mc:g}): Kienzle's law linearised at h_ref = {h_ref_mm:g} mm "
        "(cnctwin.mechanics.materials.kienzle_milling_coefficients); radial and axial "
        "terms unknown, set to 0"
    )
    note = _text(place, entry, "note", error)
    return MillingMaterial(
        name,
        coefficients,
        parent.source,
        note,
        _text(place, entry, "conditions", error) or parent.conditions,
        parent.checked,
        how,
    )


def _kienzle(
    name: str, entry: Any, where: str, error: type[DataError] | type[ConfigError]
) -> KienzleMaterial:
    place = f"{where}: [kienzle.{_toml_string(name)}]"
    _check_keys(place, entry, _KIENZLE_ALLOWED, ("kc11_n_mm2", "mc", "source"), error)
    kc11 = _number(place, "kc11_n_mm2", entry["kc11_n_mm2"], error)
    mc = _number(place, "mc", entry["mc"], error)
    return KienzleMaterial(
        name,
        kc11 * 1e6,
        mc,
        _text(place, entry, "source", error),
        _flag(place, entry, error),
        _text(place, entry, "note", error),
        _text(place, entry, "conditions", error),
    )


def _elastic(
    name: str, entry: Any, where: str, error: type[DataError] | type[ConfigError]
) -> ElasticMaterial:
    place = f"{where}: [elastic.{_toml_string(name)}]"
    _check_keys(place, entry, _ELASTIC_ALLOWED, (*_ELASTIC_KEYS, "source"), error)
    e, nu, alpha = (_number(place, key, entry[key], error) for key in _ELASTIC_KEYS)
    if nu >= 0.5:
        raise error(f"{place} poisson_ratio = {nu!r}; give 0 <= poisson_ratio < 0.5")
    return ElasticMaterial(
        name,
        e * 1e9,
        nu,
        alpha * 1e-6,
        _text(place, entry, "source", error),
        _flag(place, entry, error),
        _text(place, entry, "note", error),
    )


def _check_keys(
    place: str,
    entry: Any,
    allowed: tuple[str, ...],
    required: tuple[str, ...],
    error: type[DataError] | type[ConfigError],
) -> None:
    if not isinstance(entry, dict):
        raise error(f"{place} is not a table")
    unknown = sorted(set(entry) - set(allowed))
    if unknown:
        raise error(f"{place} unknown key {unknown[0]!r}; valid keys: {', '.join(allowed)}")
    missing = [key for key in required if key not in entry]
    if missing:
        raise error(f"{place} misses {missing[0]!r}; required: {', '.join(required)}")


def _number(place: str, key: str, value: Any, error: type[DataError] | type[ConfigError]) -> float:
    low, high, low_open, unit = _RANGES[key]
    valid = f"give {low:g} {'<' if low_open else '<='} {key} <= {high:g} {unit}".rstrip()
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise error(f"{place} {key} = {value!r} is not a number; {valid}")
    number = float(value)
    inside = (low < number if low_open else low <= number) and number <= high
    if not (math.isfinite(number) and inside):
        raise error(f"{place} {key} = {value!r}; {valid}")
    return number


def _text(
    place: str, entry: dict[str, Any], key: str, error: type[DataError] | type[ConfigError]
) -> str:
    value = entry.get(key, "")
    if not isinstance(value, str):
        raise error(f"{place} {key} = {value!r}; give a string")
    return value


def _flag(place: str, entry: dict[str, Any], error: type[DataError] | type[ConfigError]) -> bool:
    value = entry.get("checked", False)
    if not isinstance(value, bool):
        raise error(f"{place} checked = {value!r}; give true or false")
    return value
