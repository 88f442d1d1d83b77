"""Validation on real dynamometer records: slot milling, 6000 rpm, 2 flutes, ap 3 mm, 5 feeds.

Data: ``cutting_force/kistler_slot_6000rpm`` (Kistler DynoWare CSV, Fx Fy Fz in N at 10 kHz,
1 s), provenance in the data folder's MANIFEST.tsv, notes in ``stability/NOTES.md`` section 6.
The data's own reading script uses CSV Fx as the model's Fy; with a right-handed dynamometer
frame (z down) under the workpiece and a clockwise (M3) spindle, the force on the tool in the
tool frame of :mod:`cnctwin.mechanics` is ``(x, y, z) = (CSV Fy, CSV Fx, CSV Fz)``.

Not documented, so assumed: a 25 mm flat end mill ("ae25": a 25 mm slot), helix 30 deg.
The runout is estimated from the 900 mm/min record alone and used for all five feeds.

Run as a script (``python tests/mechanics/test_kistler_validation.py``) to print the figures
of docs/_validation_forces.md.
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from cnctwin.geometry import Cutter
from cnctwin.mechanics import ImmersionIntervals, milling_forces
from cnctwin.mechanics.identification import CoefficientFit, identify_coefficients
from cnctwin.mechanics.materials import milling_material

pytestmark = pytest.mark.validation

FOLDER = Path("cutting_force") / "kistler_slot_6000rpm"
FEEDS_MM_MIN = (300, 600, 900, 1200, 1500)
RPM, TEETH, DEPTH_M = 6000.0, 2, 3e-3
DIAMETER_MM, HELIX_DEG = 25.0, 30.0  # assumed, see the module notes
FLUTE_LENGTH_MM = 30.0  # assumed; the cut is 3 mm deep
REVOLUTIONS = 100
FIT_FEED = 900  # the record the runout is estimated from


def feed_per_tooth_m(feed_mm_min: float) -> float:
    return feed_mm_min / (RPM * TEETH) * 1e-3


def read_dynoware(path: Path) -> tuple[float, np.ndarray]:
    """Sampling rate (Hz) and the (n, 3) CSV force columns Fx, Fy, Fz (N) of a DynoWare export."""
    rate = math.nan
    with path.open(encoding="latin-1") as lines:
        for line in lines:
            if line.startswith("Sampling rate"):
                rate = float(line.split(",")[1])
            if line.startswith("s,N"):
                break
        data = np.loadtxt(lines, delimiter=",")
    return rate, data[:, 1:4]


def tool_frame(csv_forces: np.ndarray) -> np.ndarray:
    """Forces on the tool in the tool frame from the CSV columns (see the module notes)."""
    return csv_forces[:, [1, 0, 2]]


@dataclass
class Record:
    feed_mm_min: int
    rate_hz: float
    csv: np.ndarray

    @property
    def samples_per_rev(self) -> int:
        return round(self.rate_hz * 60.0 / RPM)

    def revolution_average(self) -> np.ndarray:
        """Tool-frame forces averaged over whole revolutions, shape (samples_per_rev, 3)."""
        n = self.samples_per_rev
        return tool_frame(self.csv[: REVOLUTIONS * n]).reshape(REVOLUTIONS, n, 3).mean(axis=0)


def load(shared_data: Path) -> list[Record]:
    folder = shared_data / FOLDER
    records = []
    for feed in FEEDS_MM_MIN:
        path = folder / f"6-n6000f{feed}ap3ae25.csv"
        if not path.is_file():
            pytest.skip(f"{path} is absent")
        rate, csv = read_dynoware(path)
        records.append(Record(feed, rate, csv))
    return records


def identify(records: list[Record]) -> CoefficientFit:
    feeds = np.array([feed_per_tooth_m(r.feed_mm_min) for r in records])
    means = np.array([r.revolution_average().mean(axis=0) for r in records])
    return identify_coefficients(feeds, means, teeth=TEETH, depth_m=DEPTH_M)


def simulate(record: Record, fit: CoefficientFit, runout_m: float, angle_rad: float) -> np.ndarray:
    cutter = Cutter(
        "flat",
        DIAMETER_MM,
        FLUTE_LENGTH_MM,
        flutes=TEETH,
        helix_rad=math.radians(HELIX_DEG),
        runout_mm=runout_m * 1e3,
        runout_angle_rad=angle_rad,
    )
    cut = ImmersionIntervals.from_angles(0.0, math.pi, DEPTH_M, slices=30)
    wave = milling_forces(
        cutter,
        fit.coefficients,
        cut,
        feed_per_tooth_m(record.feed_mm_min),
        RPM * math.pi / 30.0,
        steps=record.samples_per_rev,
    )
    return np.column_stack([wave.fx_n, wave.fy_n, wave.fz_n])


def lowpass(signal: np.ndarray, harmonics: int) -> np.ndarray:
    """Keep the mean and the first ``harmonics`` harmonics of the revolution frequency."""
    spectrum = np.fft.rfft(signal, axis=0)
    spectrum[harmonics + 1 :] = 0.0
    return np.fft.irfft(spectrum, n=signal.shape[0], axis=0)


@dataclass
class Match:
    shift: int  # samples by which the simulation is rotated to line up with the measurement
    xy: float  # correlation of Fx and Fy together
    per_axis: np.ndarray  # correlations of Fx, Fy, Fz


def match(simulated: np.ndarray, measured: np.ndarray) -> Match:
    """Align the simulated revolution with the measured one (one rotation for all three axes,
    chosen on Fx and Fy: the records start at arbitrary spindle angles), then correlate."""
    best = Match(0, -2.0, np.zeros(3))
    for shift in range(simulated.shape[0]):
        rolled = np.roll(simulated, shift, axis=0)
        xy = float(np.corrcoef(rolled[:, :2].ravel(), measured[:, :2].ravel())[0, 1])
        if xy > best.xy:
            per_axis = np.array([np.corrcoef(rolled[:, k], measured[:, k])[0, 1] for k in range(3)])
            best = Match(shift, xy, per_axis)
    return best


def estimate_runout(record: Record, fit: CoefficientFit) -> tuple[float, float]:
    """Runout (m) and its angle (rad) that best match one record's revolution shape (grid)."""
    measured = record.revolution_average()
    best = (-2.0, 0.0, 0.0)
    for runout in np.arange(0.0, 30.5e-6, 2.5e-6):
        for angle in np.radians(np.arange(0.0, 360.0, 30.0)):
            xy = match(simulate(record, fit, runout, angle), measured).xy
            if xy > best[0]:
                best = (xy, runout, angle)
            if runout == 0.0:
                break  # the angle of no runout does not matter
    return best[1], best[2]


