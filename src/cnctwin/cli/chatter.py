"""``cnctwin chatter``: time-domain milling vibration and chatter; process-damping calibration.

``simulate`` runs the time-domain model (:mod:`cnctwin.dynamics.time_domain`) of one cut
described by a stability file (``--config``, docs/stability.md) and options: RMS vibration,
chatter verdict, the semi-discretization's verdict at the same point. ``calibrate-damping``
finds the process-damping coefficient of each measured cut of a CSV and fits Royandi 2026's
Gamma model per spindle speed (:mod:`cnctwin.dynamics.process_damping`). ``detect`` finds
chatter in a measured signal (:mod:`cnctwin.cli.chatter_detect`). Guide:
docs/chatter.md. The physics works in SI; this edge speaks rpm, mm, um, g and N/m^2.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import check_count, check_number
from cnctwin.cli.chatter_detect import detect
from cnctwin.config import MAX_SPINDLE_RPM, MAX_TOOL_DIAMETER_MM
from cnctwin.errors import ConfigError, InputError

if TYPE_CHECKING:
    from cnctwin.dynamics import (
        MillingProcess,
        MillingVibration,
        ProcessDampingModel,
        StabilityConfig,
    )
    from cnctwin.geometry import Cutter

__all__ = [
    "app",
    "calibrate_damping",
    "calibration_report",
    "detect",
    "simulate",
    "simulation_report",
]

app = typer.Typer(
    help="Time-domain milling vibration, chatter detection, process-damping calibration.",
    no_args_is_help=True,
)

_RPM = math.pi / 30.0  # rad/s per rpm
_G = 9.80665  # m/s^2 per g
#: The CSV columns of ``calibrate-damping`` (those of ``cnctwin roughness fit``).
CUT_COLUMNS = ("ap_mm", "spindle_rpm", "fz_mm", "vibration_g")
#: Shortest simulated time, s: one tooth period at 6,000 rpm and two teeth is 5 ms.
MIN_SIMULATED_S = 1e-3
#: Longest simulated time, s: the solver's 10 million steps end far sooner at usual speeds.
MAX_SIMULATED_S = 60.0
#: Largest edge coefficient in magnitude, N/mm: ten times those of hard steels.
MAX_EDGE_N_MM = 1_000.0
#: Steps per tooth period: the solver's least (accuracy) and a cap far above its default.
MIN_STEPS_PER_TOOTH = 20
MAX_STEPS_PER_TOOTH = 100_000

ConfigOption = Annotated[
    Path, typer.Option("--config", help="Stability file: modes, cut (docs/stability.md).")
]
DiameterOption = Annotated[
    float | None,
    typer.Option("--diameter-mm", help="Cutter diameter, mm (default: [process_damping])."),
]
HelixOption = Annotated[
    float, typer.Option("--helix-deg", help="Helix angle, degrees (default 0: straight flutes).")
]
KteOption = Annotated[
    float | None,
    typer.Option("--kte-n-mm", help="Tangential edge coefficient, N/mm (default: material)."),
]
KreOption = Annotated[
    float | None,
    typer.Option("--kre-n-mm", help="Radial edge coefficient, N/mm (default: material)."),
]
HelicalEdgeOption = Annotated[
    bool,
    typer.Option(
        "--helical-edge/--axial-edge",
        help="Edge force per helical edge length, K dz / cos(helix) (Royandi Eq. 10-11).",
    ),
]
StepsOption = Annotated[
    int | None,
    typer.Option("--steps", help="Steps per tooth period (default: 200 per mode cycle)."),
]
JsonOption = Annotated[bool, typer.Option("--json", help="Print one JSON object.")]


@app.callback()
def _chatter() -> None:
    """Time-domain milling vibration and chatter; process-damping calibration."""


def _milling(config: StabilityConfig) -> MillingProcess:
    """The config's cut, which must be milling."""
    from cnctwin.dynamics import MillingProcess

    process = config.process()
    if not isinstance(process, MillingProcess):
        raise ConfigError("cut.operation is 'orthogonal'; the time-domain model simulates milling")
    return process


