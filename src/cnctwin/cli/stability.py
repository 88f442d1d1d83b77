"""``cnctwin stability``: chatter stability; ``stability lobes``: the lobe diagram of a cut;
``stability roadmap``: stable spindle speeds along a program (:mod:`cnctwin.cli.roadmap`).

The tool-tip modes and the cut come from a stability file (``--config``, docs/stability.md) or
from a modes file (``--modes-file``) completed by options; options override the file. The
spindle speeds: the file's ``[lobes]`` range, ``--rpm LIST`` (comma-separated speeds),
``--rpm-range MIN:MAX:N`` or the older ``--rpm LOW HIGH`` (with ``--points``). The physics
(:mod:`cnctwin.dynamics.stability`) works in SI; this edge speaks rpm, mm and Hz.
"""

from __future__ import annotations

import logging
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, TextIO

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import check_number
from cnctwin.errors import InputError
from cnctwin.report import check_report_path

if TYPE_CHECKING:
    from cnctwin.dynamics import SdmCost

__all__ = ["ProgressLine", "app", "lobes", "lobes_report", "parse_rpm_list", "parse_rpm_range"]

logger = logging.getLogger(__name__)

app = typer.Typer(help="Chatter stability of milling and turning.", no_args_is_help=True)

_RPM = math.pi / 30.0  # rad/s per rpm


