"""Benchmark of FRF estimation and modal fitting (``cnctwin.dynamics.frf``, ``.modal``).

Usage: ``python benchmarks/bench_frf.py [--quick]``. Prints a Markdown table for
docs/benchmarks.md. Rows:

* ``impact_frf``: H1 and coherence of 1 s records at 51.2 kHz (the real tap test's format),
  force window on, 1 and 10 hits;
* ``fit_modes``: 1 and 3 modes fitted to a synthetic receptance of 3 modes (1198, 1389,
  1586 Hz) with 1 % noise, 500-2500 Hz at 0.5 Hz (4001 frequencies), and the 3-mode fit's worst
  stiffness error; and 3 modes fitted to the measured tool-point FRF (Point_1, 500-3200 Hz)
  when ../shared/data is there;
* ``sdypy-EMA``: LSCF (order 20) + closest-pole selection + LSFD on the same data, when
  sdypy-EMA is installed.

Each figure is the best of several repetitions after a warm-up. ``--quick`` runs one pass in a
few seconds, to prove the script still runs.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import math
import os
import platform
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

from cnctwin.dynamics import FRF, Mode, fit_modes, impact_frf, modal_frf

TWO_PI = 2.0 * math.pi
TRUTH = [Mode(TWO_PI * 1198.0, 0.041, 8.0), Mode(TWO_PI * 1389.0, 0.048, 5.0),
         Mode(TWO_PI * 1586.0, 0.027, 20.0)]  # fmt: skip


def best_of(repeats: int, fn: Callable[[], object]) -> float:
    """Smallest wall time of ``repeats`` calls of ``fn``, s."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def hits(count: int) -> tuple[np.ndarray, np.ndarray]:
    """``count`` 1 s records at 51.2 kHz: half-sine hits, a noisy response of the modes."""
    fs, n = 51_200.0, 51_200
    t = np.arange(n) / fs
    force = np.where((t > 2e-3) & (t < 2.3e-3), 200.0 * np.sin(np.pi * (t - 2e-3) / 3e-4), 0.0)
    omega = TWO_PI * np.fft.rfftfreq(n, 1.0 / fs)
    accelerance = -(omega**2) * modal_frf(omega, TRUTH)
    response = np.fft.irfft(np.fft.rfft(force) * accelerance, n)
    rng = np.random.default_rng(0)
    noise = 0.01 * np.abs(response).max() * rng.standard_normal((count, n))
    return np.tile(force, (count, 1)), response + noise


def noisy_frf() -> tuple[np.ndarray, np.ndarray]:
    f_hz = np.arange(0.0, 3000.0, 0.5)
    h = modal_frf(TWO_PI * f_hz, TRUTH)
    rng = np.random.default_rng(3)
    return f_hz, h + 0.01 * np.abs(h).max() * (
        rng.standard_normal(h.size) + 1j * rng.standard_normal(h.size)
    )


def sdypy_fit(f_hz: np.ndarray, h: np.ndarray) -> None:
    import sdypy.EMA as ema

    with (
        warnings.catch_warnings(),
        contextlib.redirect_stdout(io.StringIO()),
        contextlib.redirect_stderr(io.StringIO()),
    ):
        warnings.simplefilter("ignore")
        model = ema.Model(frf=h[None, :], freq=f_hz, lower=500, upper=2500, pol_order_high=20,
                          frf_form="receptance")  # fmt: skip
        model.get_poles(method="lscf", show_progress=False)
        model.select_closest_poles([1198.0, 1389.0, 1586.0], f_window=50)
        model.get_constants(method="lsfd_proportional")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a short run, to check it runs")
    args = parser.parse_args()
    repeats = 1 if args.quick else 5
    rows = []
    for count in (1,) if args.quick else (1, 10):
        force, response = hits(count)
        impact_frf(force, response, 1.0 / 51_200.0)
        wall = best_of(repeats, lambda f=force, y=response: impact_frf(f, y, 1.0 / 51_200.0))
        what = f"{count} hit{'s' if count > 1 else ''} of 51 200 samples"
        rows.append((f"impact_frf, {what}", f"{wall * 1e3:.1f} ms", ""))
    f_hz, h = noisy_frf()
    frf = FRF(TWO_PI * f_hz[1:], h[1:])
    band = (TWO_PI * 500.0, TWO_PI * 2500.0)
    for n_modes in (1, 3):
        fit = fit_modes(frf, n_modes, omega_band=band)
        wall = best_of(repeats, lambda n=n_modes: fit_modes(frf, n, omega_band=band))
        note = ""
        if n_modes == 3:
            worst = max(
                abs(m.stiffness / t.stiffness - 1.0) for m, t in zip(fit.modes, TRUTH, strict=True)
            )
            note = f"stiffness within {100 * worst:.2f} % of the truth"
        rows.append((f"fit_modes, {n_modes} mode{'s' if n_modes > 1 else ''}, synthetic, "
                     f"{fit.n_frequencies} frequencies", f"{wall * 1e3:.1f} ms", note))  # fmt: skip
    data = Path(
        os.environ.get("CNCTWIN_DATA") or Path(__file__).resolve().parents[2] / "shared/data"
    )
    point_1 = data / "frf_modal/tool_tap_test/ExperimentalModalAnalysis/Point_1_Channel_1_CH1.txt"
    if point_1.is_file():
        table = np.loadtxt(point_1)
        measured = FRF(TWO_PI * table[:, 0], table[:, 1] + 1j * table[:, 2])
        real_band = (TWO_PI * 500.0, TWO_PI * 3200.0)
        fit = fit_modes(measured, 3, omega_band=real_band)
        wall = best_of(repeats, lambda: fit_modes(measured, 3, omega_band=real_band))
        rows.append((f"fit_modes, 3 modes, measured Point_1, {fit.n_frequencies} frequencies",
                     f"{wall * 1e3:.1f} ms", f"residual norm {fit.residual_norm:.3f}"))  # fmt: skip
    try:
        import sdypy.EMA  # noqa: F401
    except ImportError:
        rows.append(("sdypy-EMA LSCF + LSFD, 3 modes", "not installed", ""))
    else:
        sdypy_fit(f_hz, h)
        wall = best_of(repeats, lambda: sdypy_fit(f_hz, h))
        rows.append(("sdypy-EMA LSCF (order 20) + LSFD, 3 modes", f"{wall * 1e3:.1f} ms", ""))
    print(f"FRF and modal fit, {platform.processor() or platform.machine()}, "
          f"Python {platform.python_version()}{' (quick)' if args.quick else ''}\n")  # fmt: skip
    print("| case | time | note |")
    print("|---|---|---|")
    for case, figure, note in rows:
        print(f"| {case} | {figure} | {note} |")


if __name__ == "__main__":
    main()
