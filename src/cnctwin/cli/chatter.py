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
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import JsonOutput, check_count, check_number
from cnctwin.cli.chatter_detect import detect
from cnctwin.config import MAX_SPINDLE_RPM, MAX_TOOL_DIAMETER_MM
from cnctwin.errors import InputError

if TYPE_CHECKING:
    from cnctwin.dynamics import MillingVibration, ProcessDampingModel, StabilityConfig

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


@app.callback()
def _chatter() -> None:
    """Time-domain milling vibration and chatter; process-damping calibration."""


def _check_helix(helix_deg: float) -> None:
    """The helix angle option, degrees: 0 <= helix < 90."""
    if not (math.isfinite(helix_deg) and 0.0 <= helix_deg < 90.0):
        raise InputError(f"--helix-deg {helix_deg!r}; give 0 <= helix < 90 degrees")


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
    _check_helix(helix_deg)
    check_number("--seconds", seconds, MIN_SIMULATED_S, MAX_SIMULATED_S, unit="s")
    if transient_s is not None:
        check_number("--transient-s", transient_s, 0.0, MAX_SIMULATED_S, unit="s")
    for option, value in (("--kte-n-mm", kte_n_mm), ("--kre-n-mm", kre_n_mm)):
        if value is not None:
            check_number(option, value, -MAX_EDGE_N_MM, MAX_EDGE_N_MM, unit="N/mm")
    if steps is not None:
        check_count("--steps", steps, MIN_STEPS_PER_TOOTH, MAX_STEPS_PER_TOOTH)