@pytest.fixture(scope="module")
def records(shared_data: Path) -> list[Record]:
    return load(shared_data)


@pytest.fixture(scope="module")
def fit(records: list[Record]) -> CoefficientFit:
    return identify(records)


def test_reading_reproduces_the_notes(records: list[Record]) -> None:
    # stability/NOTES.md section 6: means over the 1 s window (all 10001 samples).
    notes = {
        "x": (63.0, 107.1, 137.7, 171.3, 210.7),
        "y": (-39.8, -60.1, -71.6, -76.8, -78.5),
        "z": (55.7, 70.9, 82.6, 85.2, 83.5),
    }
    for i, record in enumerate(records):
        assert record.rate_hz == 10000.0 and record.samples_per_rev == 100
        mean = record.csv.mean(axis=0)
        for k, axis in enumerate("xyz"):
            assert mean[k] == pytest.approx(notes[axis][i], abs=0.06)


def test_identified_coefficients_match_the_notes_and_the_library(fit: CoefficientFit) -> None:
    # NOTES section 6: "roughly Ktc 959, Kte 15.8, Krc 251, Kre 19.4".
    k = fit.coefficients.to_n_mm()
    assert k["ktc_n_mm2"] == pytest.approx(959, rel=0.005)
    assert k["kte_n_mm"] == pytest.approx(15.8, rel=0.01)
    assert k["krc_n_mm2"] == pytest.approx(251, rel=0.005)
    assert k["kre_n_mm"] == pytest.approx(19.4, rel=0.01)
    library = milling_material("kistler-slot-6000rpm").coefficients.to_n_mm()
    for key, value in k.items():
        assert library[key] == pytest.approx(value, rel=5e-4), key