def check_time_options(
    seconds: float,
    transient_s: float | None,
    kte_n_mm: float | None,
    kre_n_mm: float | None,
    steps: int | None,
    diameter_mm: float | None,
    helix_deg: float,
) -> None:
    """Range checks of the time-domain options (s, N/mm, steps per tooth period, mm, degrees)
    before any file is read; one-line :class:`InputError` naming the option."""
    if diameter_mm is not None:
        check_number(
            "--diameter-mm", diameter_mm, 0.0, MAX_TOOL_DIAMETER_MM, low_open=True, unit="mm"
        )
    if not (math.isfinite(helix_deg) and 0.0 <= helix_deg < 90.0):
        raise InputError(f"--helix-deg {helix_deg!r}; give 0 <= helix < 90 degrees")
    check_number("--seconds", seconds, MIN_SIMULATED_S, MAX_SIMULATED_S, unit="s")
    if transient_s is not None:
        check_number("--transient-s", transient_s, 0.0, MAX_SIMULATED_S, unit="s")
    for option, value in (("--kte-n-mm", kte_n_mm), ("--kre-n-mm", kre_n_mm)):
        if value is not None:
            check_number(option, value, -MAX_EDGE_N_MM, MAX_EDGE_N_MM, unit="N/mm")
    if steps is not None:
        check_count("--steps", steps, MIN_STEPS_PER_TOOTH, MAX_STEPS_PER_TOOTH)


def _edges(config: StabilityConfig, kte: float | None, kre: float | None) -> tuple[float, float]:
    """Edge coefficients in N/m: the options (N/mm), else the config's material, else 0."""
    base = config.coefficients()
    return (
        base.kte if kte is None else kte * 1e3,
        base.kre if kre is None else kre * 1e3,
    )


def _diameter(config: StabilityConfig, given: float | None) -> float | None:
    """Cutter diameter in mm from the option or the ``[process_damping]`` table."""
    if given is not None:
        return check_number(
            "--diameter-mm", given, 0.0, MAX_TOOL_DIAMETER_MM, low_open=True, unit="mm"
        )
    if config.process_damping is not None:
        return config.process_damping.diameter_mm
    return None


def _end_mill(teeth: int, diameter_mm: float, helix_deg: float, depth_mm: float) -> Cutter:
    """A flat end mill with flutes as long as the (deepest) cut ``depth_mm``: the time-domain
    model reads only its flutes, helix and diameter."""
    from cnctwin.geometry import Cutter

    if not (math.isfinite(helix_deg) and 0.0 <= helix_deg < 90.0):
        raise InputError(f"--helix-deg {helix_deg!r}; give 0 <= helix < 90 degrees")
    return Cutter.flat(diameter_mm, depth_mm, flutes=teeth, helix_rad=math.radians(helix_deg))


def _cutter(
    teeth: int, diameter_mm: float | None, helix_deg: float, depth_mm: float
) -> Cutter | None:
    """The cutter, or None (straight flutes) when no diameter is known."""
    if diameter_mm is None:
        if helix_deg != 0.0:
            raise InputError("--helix-deg needs the cutter diameter: give --diameter-mm")
        return None
    return _end_mill(teeth, diameter_mm, helix_deg, depth_mm)


