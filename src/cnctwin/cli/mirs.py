"""``cnctwin mirs``: the elastic machining-induced residual stress of a milling cut (Ward 2021).

``predict`` prints the elastic MIRS depth profile of a flat end mill cut; ``search`` finds the
feed and spindle speed within bounds that keep its largest magnitude within a limit (Ward's 30 %
reduction by default). The physics is :mod:`cnctwin.mechanics.residual_stress` and
:mod:`cnctwin.optimize.residual_stress`; this module only parses and formats. Guide:
docs/residual_stress.md.
"""

from __future__ import annotations

import math
import sys
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import check_count, check_number
from cnctwin.errors import InputError

__all__ = ["app", "predict", "search"]

app = typer.Typer(
    help="Elastic machining-induced residual stress (Ward 2021): predict, search feed and speed.",
    no_args_is_help=True,
)

_MPA = 1e6
_UM = 1e-6
#: Largest feed per tooth the edge-load model takes, mm.
MAX_FZ_MM = 10.0
#: Smallest radial depth of cut, as a fraction of the diameter (below it the engagement arc
#: vanishes in floating point).
MIN_AE_FRACTION = 1e-6

Diameter = Annotated[float, typer.Option("--diameter-mm", help="Cutter diameter in mm.")]
Teeth = Annotated[int, typer.Option("--teeth", help="Number of teeth (flutes).")]
Width = Annotated[float, typer.Option("--ae-mm", help="Radial depth of cut in mm.")]
Feed = Annotated[float, typer.Option("--feed-mm-min", help="Feed in mm/min.")]
Rpm = Annotated[float, typer.Option("--rpm", help="Spindle speed in rev/min.")]
Forces = Annotated[
    str,
    typer.Option("--forces", help="Milling entry of the materials library (cutting force)."),
]
Material = Annotated[
    str, typer.Option("--material", help="Elastic entry of the materials library (workpiece).")
]
Contact = Annotated[
    float, typer.Option("--contact-mm", help="Contact length of the edge on the surface, mm.")
]
Depth = Annotated[float, typer.Option("--depth-um", help="Deepest point of the profile, um.")]
Points = Annotated[int, typer.Option("--points", help="Depths in the profile (surface first).")]
Down = Annotated[
    bool, typer.Option("--down/--up", help="Down- (climb) or up- (conventional) milling.")
]
Materials = Annotated[
    str | None,
    typer.Option("--materials", help="Your materials file (TOML, docs/materials.md)."),
]
Json = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]


@app.callback()
def _mirs() -> None:
    """Elastic machining-induced residual stress (Ward 2021): predict, search feed and speed."""


def _cut(
    diameter_mm: float,
    teeth: int,
    ae_mm: float,
    forces: str,
    material: str,
    contact_mm: float,
    depth_um: float,
    points: int,
    down: bool,
    materials_file: str | None,
) -> Any:
    """The MIRS function of the cut (:class:`cnctwin.optimize.MillingMirs`)."""
    import numpy as np

    from cnctwin.config import MAX_TOOL_DIAMETER_MM, MIN_TOOL_DIAMETER_MM
    from cnctwin.mechanics import ElasticMirsModel, immersion_angles, load_materials
    from cnctwin.optimize import MillingMirs

    check_number(
        "--diameter-mm", diameter_mm, MIN_TOOL_DIAMETER_MM, MAX_TOOL_DIAMETER_MM, unit="mm"
    )
    check_count("--teeth", teeth, 1, 100)
    if not (math.isfinite(ae_mm) and MIN_AE_FRACTION * diameter_mm <= ae_mm <= diameter_mm):
        raise InputError(
            f"--ae-mm {ae_mm!r}: give {MIN_AE_FRACTION:g} x the diameter <= ae <= the diameter "
            f"({diameter_mm:g} mm)"
        )
    check_number("--contact-mm", contact_mm, 0.001, 100.0, unit="mm")
    check_number("--depth-um", depth_um, 1.0, 10_000.0, unit="um")
    check_count("--points", points, 2, 2000)
    library = load_materials(materials_file)
    coefficients = library.milling_material(forces).coefficients
    elastic = library.elastic_material(material)
    entry, exit_ = immersion_angles(diameter_mm * 1e-3, ae_mm * 1e-3, down)
    depths = np.linspace(0.0, depth_um * _UM, points)
    model = ElasticMirsModel(elastic, contact_mm * 1e-3, depths)
    return MillingMirs(coefficients, teeth, entry, exit_, model)