def test_identified_coefficients_reproduce_the_measured_means(fit: CoefficientFit) -> None:
    # A linear model in the feed cannot follow Fx and Fz levelling off above 0.1 mm/tooth:
    # within 7.5 N everywhere; Fy (the largest force) within 5 %.
    assert np.all(np.abs(fit.residuals_n) < 7.5)
    assert np.all(np.abs(fit.relative_residuals[:, 1]) < 0.05)
    assert fit.r_squared[1] > 0.99


def test_simulated_waveforms_match_the_measured_shape(
    records: list[Record], fit: CoefficientFit
) -> None:
    # The runout comes from the 900 mm/min record; the other four feeds are predictions.
    by_feed = {r.feed_mm_min: r for r in records}
    runout, angle = estimate_runout(by_feed[FIT_FEED], fit)
    # With two teeth only the difference of their radii shows; 10-30 um is a plausible runout
    # of an end mill in a collet, and the large/small tooth alternation is plain in the data.
    difference = 2.0 * runout * abs(math.cos(angle))
    assert 10e-6 <= difference <= 30e-6
    for record in records:
        measured = record.revolution_average()
        result = match(simulate(record, fit, runout, angle), measured)
        assert result.xy > 0.8, (record.feed_mm_min, result)
        assert result.per_axis[0] > 0.8, (record.feed_mm_min, result)
        # Without the ~800 Hz structural ringing the rigid model does not carry:
        smooth = match(simulate(record, fit, runout, angle), lowpass(measured, 6))
        assert smooth.xy > 0.88, (record.feed_mm_min, smooth)
        # Against a spindle turning the other way (time reversed) the shape does not fit.
        reversed_ = match(simulate(record, fit, runout, angle), measured[::-1])
        assert reversed_.xy < result.xy - 0.1, (record.feed_mm_min, reversed_)


def main() -> None:
    """Print the validation figures as Markdown."""
    root = Path(
        os.environ.get("CNCTWIN_DATA") or Path(__file__).parents[2].parent / "shared" / "data"
    )
    recs = load(root)
    result = identify(recs)
    k = result.coefficients.to_n_mm()
    print("| coefficient | value |\n|---|---:|")
    for key, value in k.items():
        print(f"| {key} | {value:.2f} |")
    print(f"\nR^2 x, y, z: {', '.join(f'{r:.4f}' for r in result.r_squared)}\n")
    axes = " | ".join(f"F{a} meas | F{a} fit | F{a} res" for a in "xyz")
    print(f"| feed mm/min | fz mm | {axes} |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for i, rec in enumerate(recs):
        cells = [f"{rec.feed_mm_min}", f"{feed_per_tooth_m(rec.feed_mm_min) * 1e3:.3f}"]
        for a in range(3):
            m, p = result.measured_n[i, a], result.predicted_n[i, a]
            cells += [f"{m:.1f}", f"{p:.1f}", f"{m - p:+.1f} ({100 * (m - p) / abs(m):+.1f} %)"]
        print("| " + " | ".join(cells) + " |")
    by_feed = {r.feed_mm_min: r for r in recs}
    runout, angle = estimate_runout(by_feed[FIT_FEED], result)
    difference = 2.0 * runout * abs(math.cos(angle)) * 1e6
    print(f"\nrunout {runout * 1e6:.1f} um at {math.degrees(angle):.0f} deg: teeth differ by")
    print(f"{difference:.1f} um in radius\n")
    columns = "r(Fx,Fy) | r Fx | r Fy | r Fz"
    print(
        f"| feed mm/min | {columns} | low-passed {columns} | no runout r(Fx,Fy) "
        "| reversed r(Fx,Fy) |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for rec in recs:
        meas = rec.revolution_average()
        sim = simulate(rec, result, runout, angle)
        raw, smooth = match(sim, meas), match(sim, lowpass(meas, 6))
        plain = match(simulate(rec, result, 0.0, 0.0), meas)
        rev = match(sim, meas[::-1])
        cells = [f"{rec.feed_mm_min}", f"{raw.xy:.3f}", *(f"{c:.3f}" for c in raw.per_axis)]
        cells += [f"{smooth.xy:.3f}", *(f"{c:.3f}" for c in smooth.per_axis)]
        cells += [f"{plain.xy:.3f}", f"{rev.xy:.3f}"]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    sys.exit(main())