def simulation_report(
    config: StabilityConfig,
    *,
    rpm: float,
    depth_mm: float,
    feed_mm: float | None = None,
    seconds: float = 0.3,
    transient_s: float | None = None,
    diameter_mm: float | None = None,
    helix_deg: float = 0.0,
    kte_n_mm: float | None = None,
    kre_n_mm: float | None = None,
    helical_edge: bool = False,
    cpd_n_m2: float | None = None,
    damping_model: ProcessDampingModel | None = None,
    steps: int | None = None,
) -> tuple[dict[str, Any], MillingVibration]:
    """Simulate one cut of a stability configuration and summarise it.

    Parameters
    ----------
    config
        A :class:`cnctwin.dynamics.config.StabilityConfig` with a milling cut.
    rpm, depth_mm, feed_mm
        Spindle speed (rpm), axial depth (mm) and feed per tooth (mm; default the
        ``[process_damping]`` chip thickness).
    seconds, transient_s
        Simulated time and the part of it left out of RMS and spectrum (default half), s.
    diameter_mm, helix_deg
        The cutter (diameter default from ``[process_damping]``).
    kte_n_mm, kre_n_mm, helical_edge
        Edge coefficients (default: the config's material) and how they are charged.
    cpd_n_m2, damping_model
        Process damping: a coefficient (default ``[process_damping].cpd_n_m2``, 0 turns it
        off) or a fitted Gamma model; exclusive.
    steps
        Steps per tooth period.

    Returns
    -------
    tuple
        The ``--json`` object and the simulation. JSON keys: ``spindle_rpm``, ``depth_mm``,
        ``feed_per_tooth_mm``, ``simulated_s``, ``transient_s``, ``steps_per_tooth``,
        ``slices``, ``tooth_passing_hz``, ``cpd_n_m2`` (null without process damping),
        ``process_damping_n_s_m``, ``rms`` (``displacement_um``, ``velocity_mm_s``,
        ``acceleration_m_s2``, ``acceleration_g``, ``force_n``: [x, y] each),
        ``mean_force_n`` and ``peak_to_peak_um`` ([x, y]), ``chatter``,
        ``nonsynchronous_ratio``, ``growth``, ``chatter_frequency_hz``,
        ``sdm_spectral_radius``, ``sdm_stable`` and ``wall_s``.
    """
    from cnctwin.dynamics import cut_process_damping, floquet_multipliers, simulate_milling

    process = _milling(config)
    speed = check_number("--rpm", rpm, 1.0, MAX_SPINDLE_RPM, low_open=True, unit="rpm") * _RPM
    depth = check_number("--depth-mm", depth_mm, 0.0, 1000.0, low_open=True, unit="mm") * 1e-3
    section = config.process_damping
    if feed_mm is None:
        if section is None:
            raise InputError("give --feed-mm (feed per tooth, mm)")
        feed_mm = section.chip_thickness_mm
    feed = check_number("--feed-mm", feed_mm, 0.0, 100.0, low_open=True, unit="mm") * 1e-3
    check_number("--seconds", seconds, 0.0, math.inf, low_open=True, unit="s")
    diameter = _diameter(config, diameter_mm)
    cutter = _cutter(process.teeth, diameter, helix_deg, depth_mm)
    kte, kre = _edges(config, kte_n_mm, kre_n_mm)
    if cpd_n_m2 is not None:
        check_number("--cpd-n-m2", cpd_n_m2, 0.0, math.inf, unit="N/m^2")
    if cpd_n_m2 is not None and damping_model is not None:
        raise InputError("--cpd-n-m2 and --damping-model exclude each other; give one")
    try:
        damping = cut_process_damping(
            depth_m=depth,
            feed_per_tooth_m=feed,
            spindle_rad_s=speed,
            diameter_m=None if cutter is None else cutter.diameter_m,
            cpd_pa=cpd_n_m2,
            model=damping_model,
            default_cpd_pa=None if section is None else section.cpd_n_m2,
        )
    except InputError as err:
        if diameter is None:  # the only refusal the checks above leave
            raise InputError(f"{err}; give --diameter-mm") from None
        raise
    cpd = None if damping is None else damping.coefficient_pa
    started = time.perf_counter()
    result = simulate_milling(
        config.tool_dynamics(),
        process,
        spindle_rad_s=speed,
        depth_m=depth,
        feed_per_tooth_m=feed,
        duration_s=seconds,
        cutter=cutter,
        edge_tangential_n_m=kte,
        edge_radial_n_m=kre,
        helical_edge=helical_edge,
        damping=damping,
        steps_per_tooth=steps,
    )
    rms = result.rms(transient_s)
    verdict = result.chatter(transient_s=transient_s)
    wall = time.perf_counter() - started
    window = result.steady_window(transient_s)
    radius = float(
        abs(floquet_multipliers(config.tool_dynamics(), process, speed, depth, damping=damping)[0])
    )
    displacement = result.displacement_m[window]
    report = {
        "spindle_rpm": rpm,
        "depth_mm": depth_mm,
        "feed_per_tooth_mm": feed * 1e3,
        "simulated_s": float(result.time_s.size * result.tooth_period_s / result.steps_per_tooth),
        "transient_s": float(window.start * result.tooth_period_s / result.steps_per_tooth),
        "steps_per_tooth": result.steps_per_tooth,
        "slices": result.slices,
        "tooth_passing_hz": result.tooth_passing_hz,
        "cpd_n_m2": cpd,
        "process_damping_n_s_m": result.process_damping_n_s_m,
        "rms": {
            "displacement_um": _pair(rms.displacement_m * 1e6),
            "velocity_mm_s": _pair(rms.velocity_m_s * 1e3),
            "acceleration_m_s2": _pair(rms.acceleration_m_s2),
            "acceleration_g": _pair(rms.acceleration_g),
            "force_n": _pair(rms.force_n),
        },
        "mean_force_n": _pair(result.force_n[window].mean(axis=0)),
        "peak_to_peak_um": _pair(np.ptp(displacement, axis=0) * 1e6),
        "chatter": verdict.chatter,
        "nonsynchronous_ratio": verdict.nonsynchronous_ratio,
        "growth": finite_json.finite(float(verdict.growth)),
        "chatter_frequency_hz": (
            finite_json.finite(float(verdict.frequency_hz)) if verdict.chatter else None
        ),
        "sdm_spectral_radius": radius,
        "sdm_stable": radius < 1.0,
        "wall_s": wall,
    }
    return report, result


