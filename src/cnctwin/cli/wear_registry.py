"""``cnctwin wear mount|compensate|retire|history``: tool offset compensation from part
measurements (Bolyn 2023), with the twins kept in an SQLite registry between runs."""

from __future__ import annotations

import sys
from datetime import UTC, datetime
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import JsonOutput, check_number
from cnctwin.errors import DataError
from cnctwin.store import TwinRegistry
from cnctwin.wear import ManufacturingParameters

__all__ = ["compensate", "history", "mount", "retire"]

_MM = 1e-3
_UM = 1e-6
#: Largest part dimension, mm: the swing of large lathes.
MAX_DIMENSION_MM = 10_000.0
#: Largest tolerance bound and offset resolution, um (10 mm).
MAX_TOLERANCE_UM = 10_000.0
#: Largest cutting speed, m/min: above high-speed machining of aluminium.
MAX_CUTTING_SPEED_M_MIN = 10_000.0
#: Largest feed per revolution, mm.
MAX_FEED_MM_REV = 10.0
#: Largest depth of cut, mm.
MAX_DEPTH_MM = 100.0

DbOpt = Annotated[Path, typer.Option("--db", help="Registry database (SQLite file).")]
ToolOpt = Annotated[str, typer.Option("--tool", help="Tool id, e.g. T0101-insert-42.")]
LatheOpt = Annotated[str, typer.Option("--lathe", help="Lathe name.")]


def _emit(report: dict[str, Any], as_json: bool, title: str) -> None:
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    table = Table(title=title, show_header=False, title_justify="left")
    for key, value in report.items():
        table.add_row(key, str(value))
    Console().print(table)


def mount(
    db: DbOpt,
    tool: ToolOpt,
    target_mm: Annotated[float, typer.Option("--target-mm", help="Nominal dimension, mm.")],
    tolerance_um: Annotated[
        tuple[float, float],
        typer.Option("--tolerance-um", help="Tolerance interval around the target, um."),
    ] = (-50.0, 50.0),
    lathe: LatheOpt = "lathe",
    resolution_um: Annotated[
        float, typer.Option("--resolution-um", help="Offset resolution of a new lathe, um.")
    ] = 0.0,
    material: Annotated[str | None, typer.Option("--material", help="Workpiece material.")] = None,
    tool_ref: Annotated[str | None, typer.Option("--tool-ref", help="Insert reference.")] = None,
    vc_m_min: Annotated[float | None, typer.Option("--vc-m-min", help="Cutting speed.")] = None,
    f_mm_rev: Annotated[float | None, typer.Option("--f-mm-rev", help="Feed per rev.")] = None,
    ap_mm: Annotated[float | None, typer.Option("--ap-mm", help="Depth of cut.")] = None,
    no_heritage: Annotated[
        bool, typer.Option("--no-heritage", help="Start without inheriting a retired twin.")
    ] = False,
    as_json: JsonOutput = False,
) -> None:
    """Mount a new tool: its twin inherits the drift of the most similar retired tool."""
    check_number("--target-mm", target_mm, 0.0, MAX_DIMENSION_MM, low_open=True, unit="mm")
    for value in tolerance_um:
        check_number("--tolerance-um", value, -MAX_TOLERANCE_UM, MAX_TOLERANCE_UM, unit="um")
    if not tolerance_um[0] < tolerance_um[1]:
        raise DataError(f"--tolerance-um {tolerance_um}: give LOW HIGH with LOW < HIGH, um")
    check_number("--resolution-um", resolution_um, 0.0, MAX_TOLERANCE_UM, unit="um")
    for option, value, high, unit in (
        ("--vc-m-min", vc_m_min, MAX_CUTTING_SPEED_M_MIN, "m/min"),
        ("--f-mm-rev", f_mm_rev, MAX_FEED_MM_REV, "mm"),
        ("--ap-mm", ap_mm, MAX_DEPTH_MM, "mm"),
    ):
        if value is not None:
            check_number(option, value, 0.0, high, low_open=True, unit=unit)
    given = [material, tool_ref, vc_m_min, f_mm_rev, ap_mm]
    parameters = None
    if any(v is not None for v in given):
        if any(v is None for v in given):
            raise DataError(
                "manufacturing parameters need all of --material, --tool-ref, --vc-m-min, "
                "--f-mm-rev and --ap-mm (or none of them)"
            )
        parameters = ManufacturingParameters(
            str(material),
            str(tool_ref),
            float(vc_m_min or 0) / 60.0,
            float(f_mm_rev or 0) * _MM,
            float(ap_mm or 0) * _MM,
        )
    with TwinRegistry(db) as registry:
        record = registry.mount(
            lathe,
            tool,
            target_m=target_mm * _MM,
            tolerance_m=(tolerance_um[0] * _UM, tolerance_um[1] * _UM),
            parameters=parameters,
            resolution_m=resolution_um * _UM,
            inherit=not no_heritage,
        )
    heritage = record.twin.heritage
    _emit(
        {
            "lathe": lathe,
            "tool": tool,
            "heritage_from": heritage.tool_id if heritage else None,
            "heritage_slope_um_per_part": round(heritage.slope / _UM, 3) if heritage else None,
            "initial_correction_um": round(record.twin.offset / _UM, 3),
        },
        as_json,
        f"mounted {tool} on {lathe}",
    )