class ProgressLine:
    """The estimated cost before a long run and its progress, one line at a time on stderr.

    Never on stdout, so that ``--json`` stays one JSON object. A progress line is written at
    most every ``interval_s`` seconds of ``clock`` (and at the end, if any was written).
    """

    def __init__(
        self,
        label: str,
        *,
        interval_s: float = 2.0,
        stream: TextIO | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.label = label
        self.interval_s = interval_s
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        self.started = clock()
        self.last = self.started
        self.written = False

    def estimate(self, cost: SdmCost, what: str = "speeds") -> None:
        """Write the estimated cost: speeds x depth evaluations x the measured time of one."""
        self.stream.write(
            f"{self.label}: estimated cost {cost.speeds} {what} x ~{cost.evaluations_per_speed:.3g}"
            f" depth evaluations x {cost.seconds_per_evaluation * 1e3:.3g} ms = "
            f"~{_duration(cost.seconds)}\n"
        )
        self.stream.flush()
        self.started = self.last = self.clock()

    def __call__(self, done: int, total: int) -> None:
        """Note ``done`` of ``total`` units; write a line when due."""
        now = self.clock()
        final = done >= total
        if not (now - self.last >= self.interval_s or (final and self.written)):
            return
        elapsed = now - self.started
        left = elapsed * (total - done) / done if done else math.nan
        rest = "" if final or not math.isfinite(left) else f", ~{_duration(left)} left"
        self.stream.write(f"{self.label}: {done}/{total} done, {_duration(elapsed)}{rest}\n")
        self.stream.flush()
        self.last = now
        self.written = True


def _duration(seconds: float) -> str:
    return f"{seconds:.1f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


@app.callback()
def _stability() -> None:
    """Chatter stability of milling and turning."""


def parse_rpm_list(text: str, option: str = "--rpm") -> np.ndarray:
    """Spindle speeds from ``"8000,9000,10500"`` (rpm, each > 0 and <= 200,000).

    Raises
    ------
    InputError
        Naming the option and the text, for an empty list, more than 100,000 speeds or a
        value out of range.
    """
    from cnctwin.config import MAX_SPINDLE_RPM
    from cnctwin.dynamics import MAX_POINTS

    try:
        values = np.array([float(v) for v in text.split(",") if v.strip()])
    except ValueError:
        values = np.array([math.nan])
    if not (0 < values.size <= MAX_POINTS and np.all((values > 0.0) & (values <= MAX_SPINDLE_RPM))):
        raise InputError(
            f"{option} {text!r}; give up to {MAX_POINTS} spindle speeds in rpm separated by "
            f"commas, each > 0 and <= {MAX_SPINDLE_RPM:g}"
        )
    return values


def parse_rpm_range(text: str, option: str = "--rpm-range") -> np.ndarray:
    """``N`` spindle speeds evenly spaced from ``MIN`` to ``MAX`` rpm, from ``"MIN:MAX:N"``.

    Raises
    ------
    InputError
        Naming the option and the text, unless ``0 < MIN < MAX <= 200,000`` and
        ``2 <= N <= 100,000``.
    """
    from cnctwin.config import MAX_SPINDLE_RPM
    from cnctwin.dynamics import MAX_POINTS

    parts = text.split(":")
    try:
        low, high, count = float(parts[0]), float(parts[1]), int(parts[2])
        valid = len(parts) == 3 and 0.0 < low < high <= MAX_SPINDLE_RPM and 2 <= count <= MAX_POINTS
    except (ValueError, IndexError):
        valid = False
    if not valid:
        raise InputError(
            f"{option} {text!r}; give MIN:MAX:N with 0 < MIN < MAX <= {MAX_SPINDLE_RPM:g} rpm "
            f"and 2 <= N <= {MAX_POINTS}, e.g. 5000:25000:400"
        )
    return np.linspace(low, high, count)


def lobes_report(
    config: Any, rpm: np.ndarray | None = None, progress: ProgressLine | None = None
) -> dict[str, Any]:
    """Compute the lobe diagram a stability configuration asks for.

    Parameters
    ----------
    config
        A :class:`cnctwin.dynamics.config.StabilityConfig`.
    rpm
        Spindle speeds in rpm; default the ``[lobes]`` range and number of points.
    progress
        For the semi-discretization: told the estimated cost first, then the speeds done.

    Returns
    -------
    dict
        The ``--json`` object: ``method``, ``operation``, ``spindle_rpm``,
        ``critical_depth_mm`` (null where no instability was found up to ``max_depth_mm``),
        ``chatter_frequency_hz`` (null there), ``bifurcation`` (``hopf``, ``flip``, ``fold``
        or ``none``) as equal-length lists, then ``min_critical_depth_mm`` and its
        ``min_critical_rpm`` and ``min_chatter_frequency_hz``, the zero-order approximation's
        ``absolute_depth_mm`` (the lowest limit over all speeds) and its
        ``absolute_chatter_frequency_hz``, ``max_depth_mm``, ``steps`` (sdm), ``seconds``.
    """
    from cnctwin.dynamics import sdm_cost, sdm_lobes, zoa_absolute_depth, zoa_lobes

    tool = config.tool_dynamics()
    process = config.process()
    damping = config.process_damping_model()
    spec = config.lobes
    if rpm is None:
        rpm = np.linspace(spec.rpm[0], spec.rpm[1], spec.points)
    config.check_work(float(rpm.min()))
    started = time.perf_counter()
    if spec.method == "zoa":
        if damping is not None:
            raise InputError("process damping needs --method sdm (the ZOA has no depth term)")
        result = zoa_lobes(tool, process, rpm * _RPM)
    else:
        steps = None if spec.steps == "auto" else spec.steps
        kwargs: dict[str, Any] = {
            "max_depth_m": spec.max_depth_mm * 1e-3, "steps": steps, "damping": damping
        }  # fmt: skip
        if progress is not None:
            progress.estimate(sdm_cost(tool, process, rpm * _RPM, **kwargs))
            started = time.perf_counter()
        result = sdm_lobes(tool, process, rpm * _RPM, progress=progress, **kwargs)
    seconds = time.perf_counter() - started
    absolute_m, absolute_hz = zoa_absolute_depth(tool, process)
    depth_mm = result.critical_depth_m * 1e3
    finite = np.isfinite(depth_mm)
    best = int(np.argmin(np.where(finite, depth_mm, np.inf))) if finite.any() else None
    return {
        "method": spec.method,
        "operation": config.cut.operation,
        "spindle_rpm": [float(v) for v in rpm],
        "critical_depth_mm": finite_json.finite(depth_mm.tolist()),
        "chatter_frequency_hz": finite_json.finite(result.chatter_frequency_hz.tolist()),
        "bifurcation": list(result.bifurcation),
        "min_critical_depth_mm": None if best is None else float(depth_mm[best]),
        "min_critical_rpm": None if best is None else float(rpm[best]),
        "min_chatter_frequency_hz": (
            None if best is None else float(result.chatter_frequency_hz[best])
        ),
        "absolute_depth_mm": finite_json.finite(float(absolute_m * 1e3)),
        "absolute_chatter_frequency_hz": finite_json.finite(float(absolute_hz)),
        "max_depth_mm": spec.max_depth_mm if spec.method == "sdm" else None,
        "steps": spec.steps if spec.method == "sdm" else None,
        "process_damping": damping is not None,
        "seconds": seconds,
    }


def lobes(
    config: Annotated[
        Path | None,
        typer.Option("--config", help="Stability file: modes, cut, lobes (docs/stability.md)."),
    ] = None,
    modes_file: Annotated[
        Path | None,
        typer.Option("--modes-file", help="Modes file (the modes alone); the cut from options."),
    ] = None,
    immersion: Annotated[
        float | None,
        typer.Option("--immersion", help="Radial immersion ae/D, 0.001 <= ae/D <= 1 (1: slot)."),
    ] = None,
    down: Annotated[
        bool | None,
        typer.Option("--down/--up", help="Down- (climb) or up- (conventional) milling."),
    ] = None,
    method: Annotated[
        str | None,
        typer.Option(
            "--method", help="zoa (zero-order approximation) or sdm (semi-discretization)."
        ),
    ] = None,
    rpm: Annotated[
        str | None,
        typer.Option(
            "--rpm",
            help="Spindle speeds in rpm, comma-separated (8000,9000); LOW HIGH: a range.",
        ),
    ] = None,
    rpm_range: Annotated[
        str | None,
        typer.Option("--rpm-range", help="MIN:MAX:N: N speeds from MIN to MAX rpm."),
    ] = None,
    points: Annotated[
        int | None, typer.Option("--points", help="Number of spindle speeds (default 200).")
    ] = None,
    max_depth_mm: Annotated[
        float | None,
        typer.Option("--max-depth-mm", help="sdm: highest depth searched in mm (default 10)."),
    ] = None,
    steps: Annotated[
        str | None,
        typer.Option("--steps", help="sdm: steps per period, or auto (the default)."),
    ] = None,
    teeth: Annotated[int | None, typer.Option("--teeth", help="Number of teeth.")] = None,
    material: Annotated[
        str | None,
        typer.Option("--material", help="Milling entry of the materials library."),
    ] = None,
    ktc: Annotated[
        float | None, typer.Option("--ktc", help="Tangential coefficient in N/mm^2.")
    ] = None,
    krc: Annotated[
        float | None, typer.Option("--krc", help="Radial coefficient in N/mm^2.")
    ] = None,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write the lobe diagram to this PNG file.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    html: Annotated[
        Path | None,
        typer.Option("--report", help="Write a self-contained HTML report (interactive plot)."),
    ] = None,
    high_rpm: Annotated[
        list[str] | None, typer.Argument(hidden=True, help="HIGH of --rpm LOW HIGH.")
    ] = None,
) -> None:
    """Stability lobes: the critical depth of cut and chatter frequency per spindle speed.

    Modes and cut from --config FILE, or modes from --modes-file FILE and the cut from options.

    Speeds: the file's [lobes] range, --rpm 8000,9000,10500, --rpm-range 5000:25000:400, or
    --rpm LOW HIGH with --points N.

    Milling cut options: --teeth, --material NAME (or --ktc and --krc), --immersion, --down/--up.
    """
    from cnctwin.dynamics import load_stability_config

    path = config if config is not None else modes_file
    if path is None or (config is not None and modes_file is not None):
        raise InputError("give either --config FILE or --modes-file FILE")
    if html is not None:
        check_report_path(html)
    span, speeds = _speeds(rpm, rpm_range, points, high_rpm or [])
    overrides = _overrides(
        immersion=immersion,
        down=down,
        method=method,
        rpm=span,
        points=points,
        max_depth_mm=max_depth_mm,
        steps=steps,
        teeth=teeth,
        material=material,
        ktc=ktc,
        krc=krc,
    )
    settings = load_stability_config(path, overrides, modes_only=modes_file is not None)
    report = lobes_report(settings, speeds, ProgressLine("stability lobes"))
    if plot is not None:
        _plot(plot, report, path.stem)
    if html is not None:
        from cnctwin.report import lobes_report as write_lobes_report

        write_lobes_report(html, report, path.stem)
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    Console().print(_table(report))


app.command("lobes")(lobes)


def _speeds(
    rpm: str | None, rpm_range: str | None, points: int | None, extra: list[str]
) -> tuple[tuple[float, float] | None, np.ndarray | None]:
    """The speed options as a ``[lobes]`` range (the ``--rpm LOW HIGH`` form) or speeds."""
    if extra:
        # --rpm LOW HIGH: click hands HIGH over as a stray argument.
        if rpm is None or len(extra) != 1 or "," in rpm:
            raise InputError(f"unexpected argument {' '.join(extra)!r}; see --help")
        try:
            low, high = float(rpm), float(extra[0])
        except ValueError:
            raise InputError(f"--rpm {rpm} {extra[0]}; give LOW HIGH in rpm") from None
        return (low, high), None
    if rpm is not None and rpm_range is not None:
        raise InputError("--rpm and --rpm-range exclude each other; give one")
    if points is not None and (rpm is not None or rpm_range is not None):
        raise InputError("--points goes with the file's range or --rpm LOW HIGH; "
                          "give N in --rpm-range MIN:MAX:N instead")  # fmt: skip
    if rpm is not None:
        return None, parse_rpm_list(rpm)
    if rpm_range is not None:
        return None, parse_rpm_range(rpm_range)
    return None, None


def _overrides(**given: Any) -> dict[str, dict[str, Any]]:
    """The options as replacements of the file's tables; option values checked here."""
    from cnctwin.dynamics import MIN_IMMERSION

    cut: dict[str, Any] = {}
    spec: dict[str, Any] = {}
    if given["immersion"] is not None:
        value = given["immersion"]
        if not (math.isfinite(value) and MIN_IMMERSION <= value <= 1.0):
            raise InputError(f"--immersion {value!r}; give {MIN_IMMERSION:g} <= ae/D <= 1")
        cut["radial_immersion"] = value
    if given["down"] is not None:
        cut["milling"] = "down" if given["down"] else "up"
    if given["teeth"] is not None:
        if given["teeth"] < 1:
            raise InputError(f"--teeth {given['teeth']!r}; give an integer >= 1")
        cut["teeth"] = given["teeth"]
    material, ktc, krc = given["material"], given["ktc"], given["krc"]
    if material is not None and (ktc is not None or krc is not None):
        raise InputError("--material and --ktc/--krc exclude each other; give one")
    if material is not None:
        cut.update(material=material, ktc_n_mm2=None, krc_n_mm2=None)
    if ktc is not None or krc is not None:
        if ktc is None or krc is None:
            raise InputError("give both --ktc and --krc (N/mm^2)")
        check_number("--ktc", ktc, 0.0, math.inf, low_open=True, unit="N/mm^2")
        cut.update(material=None, ktc_n_mm2=ktc, krc_n_mm2=krc)
    if given["method"] is not None:
        if given["method"] not in ("zoa", "sdm"):
            raise InputError(f"--method {given['method']!r}; give zoa or sdm")
        spec["method"] = given["method"]
    if given["rpm"] is not None:
        low, high = given["rpm"]
        if not (math.isfinite(low) and math.isfinite(high) and 0.0 < low < high):
            raise InputError(f"--rpm {low!r} {high!r}; give LOW HIGH with 0 < LOW < HIGH")
        spec["rpm"] = [low, high]
    if given["points"] is not None:
        if given["points"] < 2:
            raise InputError(f"--points {given['points']!r}; give an integer >= 2")
        spec["points"] = given["points"]
    if given["max_depth_mm"] is not None:
        check_number(
            "--max-depth-mm", given["max_depth_mm"], 0.0, math.inf, low_open=True, unit="mm"
        )
        spec["max_depth_mm"] = given["max_depth_mm"]
    if given["steps"] is not None:
        spec["steps"] = _steps(given["steps"])
    return {key: value for key, value in (("cut", cut), ("lobes", spec)) if value}


def _steps(text: str) -> int | str:
    if text == "auto":
        return text
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 2:
        raise InputError(f"--steps {text!r}; give an integer >= 2 or auto")
    return value


def _pockets(report: dict[str, Any], count: int = 5) -> list[int]:
    """Indices of the highest local maxima of the critical depth (stable pockets)."""
    depth = np.array([np.inf if v is None else v for v in report["critical_depth_mm"]])
    padded = np.concatenate(([-np.inf], depth, [-np.inf]))
    peaks = np.flatnonzero((padded[1:-1] >= padded[:-2]) & (padded[1:-1] > padded[2:]))
    return sorted(peaks[np.argsort(-depth[peaks], kind="stable")][:count].tolist())


def _table(report: dict[str, Any]) -> Table:
    table = Table(
        title=f"stability lobes ({report['method']}, {report['operation']})",
        show_header=False,
        caption=f"{len(report['spindle_rpm'])} spindle speeds "
        f"{min(report['spindle_rpm']):.0f}-{max(report['spindle_rpm']):.0f} rpm "
        f"in {report['seconds']:.2f} s",
        caption_justify="left",
    )
    table.add_column("quantity", style="bold")
    table.add_column("value", justify="right")
    if report["min_critical_depth_mm"] is None:
        limit = report["max_depth_mm"]
        table.add_row("critical depth", f"none below {limit:g} mm" if limit else "none")
    else:
        table.add_row(
            "lowest critical depth",
            f"{report['min_critical_depth_mm']:.4g} mm at {report['min_critical_rpm']:.0f} rpm, "
            f"chatter {report['min_chatter_frequency_hz']:.1f} Hz",
        )
    if report["absolute_depth_mm"] is not None:
        table.add_row(
            "ZOA absolute limit",
            f"{report['absolute_depth_mm']:.4g} mm "
            f"(chatter {report['absolute_chatter_frequency_hz']:.1f} Hz)",
        )
    flips = sum(kind == "flip" for kind in report["bifurcation"])
    if flips:
        table.add_row("period-doubling (flip)", f"at {flips} of the speeds")
    for index in _pockets(report):
        depth = report["critical_depth_mm"][index]
        text = "stable to the search limit" if depth is None else f"{depth:.4g} mm"
        table.add_row(f"stable pocket {report['spindle_rpm'][index]:.0f} rpm", text)
    return table


def _plot(path: Path, report: dict[str, Any], title: str) -> None:
    """Critical depth over spindle speed; unstable above the curve, flip points marked."""
    from matplotlib.figure import Figure  # matplotlib only when asked for

    order = np.argsort(report["spindle_rpm"], kind="stable")
    rpm = np.array(report["spindle_rpm"])[order]
    depth = np.array([np.nan if v is None else v for v in report["critical_depth_mm"]])[order]
    top = report["max_depth_mm"] or (1.5 * np.nanmax(depth) if np.isfinite(depth).any() else 1)
    shown = np.where(np.isnan(depth), top, np.minimum(depth, top))
    figure = Figure(figsize=(9.0, 5.0), dpi=100, layout="constrained")
    axes = figure.subplots()
    axes.fill_between(rpm, shown, top, color="tab:red", alpha=0.15, linewidth=0, label="chatter")
    axes.plot(rpm, shown, color="black", linewidth=1.0, label="critical depth")
    flip = np.array([kind == "flip" for kind in report["bifurcation"]])[order]
    if flip.any():
        axes.plot(rpm[flip], shown[flip], ".", color="tab:blue", label="period doubling (flip)")
    if report["absolute_depth_mm"] is not None and report["absolute_depth_mm"] < top:
        axes.axhline(report["absolute_depth_mm"], color="tab:gray", linestyle="--",
                     linewidth=0.8, label="ZOA absolute limit")  # fmt: skip
    if rpm.size > 1:
        axes.set_xlim(rpm[0], rpm[-1])
    axes.set_ylim(0.0, top)
    axes.set_xlabel("spindle speed [rpm]")
    axes.set_ylabel("axial depth of cut [mm]")
    axes.set_title(f"{title}: stability lobes ({report['method']})")
    axes.grid(alpha=0.3)
    axes.legend(loc="upper left", fontsize="small")
    figure.savefig(path)
