"""An NC program file run through the stock of a machining configuration, offline.

:func:`simulate_program` builds what :func:`~cnctwin.simulation.cut.simulate_cut` takes from a
:class:`~cnctwin.config.MachiningConfig` (a :class:`~cnctwin.geometry.Cutter` per tool, the
stock as a tri-dexel box, the interpreter of the machine's NC setup), cuts the program and
summarises the cut: volumes, engagement maxima, process time, and warnings for a rapid move
that cuts material (a collision) or material above the flutes (the shank would rub).
:func:`predict_program_signals` does the same with the machine signals
(:func:`~cnctwin.simulation.signals.simulate_signals`): forces, spindle torque, power, current.

Units as in the simulation layer: mm, mm^3, mm/min, s (names say so).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cnctwin.errors import ConfigError, NCError
from cnctwin.geometry import Cutter, DexelStock
from cnctwin.simulation.cut import StepTable, simulate_cut
from cnctwin.simulation.signals import (
    MachineSignals,
    axial_material,
    simulate_signals,
    spindle_drive_parameters,
)

if TYPE_CHECKING:
    from collections.abc import Iterator

    from cnctwin.config import MachiningConfig
    from cnctwin.nc import Interpreter

__all__ = [
    "ProgramCut",
    "ProgramSignals",
    "collision_warning",
    "predict_program_signals",
    "simulate_program",
]


@dataclass
class ProgramCut:
    """A program cut through the stock (:func:`simulate_program`).

    Attributes
    ----------
    file
        The NC file.
    table
        The engagement of every step (columns :data:`~cnctwin.simulation.cut.COLUMNS`).
    stock
        The stock after the cut.
    volume_before_mm3
        Stock volume before the cut, mm^3.
    runtime_s
        Wall-clock time of the simulation, s.
    density_per_mm, cycle_s
        Dexels per mm and cycle time (s) it ran at.
    warnings
        The interpreter's warnings, then a collision and a rubbing shank, each naming
        ``FILE:LINE``.
    """

    file: Path
    table: StepTable
    stock: DexelStock
    volume_before_mm3: float
    runtime_s: float
    density_per_mm: float
    cycle_s: float
    warnings: list[str] = field(default_factory=list)

    def summary(self) -> dict[str, Any]:
        """The cut in figures (the JSON of ``cnctwin simulate``).

        Returns
        -------
        dict
            ``file``, ``steps``, ``process_time_s``, ``runtime_s``, ``realtime_factor``,
            ``removed_volume_mm3``, ``stock_volume_before_mm3``, ``stock_volume_after_mm3``,
            ``volume_balance_mm3`` (before - after - removed: 0 up to rounding),
            ``max_ae_mm``, ``max_ap_mm``, ``max_mrr_mm3_s``, ``density_per_mm``,
            ``cycle_ms`` and ``warnings``.
        """
        table = self.table
        n = len(table)
        process_time = float(table.column("t_s")[-1]) if n else 0.0
        removed = float(table.column("removed_mm3").sum())
        after = self.stock.volume_mm3()
        runtime = self.runtime_s
        return {
            "file": str(self.file),
            "steps": n,
            "process_time_s": process_time,
            "runtime_s": runtime,
            "realtime_factor": process_time / runtime if runtime > 0 else math.inf,
            "removed_volume_mm3": removed,
            "stock_volume_before_mm3": self.volume_before_mm3,
            "stock_volume_after_mm3": after,
            "volume_balance_mm3": self.volume_before_mm3 - after - removed,
            "max_ae_mm": float(table.column("ae_mm").max()) if n else 0.0,
            "max_ap_mm": float(table.column("ap_mm").max()) if n else 0.0,
            "max_mrr_mm3_s": float(table.column("mrr_mm3_s").max()) if n else 0.0,
            "density_per_mm": self.density_per_mm,
            "cycle_ms": self.cycle_s * 1e3,
            "warnings": list(self.warnings),
        }


@dataclass
class ProgramSignals:
    """A program's predicted machine signals (:func:`predict_program_signals`).

    Attributes
    ----------
    file
        The NC file.
    signals
        The signals at every cycle.
    material, coefficients_source
        The workpiece material's name and where its cutting coefficients come from.
    rated_power_kw, rated_torque_nm
        The spindle's ratings (kW, N m), None where the configuration gives none.
    runtime_s
        Wall-clock time of the prediction, s.
    density_per_mm, cycle_s
        Dexels per mm and cycle time (s) it ran at.
    warnings
        The interpreter's warnings, then the prediction's, each naming the file.
    drilling_source
        Where the drilling coefficients come from when a tool is a drill or a tap, else None.
    """

    file: Path
    signals: MachineSignals
    material: str
    coefficients_source: str
    rated_power_kw: float | None
    rated_torque_nm: float | None
    runtime_s: float
    density_per_mm: float
    cycle_s: float
    warnings: list[str] = field(default_factory=list)
    drilling_source: str | None = None

    def summary(self) -> dict[str, Any]:
        """The signals in figures (the JSON of ``cnctwin signals``).

        Returns
        -------
        dict
            :meth:`MachineSignals.summary` plus ``file``, ``material``,
            ``coefficients_source``, ``drilling_coefficients_source`` (None without a drill or
            a tap), ``rated_power_kw``, ``rated_torque_nm``, ``runtime_s``, ``density_per_mm``,
            ``cycle_ms`` and ``warnings``.
        """
        return {
            "file": str(self.file),
            **self.signals.summary(),
            "material": self.material,
            "coefficients_source": self.coefficients_source,
            "drilling_coefficients_source": self.drilling_source,
            "rated_power_kw": self.rated_power_kw,
            "rated_torque_nm": self.rated_torque_nm,
            "runtime_s": self.runtime_s,
            "density_per_mm": self.density_per_mm,
            "cycle_ms": self.cycle_s * 1e3,
            "warnings": list(self.warnings),
        }


def _setup(
    config: MachiningConfig, density_per_mm: float
) -> tuple[dict[int, Cutter], DexelStock, Interpreter]:
    """The cutters by tool number, the stock box and the interpreter of ``config``."""
    from cnctwin.nc import Interpreter

    cutters = {tool.number: Cutter.from_tool_config(tool) for tool in config.tools}
    stock = DexelStock.box(config.stock.min_mm, config.stock.max_mm, density_per_mm)
    return cutters, stock, Interpreter(config.nc_setup())


@contextmanager
def _naming(program: Path) -> Iterator[None]:
    """Errors of the cut name the file ``program`` where they name no file (``<string>``)."""
    try:
        yield
    except NCError as err:
        if err.file == "<string>":
            raise NCError(err.message, str(program), err.line, err.column) from None
        raise


def collision_warning(table: StepTable) -> str | None:
    """The rapid moves of a cut that meet material, as ``LINE: ...`` naming every such line.

    Each step of :func:`~cnctwin.simulation.cut.simulate_cut` belongs to the move that did it
    (the step to a segment's end point is that segment's), so a rapid with contact is a rapid
    that really moves the tool through material: a collision on the machine.

    Parameters
    ----------
    table
        The steps of a cut.

    Returns
    -------
    str or None
        ``"FIRST: a rapid move cuts material (... at lines A, B, ...): a collision ..."``, with
        the removed volume (mm^3); None when no rapid meets material.
    """
    crash = (table.column("contact") > 0) & (table.column("rapid") > 0)
    if not crash.any():
        return None
    lines = table.column("line")[crash].astype(np.int64)
    volume = float(table.column("removed_mm3")[crash].sum())
    named = ", ".join(str(line) for line in np.unique(lines))
    return (
        f"{int(lines[0])}: a rapid move cuts material ({volume:.4g} mm^3 in "
        f"{int(crash.sum())} steps, at lines {named}): a collision on the machine"
    )


def simulate_program(
    program: Path,
    config: MachiningConfig,
    *,
    density_per_mm: float,
    cycle_s: float,
    on_chunk: Callable[[float], None] | None = None,
) -> ProgramCut:
    """Cut the stock of ``config`` along the NC file ``program``.

    Parameters
    ----------
    program
        NC file.
    config
        Machine (rapid rate), tools with geometry, stock (mm) and NC setup.
    density_per_mm
        Dexel density, 1/mm.
    cycle_s
        Cycle time, s.
    on_chunk
        Called after each chunk of steps with the program time reached, s (a progress bar).

    Returns
    -------
    ProgramCut
        The step table, the stock after the cut and the warnings; :meth:`ProgramCut.summary`
        gives the figures.

    Raises
    ------
    NCError
        For an error in the program (naming ``program`` and the line), or a tool it uses that
        has no geometry.
    """
    cutters, stock, interpreter = _setup(config, density_per_mm)
    volume_before = stock.volume_mm3()
    table = StepTable()
    started = time.perf_counter()
    with _naming(program):
        for rows in simulate_cut(
            interpreter.run_file(program),
            stock,
            cutters,
            rapid_mm_min=config.machine.rapid_mm_min,
            cycle_s=cycle_s,
        ):
            table.append(rows)
            if on_chunk is not None:
                on_chunk(float(rows[-1, 0]) if len(rows) else 0.0)
    runtime = time.perf_counter() - started
    warnings = list(interpreter.warnings)
    crash = collision_warning(table)
    if crash:
        warnings.append(f"{program}:{crash}")
    shank = np.flatnonzero(table.column("above_flutes") > 0)
    if shank.size:
        warnings.append(
            f"{program}:{int(table.column('line')[shank[0]])}: material above the flutes "
            f"({shank.size} steps): the shank would rub"
        )
    return ProgramCut(
        program, table, stock, volume_before, runtime, density_per_mm, cycle_s, warnings
    )


def predict_program_signals(
    program: Path,
    config: MachiningConfig,
    *,
    density_per_mm: float,
    cycle_s: float,
    on_chunk: Callable[[float], None] | None = None,
) -> ProgramSignals:
    """Predict the machine signals of the NC file ``program`` on the machine of ``config``.

    Parameters
    ----------
    program
        NC file.
    config
        Machine (with ``[machine.spindle]``), tools with geometry, stock and material (a
        milling entry of the materials library, :func:`cnctwin.mechanics.milling_material`).
    density_per_mm
        Dexel density, 1/mm.
    cycle_s
        Cycle time, s.
    on_chunk
        Called after each chunk of cycles with the program time reached, s.

    Returns
    -------
    ProgramSignals
        The signals and what they were predicted with; :meth:`ProgramSignals.summary` gives
        the figures.

    Raises
    ------
    ConfigError
        For a material missing from the library (naming ``material.name``; for a drill or a
        tap also from the drilling coefficients), an unknown spindle preset.
    NCError
        For an NC error, or a tool the program uses that has no geometry.
    """
    from cnctwin.mechanics import milling_material

    try:
        material = milling_material(config.material.name)
    except ConfigError as err:
        raise ConfigError(f"material.name: {err}") from None
    cutters, stock, interpreter = _setup(config, density_per_mm)
    drilling = axial_material(config.material.name, cutters)
    spindle = config.machine.spindle
    drive_name = spindle.preset + "".join(
        f"+{part}" for part in ("motor", "controller") if getattr(spindle, part) is not None
    )
    started = time.perf_counter()
    with _naming(program):
        signals = simulate_signals(
            interpreter.run_file(program),
            stock,
            cutters,
            material.coefficients,
            spindle_drive_parameters(spindle),
            rapid_mm_min=config.machine.rapid_mm_min,
            cycle_s=cycle_s,
            rated_power_w=None if spindle.rated_power_kw is None else spindle.rated_power_kw * 1e3,
            rated_torque_nm=spindle.rated_torque_nm,
            drive_name=drive_name,
            on_chunk=on_chunk,
            drilling=drilling,
        )
    runtime = time.perf_counter() - started
    return ProgramSignals(
        program,
        signals,
        material.name,
        material.source,
        spindle.rated_power_kw,
        spindle.rated_torque_nm,
        runtime,
        density_per_mm,
        cycle_s,
        [*interpreter.warnings, *(f"{program}: {w}" for w in signals.warnings)],
        None if drilling is None else drilling.source,
    )