def compensate(
    db: DbOpt,
    tool: ToolOpt,
    measurement_mm: Annotated[
        str, typer.Option("--measurement", help="Measured dimension of the part, mm.")
    ],
    lathe: LatheOpt = "lathe",
    write_offset: Annotated[
        Path | None,
        typer.Option(
            "--write-offset",
            help="Twin configuration whose [connection] gets the correction as a wear offset "
            "(only with [control] enabled = true; bounded by [control.tool_offset]).",
        ),
    ] = None,
    machine_tool: Annotated[
        int | None, typer.Option("--machine-tool", help="Tool number on the machine.")
    ] = None,
    offset_axis: Annotated[
        str,
        typer.Option(
            "--offset-axis",
            help="Dimension measured: diameter (half to the radius wear), radius or length.",
        ),
    ] = "diameter",
    internal: Annotated[
        bool, typer.Option("--internal", help="The dimension is internal (a bore).")
    ] = False,
    as_json: JsonOutput = False,
) -> None:
    """Record a measured part and print the tool-offset correction to apply now; with
    --write-offset, write it to the machine's wear offset and read it back."""
    if (write_offset is not None or machine_tool is not None) and (
        machine_tool is None or not 0 < machine_tool < 10_000
    ):
        raise DataError(
            f"--machine-tool {machine_tool!r}: give the tool's number on the machine "
            "(1 to 9999) with --write-offset"
        )
    if write_offset is not None:
        from cnctwin.twin import OFFSET_AXES, load_run_config

        if offset_axis not in OFFSET_AXES:
            raise DataError(f"--offset-axis {offset_axis!r}; valid: {', '.join(OFFSET_AXES)}")
        run_config = load_run_config(write_offset)
    try:
        measured = float(measurement_mm)
    except ValueError:
        raise DataError(
            f"measurement {measurement_mm!r} is not a number; give the dimension in mm"
        ) from None
    check_number("--measurement", measured, 0.0, MAX_DIMENSION_MM, low_open=True, unit="mm")
    with TwinRegistry(db) as registry:
        obs = registry.record(lathe, tool, measured * _MM)
    report: dict[str, Any] = {
        "tool": tool,
        "part": obs.part,
        "deviation_um": round(obs.measured_deviation / _UM, 3),
        "slope_um_per_part": round(obs.slope / _UM, 4),
        "trusted": obs.trusted,
        "slope_source": obs.source,
        "correction_um": round(obs.correction / _UM, 3),
        "offset_um": round(obs.offset / _UM, 3),
    }
    if write_offset is not None:
        from cnctwin.twin import apply_correction

        result = apply_correction(
            run_config,
            tool=int(machine_tool or 0),
            axis=offset_axis,  # type: ignore[arg-type]  # checked against OFFSET_AXES
            correction_mm=obs.correction / _MM,
            reason=f"{lathe} {tool} part {obs.part} measured {measured:g} mm: "
            f"correction {obs.correction / _UM:+g} um (Bolyn 2023)",
            internal=internal,
            base_dir=write_offset.parent,
        )
        report["offset_write"] = result.to_dict()
    _emit(
        report,
        as_json,
        f"{tool}: apply {obs.correction / _UM:+.1f} um",
    )


def retire(
    db: DbOpt, tool: ToolOpt, lathe: LatheOpt = "lathe", as_json: JsonOutput = False
) -> None:
    """Retire a tool; its twin becomes heritage for the next similar tool."""
    with TwinRegistry(db) as registry:
        record = registry.retire(lathe, tool)
    twin = record.twin
    _emit(
        {
            "tool": tool,
            "parts": twin.count,
            "final_slope_um_per_part": None if twin.slope is None else round(twin.slope / _UM, 4),
        },
        as_json,
        f"retired {tool}",
    )


def history(
    db: DbOpt,
    lathe: LatheOpt = "lathe",
    tool: Annotated[str | None, typer.Option("--tool", help="Only this tool.")] = None,
    as_json: JsonOutput = False,
) -> None:
    """Print the tools of a lathe and the logged parts with their corrections."""
    if not db.exists():
        raise DataError(f"{db}: no such registry")
    with TwinRegistry(db) as registry:
        tools = registry.tools(lathe)
        rows = registry.history(lathe, tool)
    parts: list[dict[str, Any]] = [
        {
            "tool": r.tool_id,
            "part": r.part,
            "deviation_um": round(r.deviation_m / _UM, 3),
            "correction_um": round(r.correction_m / _UM, 3),
            "trusted": r.trusted,
            "recorded": datetime.fromtimestamp(r.recorded_at, UTC).isoformat(timespec="seconds"),
        }
        for r in rows
    ]
    report = {
        "tools": [
            {
                "tool": t.tool_id,
                "state": t.state,
                "target_mm": t.target_m / _MM,
                "parts": t.twin.count,
                "heritage_from": t.twin.heritage.tool_id if t.twin.heritage else None,
            }
            for t in tools
        ],
        "parts": parts,
    }
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    table = Table(title=f"{lathe}: {len(rows)} parts", title_justify="left")
    for column in ("tool", "part", "deviation um", "correction um", "trusted", "recorded"):
        table.add_column(column)
    for part in parts:
        table.add_row(
            part["tool"],
            str(part["part"]),
            f"{part['deviation_um']:+.1f}",
            f"{part['correction_um']:+.1f}",
            str(part["trusted"]),
            part["recorded"],
        )
    Console().print(table)
