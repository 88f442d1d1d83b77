"""``cnctwin dynamics``: structural dynamics from tap tests. ``fit-frf`` fits modes to an FRF.

The readers of tap-test files live here, at the edge, so that :mod:`cnctwin.dynamics` stays
free of I/O. Three kinds of file are read:

- an FRF table (text): columns frequency [Hz], real part, imaginary part (m/N by default);
- an impact record (text): columns time [s], hammer force [N], response (acceleration in
  m/s^2 by default), one hit; the H1 FRF is computed from it;
- a MATLAB ``.mat`` file holding an FRF: an ``N x 2`` (real, imaginary) or complex variable,
  with a frequency vector (``f``, ``freq`` or ``frequency``, Hz) or ``df`` and ``f_start`` (Hz).

A text file is an impact record when its first column advances by less than 0.01 per row (a
sampling interval, s) and an FRF table otherwise (a frequency step, Hz); ``--kind`` overrides.
"""

from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

import numpy as np
import typer
from numpy.typing import NDArray
from rich.console import Console
from rich.table import Table

from cnctwin import finite_json
from cnctwin.cli._options import check_number
from cnctwin.dynamics.frf import FRF, FRFQuantity, impact_frf
from cnctwin.errors import ConfigError, DataError

if TYPE_CHECKING:
    from cnctwin.dynamics.modal import ModalFit

__all__ = [
    "TapTest",
    "app",
    "fit_frf",
    "fit_frf_report",
    "load_tap_test",
    "modes_file_text",
    "read_frf_mat",
    "read_impact_record",
    "read_table",
]

app = typer.Typer(help="Structural dynamics: FRFs and modal fits from tap tests.",
                  no_args_is_help=True)  # fmt: skip

TWO_PI = 2.0 * math.pi
DEFAULT_LOW_HZ = 100.0
MAX_BAND_HZ = 1.0e6
"""Highest edge of the fitted band, Hz: above any structural mode and impact hammer."""
MAX_TAU_MS = 60_000.0
"""Longest exponential window time constant, ms: longer than any tap record."""
"""Default low edge of the fitted band, Hz: below it an accelerometer's receptance is noise."""
IMPACT_STEP_LIMIT = 0.01
"""A text file whose first column steps by less than this is an impact record (s), else an FRF."""
EXCITED_DB = 40.0
"""An impact record's default band ends where the force spectrum is this far below its peak, dB."""

Kind = Literal["auto", "frf", "impact"]
_NUMBER_SPLIT = re.compile(r"[\s,;]+")


@dataclass(frozen=True)
class TapTest:
    """What a tap-test file gave.

    Attributes
    ----------
    frf
        The FRF (still the file's quantity; an impact record's H1 with its coherence).
    kind
        ``"frf"`` or ``"impact"``.
    variable
        The ``.mat`` variable read, else None.
    excited_omega
        For an impact record, the highest angular frequency the hammer excites (force spectrum
        within :data:`EXCITED_DB` of its peak), rad/s; else None.
    """

    frf: FRF
    kind: Literal["frf", "impact"]
    variable: str | None = None
    excited_omega: float | None = None


@app.callback()
def _dynamics() -> None:
    """Structural dynamics: FRFs and modal fits from tap tests."""