def _diameter_given(config: StabilityConfig, diameter_mm: float | None) -> bool:
    """Whether a cutter diameter is known: --diameter-mm or ``[process_damping]``."""
    return diameter_mm is not None or config.process_damping is not None


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
    max_seconds: float | None = None,
) -> tuple[dict[str, Any], MillingVibration]:
    """Check the options of one cut, run it (:func:`cnctwin.dynamics.run_milling`) and
    summarise it.

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
    max_seconds
        Longest simulated time while the verdict is undecided, s (default 4 x ``seconds``).

    Returns
    -------
    tuple
        The ``--json`` object and the simulation. JSON keys: ``spindle_rpm``, ``depth_mm``,
        ``feed_per_tooth_mm``, ``simulated_s``, ``transient_s``, ``steps_per_tooth``,
        ``slices``, ``tooth_passing_hz``, ``cpd_n_m2`` (null without process damping),
        ``process_damping_n_s_m``, ``rms`` (``displacement_um``, ``velocity_mm_s``,
        ``acceleration_m_s2``, ``acceleration_g``, ``force_n``: [x, y] each),
        ``mean_force_n`` and ``peak_to_peak_um`` ([x, y]), ``chatter``, ``decision``
        (``stable``, ``chatter`` or ``undecided``), ``growth_rate_per_s`` and its standard
        error ``growth_rate_sigma_per_s``, ``nonsynchronous_ratio``, ``growth``,
        ``chatter_frequency_hz``,
        ``sdm_spectral_radius``, ``sdm_stable`` and ``wall_s``.
    """
    from cnctwin.dynamics import run_milling

    speed = check_number("--rpm", rpm, 1.0, MAX_SPINDLE_RPM, low_open=True, unit="rpm") * _RPM
    depth = check_number("--depth-mm", depth_mm, 0.0, 1000.0, low_open=True, unit="mm") * 1e-3
    if feed_mm is None and config.process_damping is None:
        raise InputError("give --feed-mm (feed per tooth, mm)")
    if feed_mm is not None:
        check_number("--feed-mm", feed_mm, 0.0, 100.0, low_open=True, unit="mm")
    check_number("--seconds", seconds, 0.0, math.inf, low_open=True, unit="s")
    if diameter_mm is not None:
        check_number(
            "--diameter-mm", diameter_mm, 0.0, MAX_TOOL_DIAMETER_MM, low_open=True, unit="mm"
        )
    _check_helix(helix_deg)
    if helix_deg != 0.0 and not _diameter_given(config, diameter_mm):
        raise InputError("--helix-deg needs the cutter diameter: give --diameter-mm")
    if cpd_n_m2 is not None:
        check_number("--cpd-n-m2", cpd_n_m2, 0.0, math.inf, unit="N/m^2")
    if cpd_n_m2 is not None and damping_model is not None:
        raise InputError("--cpd-n-m2 and --damping-model exclude each other; give one")
    try:
        run = run_milling(
            config,
            spindle_rad_s=speed,
            depth_m=depth,
            feed_per_tooth_m=None if feed_mm is None else feed_mm * 1e-3,
            duration_s=seconds,
            transient_s=transient_s,
            diameter_mm=diameter_mm,
            helix_rad=math.radians(helix_deg),
            edge_tangential_n_m=None if kte_n_mm is None else kte_n_mm * 1e3,
            edge_radial_n_m=None if kre_n_mm is None else kre_n_mm * 1e3,
            helical_edge=helical_edge,
            cpd_pa=cpd_n_m2,
            damping_model=damping_model,
            steps_per_tooth=steps,
            max_duration_s=max_seconds,
        )
    except InputError as err:
        # Without a diameter, process damping (C_pd > 0) is the refusal the checks above leave.
        if not _diameter_given(config, diameter_mm) and (cpd_n_m2 or damping_model is not None):
            raise InputError(f"{err}; give --diameter-mm") from None
        raise
    result, rms, verdict = run.vibration, run.rms, run.verdict
    report = {
        "spindle_rpm": rpm,
        "depth_mm": depth_mm,
        "feed_per_tooth_mm": run.feed_per_tooth_m * 1e3,
        "simulated_s": run.simulated_s,
        "transient_s": run.transient_s,
        "steps_per_tooth": result.steps_per_tooth,
        "slices": result.slices,
        "tooth_passing_hz": result.tooth_passing_hz,
        "cpd_n_m2": run.cpd_pa,
        "process_damping_n_s_m": result.process_damping_n_s_m,
        "rms": {
            "displacement_um": _pair(rms.displacement_m * 1e6),
            "velocity_mm_s": _pair(rms.velocity_m_s * 1e3),
            "acceleration_m_s2": _pair(rms.acceleration_m_s2),
            "acceleration_g": _pair(rms.acceleration_g),
            "force_n": _pair(rms.force_n),
        },
        "mean_force_n": _pair(run.mean_force_n),
        "peak_to_peak_um": _pair(run.peak_to_peak_m * 1e6),
        "chatter": verdict.chatter,
        "decision": verdict.decision,
        "growth_rate_per_s": finite_json.finite(float(verdict.growth_rate_per_s)),
        "growth_rate_sigma_per_s": finite_json.finite(float(verdict.growth_rate_sigma_per_s)),
        "nonsynchronous_ratio": verdict.nonsynchronous_ratio,
        "growth": finite_json.finite(float(verdict.growth)),
        "chatter_frequency_hz": (
            finite_json.finite(float(verdict.frequency_hz)) if verdict.chatter else None
        ),
        "sdm_spectral_radius": run.sdm_spectral_radius,
        "sdm_stable": run.sdm_stable,
        "wall_s": run.wall_s,
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
    max_seconds: Annotated[
        float | None,
        typer.Option(
            "--max-seconds",
            help="While undecided, simulate twice as long up to this, s (default 4x --seconds).",
        ),
    ] = None,
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
    as_json: JsonOutput = False,
) -> None:
    """Simulate one milling cut in time: vibration RMS, chatter, and the SDM's verdict."""
    from cnctwin.dynamics import load_stability_config, read_damping_model

    check_time_options(seconds, transient_s, kte_n_mm, kre_n_mm, steps, diameter_mm, helix_deg)
    if max_seconds is not None:
        check_number("--max-seconds", max_seconds, MIN_SIMULATED_S, MAX_SIMULATED_S, unit="s")
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
        max_seconds=max_seconds,
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
    """Check the options, calibrate C_pd per cut and fit Gamma per speed
    (:func:`cnctwin.dynamics.calibrate_damping_cuts`; Royandi 2026, Eq. 14-19) and tabulate.

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
    from cnctwin.dynamics import calibrate_damping_cuts

    if axis not in ("x", "y"):
        raise InputError(f"--axis {axis!r}; give x or y")
    if diameter_mm is not None:
        check_number(
            "--diameter-mm", diameter_mm, 0.0, MAX_TOOL_DIAMETER_MM, low_open=True, unit="mm"
        )
    elif config.process_damping is None:
        raise InputError("give --diameter-mm: the cutting speed of Eq. 3 needs the diameter")
    _check_helix(helix_deg)
    if not cuts["ap_mm"]:
        raise InputError("cuts: no rows; give at least one cut (ap_mm, spindle_rpm, ...)")
    check_number("--seconds", seconds, 0.0, math.inf, low_open=True, unit="s")
    rpms = cuts["spindle_rpm"]
    speeds = [rpm * _RPM for rpm in rpms]
    calibration = calibrate_damping_cuts(
        config,
        depth_mm=cuts["ap_mm"],
        spindle_rad_s=speeds,
        feed_per_tooth_mm=cuts["fz_mm"],
        measured_rms_m_s2=[vib * _G for vib in cuts["vibration_g"]],
        diameter_mm=diameter_mm,
        helix_rad=math.radians(helix_deg),
        edge_tangential_n_m=None if kte_n_mm is None else kte_n_mm * 1e3,
        edge_radial_n_m=None if kre_n_mm is None else kre_n_mm * 1e3,
        helical_edge=helical_edge,
        axis="x" if axis == "x" else "y",
        duration_s=seconds,
        steps_per_tooth=steps,
    )
    rpm_of = dict(zip(speeds, rpms, strict=True))
    rows = [
        {
            "ap_mm": ap,
            "spindle_rpm": rpm,
            "fz_mm": fz,
            "vibration_g": vib,
            "simulated_g": cut.simulated_rms_m_s2 / _G,
            "relative_error": cut.relative_error,
            "cpd_n_m2": cut.cpd_pa,
            "gamma_n": cut.gamma_n,
            "effective_damping_n_s_m": cut.effective_damping_n_s_m,
            "status": cut.status,
            "runs": cut.evaluations,
        }
        for cut, ap, rpm, fz, vib in zip(
            calibration.cuts, *(cuts[name] for name in CUT_COLUMNS), strict=True
        )
    ]
    fits = [
        {
            "spindle_rpm": rpm_of[fit.spindle_rad_s],
            "a_n": fit.asymptote_n,
            "b_n": fit.amplitude_n,
            "a0_mm": fit.depth_scale_m * 1e3,
            "mape_percent": fit.mape_percent,
            "rmse_n_m2": fit.rmse_pa,
        }
        for fit in calibration.fits
    ]
    return {
        "cuts": rows,
        "fits": fits,
        "unfitted_rpm": [rpm_of[speed] for speed in calibration.unfitted_rad_s],
        "axis": axis,
        "wall_s": calibration.wall_s,
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
        verdict = report["decision"]
    rate, sigma = report["growth_rate_per_s"], report["growth_rate_sigma_per_s"]
    growth = "" if rate is None or sigma is None else f"; grows {rate:.3g} +- {2 * sigma:.2g} 1/s"
    table.add_row(
        "time domain",
        verdict,
        f"{100 * report['nonsynchronous_ratio']:.3g} % off harmonics{growth}",
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
