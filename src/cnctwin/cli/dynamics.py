"""``cnctwin dynamics``: structural dynamics from tap tests. ``fit-frf`` fits modes to an FRF.

The tap-test files (FRF tables, impact records, ``.mat`` FRFs) are read by
:mod:`cnctwin.measurements.tap_test`, so that :mod:`cnctwin.dynamics` stays free of I/O.
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
from cnctwin.cli._options import check_number
from cnctwin.dynamics import FRF, FRFQuantity
from cnctwin.errors import DataError, InputError
from cnctwin.measurements import TapTestKind, load_tap_test

if TYPE_CHECKING:
    from cnctwin.dynamics import ModalFit

__all__ = ["app", "fit_frf", "fit_frf_report", "modes_file_text"]

app = typer.Typer(help="Structural dynamics: FRFs and modal fits from tap tests.",
                  no_args_is_help=True)  # fmt: skip

TWO_PI = 2.0 * math.pi
MAX_BAND_HZ = 1.0e6
"""Highest edge of the fitted band, Hz: above any structural mode and impact hammer."""
MAX_TAU_MS = 60_000.0
"""Longest exponential window time constant, ms: longer than any tap record."""


@app.callback()
def _dynamics() -> None:
    """Structural dynamics: FRFs and modal fits from tap tests."""


def fit_frf_report(
    path: Path,
    *,
    modes: int = 1,
    band_hz: tuple[float, float] | None = None,
    kind: TapTestKind = "auto",
    variable: str | None = None,
    quantity: FRFQuantity | None = None,
    tau_ms: float | None = None,
    plot: Path | None = None,
) -> dict[str, Any]:
    """Read a tap-test file, fit ``modes`` modes, return the JSON of ``cnctwin dynamics fit-frf``.

    Returns
    -------
    dict
        ``file``, ``kind``, ``variable``, ``quantity``, ``band_hz``, ``n_frequencies``,
        ``averages``, ``coherence_weighted``, ``window_tau_ms``, ``residual_norm``,
        ``upper_residual_m_n``, ``lower_residual_per_kg`` and ``modes``: per mode
        ``natural_frequency_hz``, ``damping_ratio``, ``stiffness_n_m``, ``mass_kg``,
        ``damping_n_s_m``, ``modal_constant_per_kg`` and ``residual_norm`` (over its
        half-power band).
    """
    from cnctwin.dynamics import default_band, fit_modes

    if tau_ms is not None:
        check_number("--tau-ms", tau_ms, 0.0, MAX_TAU_MS, low_open=True, unit="ms")
    if band_hz is not None:
        for value in band_hz:
            check_number("--band", value, 0.0, MAX_BAND_HZ, unit="Hz")
    test = load_tap_test(
        path, kind=kind, variable=variable, quantity=quantity,
        tau_s=None if tau_ms is None else tau_ms * 1e-3,
    )  # fmt: skip
    receptance = test.frf.to_receptance()
    if band_hz is None:
        try:
            low, high = default_band(receptance, test.excited_omega)
        except DataError as err:
            raise DataError(f"{path}: {err} with --band LO HI") from None
    else:
        low, high = (TWO_PI * value for value in band_hz)
        if not (0.0 <= low < high):
            raise InputError(f"--band {band_hz[0]:g} {band_hz[1]:g}: give 0 <= LO < HI, in Hz")
    fit = fit_modes(receptance, modes, omega_band=(low, high))
    if plot is not None:
        _plot(plot, receptance, fit, path.name)
    return {
        "file": str(path),
        "kind": test.kind,
        "variable": test.variable,
        "quantity": test.frf.quantity,
        "band_hz": [fit.omega_band[0] / TWO_PI, fit.omega_band[1] / TWO_PI],
        "n_frequencies": fit.n_frequencies,
        "averages": test.frf.averages,
        "coherence_weighted": fit.coherence_weighted,
        "window_tau_ms": tau_ms,
        "residual_norm": fit.residual_norm,
        "upper_residual_m_n": fit.upper_residual,
        "lower_residual_per_kg": fit.lower_residual,
        "modes": [
            {
                "natural_frequency_hz": mode.omega_n / TWO_PI,
                "damping_ratio": mode.zeta,
                "stiffness_n_m": mode.stiffness,
                "mass_kg": mode.mass,
                "damping_n_s_m": mode.damping,
                "modal_constant_per_kg": mode.residue,
                "residual_norm": norm,
            }
            for mode, norm in zip(fit.modes, fit.mode_residual_norms, strict=True)
        ],
    }


def modes_file_text(report: dict[str, Any], direction: str) -> str:
    """The fitted modes of ``report`` as ``[[modes]]`` tables of a modes file (TOML).

    Parameters
    ----------
    report
        The JSON of ``fit-frf`` (:func:`fit_frf_report`).
    direction
        ``"x"`` or ``"y"``: the direction of the measured driving-point FRF.

    Returns
    -------
    str
        TOML text read by ``cnctwin stability lobes --modes-file`` (docs/stability.md).
    """
    low, high = report["band_hz"]
    lines = [
        f"# Modes fitted to {report['file']} ({low:.0f}-{high:.0f} Hz) by cnctwin dynamics "
        f"fit-frf, direction {direction}."
    ]
    for mode in report["modes"]:
        lines += [
            "",
            "[[modes]]",
            f'direction = "{direction}"',
            f"fn_hz = {mode['natural_frequency_hz']!r}",
            f"damping_ratio = {mode['damping_ratio']!r}",
            f"stiffness_n_m = {mode['stiffness_n_m']!r}",
        ]
    return "\n".join(lines) + "\n"


def _plot(path: Path, frf: FRF, fit: ModalFit, title: str) -> None:
    """Real part, imaginary part and magnitude, measured and fitted, over the band +- 20 %.

    With an exponential window both curves are the windowed FRF (:meth:`ModalFit.evaluate`).
    """
    from matplotlib.figure import Figure  # matplotlib only when asked for

    low, high = fit.omega_band
    keep = (frf.omega >= 0.8 * low) & (frf.omega <= 1.2 * high)
    omega = frf.omega[keep]
    f_hz = omega / TWO_PI
    measured = frf.h[keep]
    fitted = fit.evaluate(omega, windowed=True)
    figure = Figure(figsize=(9.0, 8.0), dpi=100, layout="constrained")
    real, imag, magnitude = figure.subplots(3, 1, sharex=True)
    window = f", exponential window 1/tau = {fit.window_decay:.3g} 1/s" if fit.window_decay else ""
    figure.suptitle(
        f"{title}: {len(fit.modes)}-mode fit, residual norm {fit.residual_norm:.3f}{window}"
    )
    for axes, part, label in ((real, np.real, "real [m/N]"), (imag, np.imag, "imaginary [m/N]")):
        axes.plot(f_hz, part(measured), linewidth=0.8, label="measured")
        axes.plot(f_hz, part(fitted), linewidth=1.0, linestyle="--", label="fit")
        axes.set_ylabel(label)
    magnitude.semilogy(f_hz, np.abs(measured), linewidth=0.8, label="measured")
    magnitude.semilogy(f_hz, np.abs(fitted), linewidth=1.0, linestyle="--", label="fit")
    magnitude.set_ylabel("|H| [m/N]")
    magnitude.set_xlabel("frequency [Hz]")
    for mode in fit.modes:
        for axes in (real, imag, magnitude):
            axes.axvline(mode.omega_n / TWO_PI, color="tab:gray", linewidth=0.6, alpha=0.6)
    if frf.coherence is not None and frf.averages > 1:
        coherence = magnitude.twinx()
        coherence.plot(f_hz, frf.coherence[keep], color="tab:green", linewidth=0.6)
        coherence.set_ylim(0.0, 1.05)
        coherence.set_ylabel("coherence (green)")
    for axes in (real, imag, magnitude):
        axes.axvspan(low / TWO_PI, high / TWO_PI, color="tab:blue", alpha=0.05, linewidth=0)
        axes.grid(alpha=0.3)
    real.legend(loc="upper right", fontsize="small")
    figure.savefig(path)


@app.command("fit-frf")
def fit_frf(
    file: Annotated[Path, typer.Argument(help="FRF table, impact record (text) or .mat FRF.")],
    modes: Annotated[int, typer.Option("--modes", min=1, max=20, help="Number of modes.")] = 1,
    band: Annotated[
        tuple[float, float] | None,
        typer.Option("--band", help="Fitted band LO HI in Hz (default 100 Hz to the top)."),
    ] = None,
    plot: Annotated[
        Path | None, typer.Option("--plot", help="Write measured vs fitted FRF to this PNG.")
    ] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    kind: Annotated[
        str, typer.Option("--kind", help="auto, frf (Hz, Re, Im) or impact (t, force, response).")
    ] = "auto",
    variable: Annotated[
        str | None, typer.Option("--variable", help="The FRF's variable in a .mat file.")
    ] = None,
    quantity: Annotated[
        str | None,
        typer.Option(
            "--quantity",
            help="receptance, mobility or accelerance (default: receptance for an FRF, "
            "accelerance for an impact record's response).",
        ),
    ] = None,
    tau_ms: Annotated[
        float | None,
        typer.Option("--tau-ms", help="Exponential window on an impact record, time constant ms."),
    ] = None,
    modes_out: Annotated[
        Path | None,
        typer.Option(
            "--modes-out", help="Write the modes as a modes file for 'stability lobes' (TOML)."
        ),
    ] = None,
    direction: Annotated[
        str, typer.Option("--direction", help="Direction of the measured FRF: x or y.")
    ] = "x",
) -> None:
    """Fit modes (natural frequency, damping, stiffness, mass) to a tap test's FRF.

    Each mode is 1 / (k - m w^2 + j c w) (Royandi 2026, Eq. 13); the fit is nonlinear least
    squares on the complex receptance with upper and lower residuals. Fit each direction's
    FRF (x, y) separately; --modes-out writes each fit's modes, along --direction, as
    [[modes]] tables: concatenate the x and y files into one modes file.
    """
    if direction not in ("x", "y"):
        raise InputError(f"--direction {direction!r}; valid: x, y")
    if kind not in ("auto", "frf", "impact"):
        raise InputError(f"--kind {kind!r}; valid: auto, frf, impact")
    if quantity is not None and quantity not in ("receptance", "mobility", "accelerance"):
        raise InputError(f"--quantity {quantity!r}; valid: receptance, mobility, accelerance")
    report = fit_frf_report(
        file, modes=modes, band_hz=band, kind=kind, variable=variable,  # type: ignore[arg-type]
        quantity=quantity, tau_ms=tau_ms, plot=plot,  # type: ignore[arg-type]
    )  # fmt: skip
    if modes_out is not None:
        modes_out.write_text(modes_file_text(report, direction), encoding="utf-8")
    if as_json:
        sys.stdout.write(finite_json.dumps(report) + "\n")
        return
    low, high = report["band_hz"]
    console = Console()
    console.print(
        f"{file}: {report['kind']}, {low:.0f}-{high:.0f} Hz, residual norm "
        f"{report['residual_norm']:.3f}",
        markup=False,
        highlight=False,
        soft_wrap=True,
    )
    table = Table()
    for column in ("f_n (Hz)", "zeta (%)", "k (N/um)", "m (kg)", "c (N s/m)", "fit"):
        table.add_column(column, justify="right")
    for mode in report["modes"]:
        table.add_row(
            f"{mode['natural_frequency_hz']:.1f}",
            f"{100.0 * mode['damping_ratio']:.2f}",
            f"{mode['stiffness_n_m'] * 1e-6:.4g}",
            f"{mode['mass_kg']:.4g}",
            f"{mode['damping_n_s_m']:.4g}",
            f"{mode['residual_norm']:.3f}",
        )
    console.print(table)