def read_table(path: Path, n_columns: int = 3) -> NDArray[np.float64]:
    """The numeric rows of a text table: whitespace, comma or semicolon separated.

    Blank lines and lines starting with ``#``, ``%`` or ``;`` are skipped, and so is a header
    (rows before the first numeric one).

    Returns
    -------
    numpy.ndarray
        Shape ``(rows, n_columns)``; extra columns are an error.

    Raises
    ------
    DataError
        ``FILE:LINE: ...`` for a row that is not ``n_columns`` numbers, or a file without rows.
    """
    rows: list[list[float]] = []
    with path.open(encoding="utf-8", errors="replace") as handle:
        for number, line in enumerate(handle, start=1):
            text = line.strip()
            if not text or text[0] in "#%;":
                continue
            fields = [field for field in _NUMBER_SPLIT.split(text) if field]
            try:
                values = [float(field) for field in fields]
            except ValueError:
                if not rows:
                    continue  # a header
                raise DataError(
                    f"{path}:{number}: {text[:40]!r} is not {n_columns} numbers"
                ) from None
            if len(values) != n_columns:
                raise DataError(
                    f"{path}:{number}: {len(values)} columns; give {n_columns} (see "
                    "cnctwin dynamics fit-frf --help)"
                )
            rows.append(values)
    if len(rows) < 4:
        raise DataError(f"{path}: {len(rows)} numeric rows; give a table of at least 4")
    table = np.asarray(rows)
    if not np.all(np.isfinite(table)):
        raise DataError(f"{path}: the table holds NaN or infinite values")
    return table


def _frf_from_table(path: Path, table: NDArray[np.float64], quantity: FRFQuantity) -> FRF:
    frequency_hz = table[:, 0]
    if np.any(np.diff(frequency_hz) <= 0.0) or frequency_hz[0] < 0.0:
        raise DataError(f"{path}: the frequencies (first column, Hz) must be >= 0 and increasing")
    return FRF(TWO_PI * frequency_hz, table[:, 1] + 1j * table[:, 2], quantity)