@app.command()
def simulate(
    config: ConfigOption,
    rpm: Annotated[float, typer.Option("--rpm", help="Spindle speed, rpm.")],
    depth_mm: Annotated[float, typer.Option("--depth-mm", help="Axial depth of cut, mm.")],
    feed_mm: Annotated[
        float | None,
        typer.Option("--feed-mm", help="Feed per tooth, mm (default: [process_damping])."),
    ] = None,
    seconds: Annotated[
        float, typer.Option("--seconds", help="Time to simulate, s (default 0.3).")
    ] = 0.3,
    transient_s: Annotated[
        float | None,
        typer.Option("--transient-s", help="Time left out of RMS and spectrum (default half)."),
    ] = None,
    diameter_mm: DiameterOption = None,
    helix_deg: HelixOption = 0.0,
    kte_n_mm: KteOption = None,
    kre_n_mm: KreOption = None,
    helical_edge: HelicalEdgeOption = False,
    cpd_n_m2: Annotated[
        float | None,
        typer.Option("--cpd-n-m2", help="Process damping C_pd, N/m^2 (0: off; default: file)."),
    ] = None,
    damping_model: Annotated[
        Path | None,
        typer.Option("--damping-model", help="C_pd from the JSON of calibrate-damping."),
    ] = None,
    steps: StepsOption = None,
    plot: Annotated[
        Path | None,
        typer.Option("--plot", help="Write displacement, force and spectrum to this PNG."),
    ] = None,
    signals: Annotated[
        Path | None,
        typer.Option(
            "--signals", help="Write the signals over time to this CSV (for chatter detect)."
        ),
    ] = None,
    as_json: JsonOption = False,
) -> None:
    """Simulate one milling cut in time: vibration RMS, chatter, and the SDM's verdict."""
    from cnctwin.dynamics import load_stability_config, read_damping_model

    check_time_options(seconds, transient_s, kte_n_mm, kre_n_mm, steps, diameter_mm, helix_deg)
    settings = load_stability_config(config)
    model = read_damping_model(damping_model) if damping_model is not None else None
    report, result = simulation_report(
        settings,
        rpm=rpm,
        depth_mm=depth_mm,
        feed_mm=feed_mm,
        seconds=seconds,
        transient_s=transient_s,
        diameter_mm=diameter_mm,
        helix_deg=helix_deg,
        kte_n_mm=kte_n_mm,
        kre_n_mm=kre_n_mm,
        helical_edge=helical_edge,
        cpd_n_m2=cpd_n_m2,
        damping_model=model,
        steps=steps,
    )
    if plot is not None:
        _plot_simulation(plot, result, report, config.stem)
    if signals is not None:
        _write_signals(signals, result)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    Console().print(_simulation_table(report))


