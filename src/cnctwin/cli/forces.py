"""``cnctwin forces``: mean milling forces, torque and power of one cut (a shop-floor calculator);
``cnctwin materials``: the materials library behind it (list, identify your own).

A flat end mill in a straight cut of radial depth ae and axial depth ap, coefficients from the
materials library (``--material``, with a user's file ``--materials``) or given (``--ktc ...
--kae``). Customary units at this edge (mm, rpm, N/mm^2, N/mm); the model
(:mod:`cnctwin.mechanics`) works in SI. The library, its schema and the conversions live in
:mod:`cnctwin.mechanics.materials`; this module only reads options and formats.

Frame and signs: forces on the tool; x along the feed, y normal to it in the plane (to the
left of the feed seen from the spindle), z along the tool axis toward the spindle; the spindle
turns clockwise seen from the spindle (M3). Up-milling cuts on the +y side, down-milling on
the -y side. Torque and power are positive while cutting.
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path
from typing import Annotated, Any

import typer
from rich import box
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import check_count, check_number
from cnctwin.errors import ConfigError, DataError, InputError

__all__ = ["forces", "forces_report", "materials_app"]

_SLICES = 50
_STEPS = 360


def forces_report(
    *,
    diameter_mm: float,
    teeth: int,
    helix_deg: float,
    ae_mm: float,
    ap_mm: float,
    fz_mm: float,
    rpm: float,
    material: str | None = None,
    coefficients_n_mm: dict[str, float] | None = None,
    down_milling: bool = True,
    materials_file: str | None = None,
) -> dict[str, Any]:
    """Mean and peak forces of one cut, in the units of ``cnctwin forces --json``.

    Parameters
    ----------
    diameter_mm, teeth, helix_deg
        Flat end mill: diameter in mm, number of teeth, helix angle in degrees.
    ae_mm, ap_mm, fz_mm
        Radial and axial depths of cut and feed per tooth, in mm.
    rpm
        Spindle speed in rev/min.
    material
        Name of a milling entry of the materials library; exclusive with ``coefficients_n_mm``.
    coefficients_n_mm
        ``ktc_n_mm2``, ``krc_n_mm2``, ``kac_n_mm2`` (N/mm^2), ``kte_n_mm``, ``kre_n_mm``,
        ``kae_n_mm`` (N/mm); missing keys are 0.
    down_milling
        Down- (climb) milling if True, up- (conventional) milling if False.
    materials_file
        A user's materials file (TOML, docs/materials.md) whose entries ``material`` may name.

    Returns
    -------
    dict
        ``mean_fx_n``, ``mean_fy_n``, ``mean_fz_n``, ``mean_resultant_n`` (magnitude of the
        mean force), ``max_resultant_n`` (over a revolution), ``mean_torque_nm``,
        ``mean_power_w``, then ``entry_deg``, ``exit_deg``, ``milling``, ``material`` and
        ``derived`` (how a derived library entry was computed, else "").

    Raises
    ------
    InputError
        For a value out of range, an unknown material, or both or neither coefficient sources.
    """
    from cnctwin.config import (
        MAX_SPINDLE_RPM,
        MAX_TOOL_DIAMETER_MM,
        MAX_TOOL_LENGTH_MM,
        MIN_TOOL_DIAMETER_MM,
    )
    from cnctwin.geometry import Cutter
    from cnctwin.mechanics import (
        CuttingCoefficients,
        ImmersionIntervals,
        immersion_angles,
        load_materials,
        mean_forces,
        milling_forces,
    )

    if not (MIN_TOOL_DIAMETER_MM <= diameter_mm <= MAX_TOOL_DIAMETER_MM):
        raise InputError(
            f"--diameter-mm {diameter_mm!r}; give {MIN_TOOL_DIAMETER_MM:g} <= diameter <= "
            f"{MAX_TOOL_DIAMETER_MM:g} mm"
        )
    check_number("--ap-mm", ap_mm, 0.0, MAX_TOOL_LENGTH_MM, low_open=True, unit="mm")
    check_number("--fz-mm", fz_mm, 0.0, 100.0, low_open=True, unit="mm")
    check_number("--rpm", rpm, 0.0, MAX_SPINDLE_RPM, low_open=True, unit="rpm")
    if not (math.isfinite(ae_mm) and 0.0 < ae_mm <= diameter_mm):
        raise InputError(f"--ae-mm {ae_mm!r}; give 0 < ae <= the diameter ({diameter_mm!r} mm)")
    if not 1 <= teeth <= 100:
        raise InputError(f"--teeth {teeth!r}; give an integer from 1 to 100")
    if not (math.isfinite(helix_deg) and 0.0 <= helix_deg < 90.0):
        raise InputError(f"--helix-deg {helix_deg!r}; give 0 <= helix < 90 degrees")
    derived = ""
    if material is not None and coefficients_n_mm is None:
        entry = load_materials(materials_file).milling_material(material)
        coefficients, derived = entry.coefficients, entry.derived
    elif material is None and coefficients_n_mm is not None:
        coefficients = CuttingCoefficients.from_n_mm(**coefficients_n_mm)
    else:
        raise InputError("give either --material NAME or the coefficients --ktc and --krc")
    # The force model reads only the engaged slices: the flutes are taken as long as the cut.
    cutter = Cutter.flat(diameter_mm, ap_mm, flutes=teeth, helix_rad=math.radians(helix_deg))
    cut = ImmersionIntervals.from_depths(
        cutter, ae_mm * 1e-3, ap_mm * 1e-3, down_milling=down_milling, slices=_SLICES
    )
    omega = rpm * 2.0 * math.pi / 60.0
    mean = mean_forces(cutter, coefficients, cut, fz_mm * 1e-3, omega)
    wave = milling_forces(cutter, coefficients, cut, fz_mm * 1e-3, omega, steps=_STEPS)
    entry, exit_ = immersion_angles(cutter.diameter_m, ae_mm * 1e-3, down_milling)
    return {
        "mean_fx_n": mean.fx_n,
        "mean_fy_n": mean.fy_n,
        "mean_fz_n": mean.fz_n,
        "mean_resultant_n": mean.resultant_n,
        "max_resultant_n": float(wave.resultant_n.max()),
        "mean_torque_nm": mean.torque_nm,
        "mean_power_w": mean.power_w,
        "entry_deg": math.degrees(entry),
        "exit_deg": math.degrees(exit_),
        "milling": "down" if down_milling else "up",
        "material": material,
        "derived": derived,
    }


def _coefficient(name: str, unit: str) -> Any:
    return typer.Option(f"--{name}", help=f"{name.capitalize()} coefficient in {unit}.")


def forces(
    diameter_mm: Annotated[float, typer.Option("--diameter-mm", help="Cutter diameter in mm.")],
    teeth: Annotated[int, typer.Option("--teeth", help="Number of teeth (flutes).")],
    helix_deg: Annotated[float, typer.Option("--helix-deg", help="Helix angle in degrees.")],
    ae_mm: Annotated[float, typer.Option("--ae-mm", help="Radial depth of cut in mm.")],
    ap_mm: Annotated[float, typer.Option("--ap-mm", help="Axial depth of cut in mm.")],
    fz_mm: Annotated[float, typer.Option("--fz-mm", help="Feed per tooth in mm.")],
    rpm: Annotated[float, typer.Option("--rpm", help="Spindle speed in rev/min.")],
    material: Annotated[
        str | None,
        typer.Option("--material", help="Milling entry of the materials library."),
    ] = None,
    ktc: Annotated[float | None, _coefficient("ktc", "N/mm^2")] = None,
    krc: Annotated[float | None, _coefficient("krc", "N/mm^2")] = None,
    kac: Annotated[float | None, _coefficient("kac", "N/mm^2")] = None,
    kte: Annotated[float | None, _coefficient("kte", "N/mm")] = None,
    kre: Annotated[float | None, _coefficient("kre", "N/mm")] = None,
    kae: Annotated[float | None, _coefficient("kae", "N/mm")] = None,
    down: Annotated[
        bool, typer.Option("--down/--up", help="Down- (climb) or up- (conventional) milling.")
    ] = True,
    materials_file: Annotated[
        str | None,
        typer.Option(
            "--materials",
            help="Your materials file (TOML, docs/materials.md): its entries join the library.",
        ),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """Mean forces, torque and power of a flat end mill in a straight cut.

    Forces on the tool: x along the feed, y normal to it in the plane, z axis to the spindle.

    Coefficients: --material NAME (cnctwin materials list; your own with --materials FILE), or
    --ktc and --krc (--kac --kte --kre --kae default to 0).
    """
    given = {
        "ktc_n_mm2": ktc,
        "krc_n_mm2": krc,
        "kac_n_mm2": kac,
        "kte_n_mm": kte,
        "kre_n_mm": kre,
        "kae_n_mm": kae,
    }
    explicit = {key: value for key, value in given.items() if value is not None}
    if explicit and material is not None:
        raise InputError("--material and explicit coefficients exclude each other; give one")
    if material is None and (ktc is None or krc is None):
        raise InputError("give --material NAME, or at least --ktc and --krc")
    report = forces_report(
        diameter_mm=diameter_mm,
        teeth=teeth,
        helix_deg=helix_deg,
        ae_mm=ae_mm,
        ap_mm=ap_mm,
        fz_mm=fz_mm,
        rpm=rpm,
        material=material,
        coefficients_n_mm=explicit or None,
        down_milling=down,
        materials_file=materials_file,
    )
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    Console().print(_table(report))


def _table(report: dict[str, Any]) -> Table:
    table = Table(
        show_header=False,
        caption="forces on the tool: x feed, y normal in the plane, z tool axis to the spindle",
        caption_justify="left",
    )
    table.add_column("quantity", style="bold")
    table.add_column("value", justify="right")
    table.add_row("coefficients", report["material"] or "given")
    if report["derived"]:
        table.add_row("derived", "from Kienzle: no radial/axial terms")
    table.add_row("milling", report["milling"])
    table.add_row("entry / exit", f"{report['entry_deg']:.1f} / {report['exit_deg']:.1f} deg")
    table.add_row("mean Fx", f"{report['mean_fx_n']:.1f} N")
    table.add_row("mean Fy", f"{report['mean_fy_n']:.1f} N")
    table.add_row("mean Fz", f"{report['mean_fz_n']:.1f} N")
    table.add_row("mean resultant", f"{report['mean_resultant_n']:.1f} N")
    table.add_row("max resultant", f"{report['max_resultant_n']:.1f} N")
    table.add_row("mean torque", f"{report['mean_torque_nm']:.3f} N m")
    table.add_row("mean power", f"{report['mean_power_w']:.0f} W")
    return table


materials_app = typer.Typer(
    help="The materials library: list its entries, identify your own from measured forces.",
    no_args_is_help=True,
)


@materials_app.command("list")
def materials_list(
    materials_file: Annotated[
        str | None,
        typer.Option("--materials", help="Your materials file (TOML): listed with the library."),
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
) -> None:
    """List the milling and Kienzle entries with their source, conditions and checked flag."""

    from cnctwin.mechanics import load_materials

    library = load_materials(materials_file)
    milling = [
        {
            "name": m.name,
            **m.coefficients.to_n_mm(),
            "checked": m.checked,
            "derived": m.derived,
            "source": m.source,
            "conditions": m.conditions,
            "note": m.note,
        }
        for m in library.milling.values()
    ]
    kienzle = [
        {
            "name": k.name,
            "kc11_n_mm2": k.kc11_pa / 1e6,
            "mc": k.mc,
            "checked": k.checked,
            "source": k.source,
            "conditions": k.conditions,
            "note": k.note,
        }
        for k in library.kienzle.values()
    ]
    if as_json:
        report = {"milling": milling, "kienzle": kienzle}
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    milling_rows = [
        (
            row["name"],
            " ".join(f"{row[k]:.4g}" for k in ("ktc_n_mm2", "krc_n_mm2", "kac_n_mm2")),
            " ".join(f"{row[k]:.4g}" for k in ("kte_n_mm", "kre_n_mm", "kae_n_mm")),
            "derived" if row["derived"] else ("yes" if row["checked"] else "no"),
        )
        for row in milling
    ]
    kienzle_rows = [
        (
            row["name"],
            f"{row['kc11_n_mm2']:g}",
            f"{row['mc']:g}",
            "yes" if row["checked"] else "no",
        )
        for row in kienzle
    ]
    console = Console()
    console.print(
        _listing(
            "milling (cnctwin forces --material NAME)",
            ("name", "Ktc Krc Kac N/mm^2", "Kte Kre Kae N/mm", "checked"),
            milling_rows,
        )
    )
    console.print(
        _listing(
            "Kienzle (turning, drilling)", ("name", "kc1.1 N/mm^2", "mc", "checked"), kienzle_rows
        )
    )
    console.print("checked: compared with the printed source (no: second-hand).")
    console.print("Sources, conditions and notes: --json, or docs/materials.md.")


def _listing(title: str, headers: tuple[str, ...], rows: list[tuple[str, ...]]) -> Table:
    """A table of ``headers``, one row per entry."""
    table = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, pad_edge=False)
    for header in headers:
        table.add_column(header, no_wrap=True)
    for row in rows:
        table.add_row(*row)
    return table


@materials_app.command("identify")
def materials_identify(
    means: Annotated[
        Path,
        typer.Argument(help="CSV of mean forces: columns fz_mm, fx_n, fy_n, fz_n ('#' comments)."),
    ],
    teeth: Annotated[int, typer.Option("--teeth", help="Number of teeth (flutes).")],
    ap_mm: Annotated[float, typer.Option("--ap-mm", help="Axial depth of cut in mm.")],
    name: Annotated[str, typer.Option("--name", help="Name of the new entry.")],
    diameter_mm: Annotated[
        float | None, typer.Option("--diameter-mm", help="Cutter diameter in mm (with --ae-mm).")
    ] = None,
    ae_mm: Annotated[
        float | None,
        typer.Option("--ae-mm", help="Radial depth of cut in mm; default: a slot."),
    ] = None,
    down: Annotated[
        bool, typer.Option("--down/--up", help="Down- (climb) or up- (conventional) milling.")
    ] = True,
    source: Annotated[
        str | None,
        typer.Option("--source", help="Where the forces come from (the entry's source)."),
    ] = None,
) -> None:
    """Identify milling coefficients from mean forces at several feeds; print a library entry.

    Altintas' linear regression of per-revolution mean forces against the feed per tooth
    (cnctwin.mechanics.identify_coefficients). The output is a [milling."NAME"] table of the
    materials schema: redirect it to a file and give that file to --materials.
    """
    import numpy as np

    from cnctwin.config import MAX_TOOL_DIAMETER_MM, MAX_TOOL_LENGTH_MM
    from cnctwin.mechanics import identify_coefficients, immersion_angles, milling_entry_toml

    check_count("--teeth", teeth, 1, 100)
    # 1 um: a thinner cut cannot be measured, and its coefficients overflow.
    check_number("--ap-mm", ap_mm, 1e-3, MAX_TOOL_LENGTH_MM, unit="mm")
    if (ae_mm is None) != (diameter_mm is None):
        raise InputError("give --ae-mm and --diameter-mm together (or neither, for a slot)")
    if ae_mm is None or diameter_mm is None:
        entry, exit_, cut = 0.0, math.pi, "slot"
    else:
        check_number(
            "--diameter-mm", diameter_mm, 0.0, MAX_TOOL_DIAMETER_MM, low_open=True, unit="mm"
        )
        if not (math.isfinite(ae_mm) and 1e-3 <= ae_mm <= diameter_mm):
            raise InputError(
                f"--ae-mm {ae_mm!r}; give 0.001 <= ae <= --diameter-mm ({diameter_mm!r})"
            )
        entry, exit_ = immersion_angles(diameter_mm * 1e-3, ae_mm * 1e-3, down)
        cut = f"ae {ae_mm:g} mm of D {diameter_mm:g} mm, {'down' if down else 'up'}-milling"
    feeds_mm, forces_n = _read_means(means)
    try:
        fit = identify_coefficients(
            np.array(feeds_mm) * 1e-3,
            np.array(forces_n),
            teeth=teeth,
            depth_m=ap_mm * 1e-3,
            entry_rad=entry,
            exit_rad=exit_,
        )
    except (DataError, ConfigError) as err:
        raise InputError(f"{means} with --ae-mm {ae_mm} --ap-mm {ap_mm:g}: {err}") from None
    r2 = ", ".join(f"{axis} {value:.3f}" for axis, value in zip("xyz", fit.r_squared, strict=True))
    sys.stdout.write(
        milling_entry_toml(
            name,
            fit.coefficients,
            source=source
            or f"Identified with cnctwin materials identify from {means.name} (mean forces).",
            conditions=(
                f"{cut}, {teeth} teeth, ap {ap_mm:g} mm, fz {min(feeds_mm):g}-"
                f"{max(feeds_mm):g} mm/tooth ({len(feeds_mm)} feeds)"
            ),
            note=f"Fit R^2: {r2}.",
        )
    )


def _read_means(path: Path) -> tuple[list[float], list[list[float]]]:
    """Feeds per tooth (mm) and mean forces (N, rows Fx Fy Fz) of a mean-forces CSV."""
    columns = ("fz_mm", "fx_n", "fy_n", "fz_n")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"{path}: {err}") from None
    rows = [
        (number, row)
        for number, row in enumerate(csv.reader(text.splitlines()), start=1)
        if row and not row[0].lstrip().startswith("#")
    ]
    if not rows or [cell.strip() for cell in rows[0][1]] != list(columns):
        raise InputError(f"{path}: the first row must be the header {','.join(columns)}")
    feeds: list[float] = []
    forces: list[list[float]] = []
    for number, row in rows[1:]:
        try:
            values = [float(cell) for cell in row]
        except ValueError:
            values = []
        if len(values) != 4 or not all(math.isfinite(v) for v in values) or values[0] <= 0.0:
            raise InputError(
                f"{path} line {number}: {','.join(row)!r}; give fz_mm > 0 and three finite forces"
            )
        feeds.append(values[0])
        forces.append(values[1:])
    if len(set(feeds)) < 2:
        raise InputError(f"{path}: {len(set(feeds))} distinct feeds; give at least two")
    return feeds, forces