def read_impact_record(
    path: Path, table: NDArray[np.float64] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Force [N], response and sampling interval [s] of an impact record (t, force, response).

    ``table`` is the file's table when it has been read already.

    Raises
    ------
    DataError
        When the time column is not uniformly increasing.
    """
    rows = read_table(path) if table is None else table
    time = rows[:, 0]
    dt = float(time[-1] - time[0]) / (time.size - 1)
    # The times are printed with few digits: allow rounding, not a missing or repeated sample.
    if not dt > 0.0 or np.max(np.abs(time - time[0] - dt * np.arange(time.size))) > 0.25 * dt:
        raise DataError(f"{path}: the time column (s) must increase by a constant step")
    return rows[:, 1], rows[:, 2], dt


def read_frf_mat(
    path: Path, variable: str | None = None, quantity: FRFQuantity = "receptance"
) -> tuple[FRF, str]:
    """An FRF from a MATLAB ``.mat`` file (module docstring), and the variable's name.

    Raises
    ------
    DataError
        When the file holds no FRF, several without ``variable``, or no frequencies.
    """
    from scipy.io import loadmat  # scipy.io only when a .mat is read

    try:
        content = {k: v for k, v in loadmat(str(path)).items() if not k.startswith("__")}
    except (ValueError, NotImplementedError, TypeError) as err:
        raise DataError(f"{path}: not a readable MATLAB file ({err})") from None
    candidates = {name: value for name, value in content.items() if _frf_like(value)}
    if variable is None:
        if len(candidates) != 1:
            found = ", ".join(sorted(candidates)) or "none"
            raise DataError(
                f"{path}: {len(candidates)} FRF variables ({found}); name one with --variable"
            )
        variable = next(iter(candidates))
    elif variable not in candidates:
        raise DataError(
            f"{path}: no FRF variable {variable!r}; valid: "
            f"{', '.join(sorted(candidates)) or 'none'}"
        )
    value = np.asarray(candidates[variable])
    h = value[:, 0] + 1j * value[:, 1] if np.isrealobj(value) else value.ravel()
    frequency_hz = _mat_frequencies(path, content, h.size)
    return FRF(TWO_PI * frequency_hz, h.astype(complex), quantity), variable


def _frf_like(value: Any) -> bool:
    """An N x 2 real array or a complex vector, N >= 4."""
    if not isinstance(value, np.ndarray) or value.dtype.kind not in "fc" or value.size < 8:
        return False
    if value.dtype.kind == "c":
        return value.ndim == 1 or (value.ndim == 2 and 1 in value.shape)
    return value.ndim == 2 and value.shape[1] == 2 and value.shape[0] >= 4


def _mat_frequencies(path: Path, content: dict[str, Any], n: int) -> NDArray[np.float64]:
    for name in ("f", "freq", "frequency", "f_hz", "freq_hz"):
        if name in content and np.asarray(content[name]).size == n:
            return np.asarray(content[name], dtype=np.float64).ravel()
    if "df" in content:
        df = float(np.asarray(content["df"]).ravel()[0])
        start = float(np.asarray(content.get("f_start", 0.0)).ravel()[0])
        if df > 0.0:
            return np.asarray(start + df * np.arange(n), dtype=np.float64)
    raise DataError(
        f"{path}: no frequencies; give a vector f (Hz) of {n} values, or df and f_start (Hz)"
    )


def load_tap_test(
    path: Path,
    *,
    kind: Kind = "auto",
    variable: str | None = None,
    quantity: FRFQuantity | None = None,
    tau_s: float | None = None,
) -> TapTest:
    """Read a tap-test file (module docstring) into an FRF.

    Parameters
    ----------
    path
        The file: ``.mat``, or a text table.
    kind
        ``"frf"``, ``"impact"`` or ``"auto"`` (a ``.mat`` is an FRF; a text file by its first
        column's step).
    variable
        The ``.mat`` variable holding the FRF.
    quantity
        What the FRF (or the impact record's response) is; default ``"receptance"`` for an FRF,
        ``"accelerance"`` (response in m/s^2) for an impact record.
    tau_s
        Exponential window time constant for an impact record, s; None for none.
    """
    if not path.is_file():
        raise DataError(f"{path}: no such file")
    if path.suffix.lower() == ".mat":
        if kind == "impact":
            raise DataError(f"{path}: impact records are read from text files, not .mat")
        frf, name = read_frf_mat(path, variable, quantity or "receptance")
        return TapTest(frf, "frf", name)
    table = read_table(path)
    if kind == "auto":
        step = float(np.median(np.diff(table[:, 0])))
        kind = "impact" if 0.0 < step < IMPACT_STEP_LIMIT else "frf"
    if kind == "frf":
        return TapTest(_frf_from_table(path, table, quantity or "receptance"), "frf")
    force, response, dt = read_impact_record(path, table)
    frf = impact_frf(force, response, dt, quantity=quantity or "accelerance", tau=tau_s)
    spectrum = np.abs(np.fft.rfft(force))
    excited = np.flatnonzero(spectrum >= spectrum.max() * 10.0 ** (-EXCITED_DB / 20.0))
    return TapTest(
        frf, "impact", None, TWO_PI * float(np.fft.rfftfreq(force.size, dt)[excited[-1]])
    )


def fit_frf_report(
    path: Path,
    *,
    modes: int = 1,
    band_hz: tuple[float, float] | None = None,
    kind: Kind = "auto",
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
    from cnctwin.dynamics.modal import fit_modes

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
        high = receptance.omega[-1] if test.excited_omega is None else test.excited_omega
        low = TWO_PI * DEFAULT_LOW_HZ
        if high <= low:
            raise ConfigError(
                f"{path}: the default band starts at {DEFAULT_LOW_HZ:g} Hz, above the data "
                f"({high / TWO_PI:g} Hz); give --band LO HI"
            )
    else:
        low, high = (TWO_PI * value for value in band_hz)
        if not (0.0 <= low < high):
            raise ConfigError(f"--band {band_hz[0]:g} {band_hz[1]:g}: give 0 <= LO < HI, in Hz")
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
        raise ConfigError(f"--direction {direction!r}; valid: x, y")
    if kind not in ("auto", "frf", "impact"):
        raise ConfigError(f"--kind {kind!r}; valid: auto, frf, impact")
    if quantity is not None and quantity not in ("receptance", "mobility", "accelerance"):
        raise ConfigError(f"--quantity {quantity!r}; valid: receptance, mobility, accelerance")
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