#: Columns of ``simulate --signals`` (SI units, named so).
SIGNAL_COLUMNS = ("t_s", "x_m", "y_m", "ax_m_s2", "ay_m_s2", "fx_n", "fy_n")


def _write_signals(path: Path, result: MillingVibration) -> None:
    """The simulated displacement, acceleration and force over time as a CSV."""
    data = np.column_stack(
        (result.time_s, result.displacement_m, result.acceleration_m_s2, result.force_n)
    )
    np.savetxt(path, data, delimiter=",", header=",".join(SIGNAL_COLUMNS), comments="", fmt="%.10g")


def calibration_report(
    config: StabilityConfig,
    cuts: dict[str, list[float]],
    *,
    diameter_mm: float | None = None,
    helix_deg: float = 0.0,
    kte_n_mm: float | None = None,
    kre_n_mm: float | None = None,
    helical_edge: bool = False,
    axis: str = "x",
    seconds: float = 0.2,
    steps: int | None = None,
) -> dict[str, Any]:
    """Calibrate C_pd per cut (Royandi 2026, Eq. 14) and fit Gamma per speed (Eq. 15-19).

    Parameters
    ----------
    config
        A stability configuration with a milling cut (the cuts are made with its immersion).
    cuts
        Columns ``ap_mm``, ``spindle_rpm``, ``fz_mm``, ``vibration_g`` (measured RMS
        acceleration along ``axis``, g).
    diameter_mm, helix_deg, kte_n_mm, kre_n_mm, helical_edge, steps
        As for :func:`simulation_report`; the diameter is required (cutting speed).
    axis
        ``"x"`` (feed) or ``"y"``.
    seconds
        Simulated time per run, s.

    Returns
    -------
    dict
        ``cuts``: per cut ``ap_mm``, ``spindle_rpm``, ``fz_mm``, ``vibration_g``,
        ``simulated_g``, ``relative_error`` (Eq. 14), ``cpd_n_m2``, ``gamma_n``,
        ``effective_damping_n_s_m``, ``status`` and ``runs``; ``fits``: per spindle speed
        with at least 3 matched depths ``spindle_rpm``, ``a_n``, ``b_n``, ``a0_mm``
        (``Gamma = A + B exp(-a_p / a0)``, the decaying form), ``mape_percent`` and
        ``rmse_n_m2``; ``unfitted_rpm``: the speeds without a fit; ``axis``, ``wall_s``.
    """
    from cnctwin.dynamics import (
        CalibrationSetup,
        calibrate_cpd,
        fit_process_damping_model,
    )

    if axis not in ("x", "y"):
        raise InputError(f"--axis {axis!r}; give x or y")
    process = _milling(config)
    diameter = _diameter(config, diameter_mm)
    if diameter is None:
        raise InputError("give --diameter-mm: the cutting speed of Eq. 3 needs the diameter")
    if not cuts["ap_mm"]:
        raise InputError("cuts: no rows; give at least one cut (ap_mm, spindle_rpm, ...)")
    cutter = _end_mill(process.teeth, diameter, helix_deg, max(cuts["ap_mm"]))
    kte, kre = _edges(config, kte_n_mm, kre_n_mm)
    setup = CalibrationSetup(
        config.tool_dynamics(),
        process,
        cutter,
        kte,
        kre,
        helical_edge,
        check_number("--seconds", seconds, 0.0, math.inf, low_open=True, unit="s"),
        steps,
        "x" if axis == "x" else "y",
    )
    started = time.perf_counter()
    rows = []
    for ap, rpm, fz, vib in zip(*(cuts[name] for name in CUT_COLUMNS), strict=True):
        speed = rpm * _RPM
        found = calibrate_cpd(
            setup,
            spindle_rad_s=speed,
            depth_m=ap * 1e-3,
            feed_per_tooth_m=fz * 1e-3,
            measured_rms_m_s2=vib * _G,
        )
        gamma = found.cpd_pa * ap * fz * 1e-6  # Eq. 15, N
        rows.append(
            {
                "ap_mm": ap,
                "spindle_rpm": rpm,
                "fz_mm": fz,
                "vibration_g": vib,
                "simulated_g": found.simulated_rms / _G,
                "relative_error": found.relative_error,
                "cpd_n_m2": found.cpd_pa,
                "gamma_n": gamma,
                "effective_damping_n_s_m": gamma / (speed * cutter.radius_m),
                "status": found.status,
                "runs": found.evaluations,
            }
        )
    fits, unfitted = [], []
    for rpm in sorted({row["spindle_rpm"] for row in rows}):
        group = [r for r in rows if r["spindle_rpm"] == rpm and r["status"] == "matched"]
        if len({r["ap_mm"] for r in group}) < 3:
            unfitted.append(rpm)
            continue
        model = fit_process_damping_model(
            [r["spindle_rpm"] * _RPM for r in group],
            [r["ap_mm"] * 1e-3 for r in group],
            [r["fz_mm"] * 1e-3 for r in group],
            [r["cpd_n_m2"] for r in group],
        )
        fit = model.fits[0]
        fits.append(
            {
                "spindle_rpm": rpm,
                "a_n": fit.asymptote_n,
                "b_n": fit.amplitude_n,
                "a0_mm": fit.depth_scale_m * 1e3,
                "mape_percent": fit.mape_percent,
                "rmse_n_m2": fit.rmse_pa,
            }
        )
    return {
        "cuts": rows,
        "fits": fits,
        "unfitted_rpm": unfitted,
        "axis": axis,
        "wall_s": time.perf_counter() - started,
    }