def _check_cut(feed_mm_min: float, rpm: float, teeth: int) -> None:
    check_number("--feed-mm-min", feed_mm_min, 0.0, 1e6, low_open=True, unit="mm/min")
    check_number("--rpm", rpm, 0.0, 1e6, low_open=True, unit="rpm")
    _check_fz("--feed-mm-min", feed_mm_min, "--rpm", rpm, teeth)


def _check_fz(feed_option: str, feed: float, rpm_option: str, rpm: float, teeth: int) -> None:
    """The feed per tooth of a feed and speed is at most 10 mm (the model's range)."""
    fz_mm = feed / (max(teeth, 1) * rpm)
    if not fz_mm <= MAX_FZ_MM:
        raise InputError(
            f"{feed_option} {feed:g} at {rpm_option} {rpm:g} is a feed per tooth of "
            f"{fz_mm:g} mm; give a feed and speed with at most {MAX_FZ_MM:g} mm per tooth"
        )


@app.command()
def predict(
    diameter_mm: Diameter,
    teeth: Teeth,
    ae_mm: Width,
    feed_mm_min: Feed,
    rpm: Rpm,
    forces: Forces = "AA7075-T6",
    material: Material = "AA7050-T7451",
    contact_mm: Contact = 0.1,
    depth_um: Depth = 200.0,
    points: Points = 41,
    down: Down = True,
    materials_file: Materials = None,
    as_json: Json = False,
) -> None:
    """The elastic MIRS depth profile of a flat end mill cut (Ward 2021, Eq. 3-5)."""
    _check_cut(feed_mm_min, rpm, teeth)
    cut = _cut(
        diameter_mm, teeth, ae_mm, forces, material, contact_mm, depth_um,
        points, down, materials_file,
    )  # fmt: skip
    profile = cut.profile(feed_mm_min, rpm)
    fz_mm = feed_mm_min / (teeth * rpm)
    from cnctwin.mechanics import milling_surface_load

    load = milling_surface_load(
        cut.coefficients, fz_mm * 1e-3, cut.entry_rad, cut.exit_rad, contact_mm * 1e-3
    )
    report = {
        "feed_mm_min": feed_mm_min,
        "rpm": rpm,
        "fz_mm": fz_mm,
        "normal_load_n_mm": load.normal_n_m * 1e-3,
        "tangential_load_n_mm": load.tangential_n_m * 1e-3,
        "contact_mm": contact_mm,
        "max_abs_sigma_xx_mpa": profile.max_abs_xx_pa / _MPA,
        "depth_um": [float(z) / _UM for z in profile.depth_m],
        "sigma_xx_mpa": [float(s) / _MPA for s in profile.sigma_xx_pa],
        "sigma_yy_mpa": [float(s) / _MPA for s in profile.sigma_yy_pa],
    }
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    console = Console()
    console.print(
        f"fz {fz_mm:.4f} mm; edge load P {report['normal_load_n_mm']:.1f} N/mm, "
        f"Q {report['tangential_load_n_mm']:.1f} N/mm over {contact_mm:g} mm; "
        f"max |sigma_xx| {report['max_abs_sigma_xx_mpa']:.1f} MPa"
    )
    table = Table("depth um", "sigma_xx MPa", "sigma_yy MPa", title="elastic MIRS")
    step = max(1, (len(profile.depth_m) - 1) // 10)
    for i in range(0, len(profile.depth_m), step):
        table.add_row(
            f"{report['depth_um'][i]:.1f}",
            f"{report['sigma_xx_mpa'][i]:.1f}",
            f"{report['sigma_yy_mpa'][i]:.1f}",
        )
    console.print(table)


@app.command()
def search(
    diameter_mm: Diameter,
    teeth: Teeth,
    ae_mm: Width,
    feed_mm_min: Feed,
    rpm: Rpm,
    reduction: Annotated[
        float,
        typer.Option("--reduction", help="Fraction by which to lower the MIRS of the cut given."),
    ] = 0.3,
    limit_mpa: Annotated[
        float | None,
        typer.Option("--limit-mpa", help="Largest MIRS allowed, MPa (instead of --reduction)."),
    ] = None,
    min_feed: Annotated[
        float | None, typer.Option("--min-feed", help="Lowest feed, mm/min (default: 10 %).")
    ] = None,
    max_feed: Annotated[
        float | None, typer.Option("--max-feed", help="Highest feed, mm/min (default: given).")
    ] = None,
    min_rpm: Annotated[
        float | None, typer.Option("--min-rpm", help="Lowest speed, rpm (default: 50 %).")
    ] = None,
    max_rpm: Annotated[
        float | None, typer.Option("--max-rpm", help="Highest speed, rpm (default: given).")
    ] = None,
    speeds: Annotated[int, typer.Option("--speeds", help="Spindle speeds tried.")] = 9,
    forces: Forces = "AA7075-T6",
    material: Material = "AA7050-T7451",
    contact_mm: Contact = 0.1,
    depth_um: Depth = 200.0,
    points: Points = 41,
    down: Down = True,
    materials_file: Materials = None,
    as_json: Json = False,
) -> None:
    """The largest feed, and its speed, that keep the elastic MIRS within a limit."""
    from cnctwin.optimize import search_feed_speed

    _check_cut(feed_mm_min, rpm, teeth)
    check_count("--speeds", speeds, 1, 200)
    cut = _cut(
        diameter_mm, teeth, ae_mm, forces, material, contact_mm, depth_um,
        points, down, materials_file,
    )  # fmt: skip
    start = cut(feed_mm_min, rpm)
    if limit_mpa is None:
        check_number("--reduction", reduction, 0.0, 1.0, unit="(fraction)")
        if reduction >= 1.0:
            raise InputError(f"--reduction {reduction!r}: give 0 <= reduction < 1")
        limit_pa = (1.0 - reduction) * start
    else:
        limit_pa = check_number("--limit-mpa", limit_mpa, 0.0, 1e5, low_open=True) * _MPA
    feeds = (
        min_feed if min_feed is not None else 0.1 * feed_mm_min,
        max_feed if max_feed is not None else feed_mm_min,
    )
    rpms = (
        min_rpm if min_rpm is not None else 0.5 * rpm,
        max_rpm if max_rpm is not None else rpm,
    )
    for option, value in zip(
        ("--min-feed", "--max-feed", "--min-rpm", "--max-rpm"), (*feeds, *rpms), strict=True
    ):
        check_number(option, value, 0.0, 1e6, low_open=True)
    if feeds[0] > feeds[1]:
        raise InputError(
            f"--min-feed {feeds[0]:g} > --max-feed {feeds[1]:g} mm/min: give min <= max"
        )
    if rpms[0] > rpms[1]:
        raise InputError(f"--min-rpm {rpms[0]:g} > --max-rpm {rpms[1]:g}: give min <= max")
    _check_fz("--max-feed", feeds[1], "--min-rpm", rpms[0], teeth)
    found = search_feed_speed(cut, limit_pa, feeds, rpms, speeds=speeds)
    report = {
        "start_feed_mm_min": feed_mm_min,
        "start_rpm": rpm,
        "start_mirs_mpa": start / _MPA,
        "limit_mpa": limit_pa / _MPA,
        "feasible": found.feasible,
        "feed_mm_min": found.feed_mm_min,
        "rpm": found.spindle_rpm,
        "fz_mm": found.feed_mm_min / (teeth * found.spindle_rpm),
        "mirs_mpa": found.mirs_pa / _MPA,
        "reduction": 1.0 - found.mirs_pa / start,
        "evaluations": found.evaluations,
    }
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    verdict = "meets" if found.feasible else "CANNOT meet (lowest MIRS shown)"
    Console().print(
        f"start {feed_mm_min:g} mm/min, {rpm:g} rpm: max |sigma_xx| {start / _MPA:.1f} MPa; "
        f"limit {limit_pa / _MPA:.1f} MPa\n"
        f"{verdict}: {found.feed_mm_min:.0f} mm/min, {found.spindle_rpm:.0f} rpm "
        f"(fz {report['fz_mm']:.4f} mm): {found.mirs_pa / _MPA:.1f} MPa "
        f"({100 * report['reduction']:.0f} % lower; {found.evaluations} evaluations)"
    )