@app.command("calibrate-damping")
def calibrate_damping(
    cuts: Annotated[
        Path,
        typer.Argument(help="CSV with columns ap_mm, spindle_rpm, fz_mm, vibration_g."),
    ],
    config: ConfigOption,
    diameter_mm: DiameterOption = None,
    helix_deg: HelixOption = 0.0,
    kte_n_mm: KteOption = None,
    kre_n_mm: KreOption = None,
    helical_edge: HelicalEdgeOption = False,
    axis: Annotated[
        str, typer.Option("--axis", help="Direction of the measured RMS: x (feed) or y.")
    ] = "x",
    seconds: Annotated[
        float, typer.Option("--seconds", help="Simulated time per run, s (default 0.2).")
    ] = 0.2,
    steps: StepsOption = None,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write Gamma over depth per speed to this PNG.")
    ] = None,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object (read by --damping-model).")
    ] = False,
) -> None:
    """Process damping per measured cut (Royandi 2026, Eq. 14) and its Gamma model (Eq. 15-19)."""
    from cnctwin.dynamics import load_stability_config
    from cnctwin.measurements import read_columns

    check_time_options(seconds, None, kte_n_mm, kre_n_mm, steps, diameter_mm, helix_deg)
    settings = load_stability_config(config)
    columns = read_columns(cuts, list(CUT_COLUMNS))
    report = calibration_report(
        settings,
        columns,
        diameter_mm=diameter_mm,
        helix_deg=helix_deg,
        kte_n_mm=kte_n_mm,
        kre_n_mm=kre_n_mm,
        helical_edge=helical_edge,
        axis=axis,
        seconds=seconds,
        steps=steps,
    )
    report["source"] = str(cuts)
    if plot is not None:
        _plot_calibration(plot, report, cuts.stem)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    console = Console()
    console.print(_cuts_table(report))
    console.print(_fits_table(report))


app.command("detect")(detect)


def _pair(values: np.ndarray) -> list[float]:
    return [float(values[0]), float(values[1])]


def _simulation_table(report: dict[str, Any]) -> Table:
    table = Table(
        title=f"milling simulation: {report['spindle_rpm']:g} rpm, "
        f"a_p {report['depth_mm']:g} mm, f_z {report['feed_per_tooth_mm']:g} mm",
        show_header=False,
        title_justify="left",
        caption=f"{report['simulated_s']:.3g} s simulated ({report['steps_per_tooth']} steps "
        f"per tooth period, {report['slices']} slices) in {report['wall_s']:.2f} s; RMS after "
        f"{report['transient_s']:.3g} s",
        caption_justify="left",
    )
    table.add_column("quantity", style="bold")
    table.add_column("x", justify="right")
    table.add_column("y", justify="right")
    rms = report["rms"]
    for label, key, unit in (
        ("displacement RMS", "displacement_um", "um"),
        ("velocity RMS", "velocity_mm_s", "mm/s"),
        ("acceleration RMS", "acceleration_g", "g"),
        ("cutting force RMS", "force_n", "N"),
    ):
        table.add_row(label, *(f"{v:.4g} {unit}" for v in rms[key]))
    table.add_row("mean cutting force", *(f"{v:.4g} N" for v in report["mean_force_n"]))
    table.add_row("peak-to-peak displacement", *(f"{v:.4g} um" for v in report["peak_to_peak_um"]))
    if report["chatter"]:
        verdict = f"CHATTER at {report['chatter_frequency_hz']:.1f} Hz"
    else:
        verdict = "stable"
    table.add_row(
        "time domain", verdict, f"{100 * report['nonsynchronous_ratio']:.3g} % off harmonics"
    )
    sdm = "stable" if report["sdm_stable"] else "unstable"
    table.add_row("semi-discretization", sdm, f"|mu| = {report['sdm_spectral_radius']:.4f}")
    if report["cpd_n_m2"] is not None:
        table.add_row(
            "process damping",
            f"C_pd {report['cpd_n_m2']:.3g} N/m^2",
            f"C_eff {report['process_damping_n_s_m']:.4g} N s/m",
        )
    return table


def _cuts_table(report: dict[str, Any]) -> Table:
    table = Table(title="process damping per cut (Royandi 2026, Eq. 14)", title_justify="left")
    for name in ("ap mm", "rpm", "fz mm", "measured g", "model g", "C_pd N/m^2", "C_eff N s/m"):
        table.add_column(name, justify="right")
    table.add_column("status")
    for row in report["cuts"]:
        table.add_row(
            f"{row['ap_mm']:g}",
            f"{row['spindle_rpm']:g}",
            f"{row['fz_mm']:g}",
            f"{row['vibration_g']:.4g}",
            f"{row['simulated_g']:.4g}",
            f"{row['cpd_n_m2']:.3g}",
            f"{row['effective_damping_n_s_m']:.4g}",
            row["status"],
        )
    return table


def _fits_table(report: dict[str, Any]) -> Table:
    table = Table(
        title="Gamma = A + B exp(-a_p / a0) per speed (Eq. 15-19, decaying form)",
        title_justify="left",
        caption=(
            f"no fit (fewer than 3 matched depths) at {report['unfitted_rpm']} rpm"
            if report["unfitted_rpm"]
            else None
        ),
        caption_justify="left",
    )
    for name in ("rpm", "A N", "B N", "a0 mm", "MAPE %"):
        table.add_column(name, justify="right")
    for fit in report["fits"]:
        table.add_row(
            f"{fit['spindle_rpm']:g}",
            f"{fit['a_n']:.4g}",
            f"{fit['b_n']:.4g}",
            f"{fit['a0_mm']:.3g}",
            f"{fit['mape_percent']:.2f}",
        )
    return table


def _plot_simulation(
    path: Path, result: MillingVibration, report: dict[str, Any], title: str
) -> None:
    """Displacement over time, force over the last tooth periods, acceleration spectrum."""
    from matplotlib.figure import Figure  # matplotlib only when asked for

    figure = Figure(figsize=(9.0, 9.0), dpi=100, layout="constrained")
    top, middle, bottom = figure.subplots(3, 1)
    t_ms = result.time_s * 1e3
    for axis, name in ((0, "x"), (1, "y")):
        top.plot(t_ms, result.displacement_m[:, axis] * 1e6, linewidth=0.6, label=name)
    top.axvspan(0.0, report["transient_s"] * 1e3, color="tab:gray", alpha=0.15, label="transient")
    top.set_xlabel("time [ms]")
    top.set_ylabel("tool-tip displacement [um]")
    top.legend(loc="upper right", fontsize="small")
    verdict = "chatter" if report["chatter"] else "stable"
    top.set_title(
        f"{title}: {report['spindle_rpm']:g} rpm, a_p {report['depth_mm']:g} mm ({verdict})"
    )
    last = slice(max(0, t_ms.size - 5 * result.steps_per_tooth), t_ms.size)
    for axis, name in ((0, "Fx"), (1, "Fy")):
        middle.plot(t_ms[last], result.force_n[last, axis], linewidth=0.8, label=name)
    middle.set_xlabel("time [ms]")
    middle.set_ylabel("cutting force on the tool [N]")
    middle.legend(loc="upper right", fontsize="small")
    top_hz = 10.0 * result.tooth_passing_hz
    for spectrum, name in (
        (result.spectrum("acceleration", "x", report["transient_s"]), "x"),
        (result.spectrum("acceleration", "y", report["transient_s"]), "y"),
    ):
        shown = (spectrum.frequency_hz <= top_hz) & (spectrum.amplitude > 0.0)
        if shown.any():  # an axis without a mode does not move
            amplitude = spectrum.amplitude[shown] / _G
            bottom.semilogy(spectrum.frequency_hz[shown], amplitude, linewidth=0.6, label=name)
    for k in range(1, 11):
        bottom.axvline(k * result.tooth_passing_hz, color="tab:gray", linewidth=0.4, alpha=0.5)
    if report["chatter_frequency_hz"] is not None:
        bottom.axvline(report["chatter_frequency_hz"], color="tab:red", linestyle="--",
                       linewidth=0.8, label="chatter")  # fmt: skip
    bottom.set_xlim(0.0, top_hz)
    bottom.set_xlabel("frequency [Hz] (grey: tooth-passing harmonics)")
    bottom.set_ylabel("acceleration amplitude [g]")
    bottom.legend(loc="upper right", fontsize="small")
    figure.savefig(path)


def _plot_calibration(path: Path, report: dict[str, Any], title: str) -> None:
    """Gamma over depth per speed: calibrated cuts and the fitted curves (Fig. 12's layout)."""
    from matplotlib.figure import Figure  # matplotlib only when asked for

    figure = Figure(figsize=(8.0, 5.0), dpi=100, layout="constrained")
    axes = figure.subplots()
    speeds = sorted({row["spindle_rpm"] for row in report["cuts"]})
    fits = {fit["spindle_rpm"]: fit for fit in report["fits"]}
    for index, rpm in enumerate(speeds):
        color = f"C{index}"
        rows = [r for r in report["cuts"] if r["spindle_rpm"] == rpm and r["cpd_n_m2"] > 0]
        axes.plot([r["ap_mm"] for r in rows], [r["gamma_n"] for r in rows], "o", color=color,
                  label=f"{rpm:g} rpm")  # fmt: skip
        if rpm in fits:
            fit = fits[rpm]
            depth = np.linspace(min(r["ap_mm"] for r in rows), max(r["ap_mm"] for r in rows), 100)
            gamma = fit["a_n"] + fit["b_n"] * np.exp(-depth / fit["a0_mm"])
            axes.plot(depth, gamma, color=color, linewidth=1.0)
    axes.set_xlabel("axial depth of cut a_p [mm]")
    axes.set_ylabel("Gamma = C_pd a_p f_z [N]")
    axes.set_title(f"{title}: normalised process damping (Royandi 2026, Eq. 15-19)")
    axes.grid(alpha=0.3)
    axes.legend(fontsize="small")
    figure.savefig(path)
