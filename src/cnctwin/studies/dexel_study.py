"""The dexel density x cycle time study of Heide 2025 (Sec. 2.3, Table 2): definition and one run.

Heide et al. (2025) simulated a side-milling cut of aluminium with a 6 mm cylindrical tool at
``ae = 1.8 mm`` and ``ap = 10 mm`` for every combination of dexel density
``rho in {5, 10, 13, 16, 20} /mm``, cycle time ``t_cycle in {6.25, 12.5, 25, 50, 75, 100, 150,
200} ms`` and feed ``vf in {480, 960, ..., 2880} mm/min`` (240 runs), and compared the simulated
width of cut and feed with the programmed ones and the runtime.

Here one run is an NC program (:meth:`SideMillingCut.program`) interpreted and sampled at the
cycle time (:mod:`cnctwin.nc`) and cut through a fresh tri-dexel block
(:func:`cnctwin.simulation.simulate_cut`), the twin's offline loop. Its metrics, over the steady
part of the cut (the tool at least one diameter inside both ends of the block):

- ``delta_ae_mm``: mean ``|ae - ae_nominal|`` of the steps, mm (the geometry layer's ``ae``: the
  extent of the removed material across the feed);
- ``feed_deviation_pct``: mean ``|vf_rec - vf| / vf * 100`` of the steps, with ``vf_rec`` the
  feed reconstructed from the tip's displacement per cycle (Heide 2025, Sec. 2.3);
- ``volume_deviation_pct``: ``(V - V_nom) / V_nom * 100`` with ``V`` the volume the steps
  removed and ``V_nom = ae ap s n`` what a continuous cut removes over the same ``n`` steps of
  length ``s``: negative where the discrete positions leave scallops (steps ``s < D``, a
  fraction ``(s R - (s/2) sqrt(R^2 - s^2/4) - R^2 asin(s / 2R)) / (s ae)`` while the scallop
  stays below the side face) or islands of material (``s`` beyond the engaged chord). Not part
  of Heide 2025's score; it shows what the score cannot (Heide 2025, Fig. 7a);
- ``runtime_s`` (wall) and ``cpu_s`` (CPU of the process) of the simulation loop: interpreting,
  sampling and cutting with engagement, not building the block.

Units at this edge: mm, mm/min, s (names say so).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from itertools import product

import numpy as np

from cnctwin.errors import ConfigError
from cnctwin.geometry import Cutter, DexelStock
from cnctwin.nc import interpret_text
from cnctwin.simulation import COLUMNS, simulate_cut

__all__ = [
    "PAPER",
    "PAPER_CYCLES_S",
    "PAPER_DENSITIES_PER_MM",
    "PAPER_FEEDS_MM_MIN",
    "PAPER_PROCESS_S",
    "DexelStudy",
    "RunResult",
    "RunSpec",
    "SideMillingCut",
    "run_one",
]

#: Heide 2025, Table 2: dexel densities, 1/mm.
PAPER_DENSITIES_PER_MM = (5.0, 10.0, 13.0, 16.0, 20.0)
#: Heide 2025, Table 2: cycle times, s.
PAPER_CYCLES_S = (0.00625, 0.0125, 0.025, 0.05, 0.075, 0.1, 0.15, 0.2)
#: Heide 2025, Table 2: programmed feeds, mm/min.
PAPER_FEEDS_MM_MIN = (480.0, 960.0, 1440.0, 1920.0, 2400.0, 2880.0)
#: Heide 2025, Sec. 2.3: process duration of the study's cut, s.
PAPER_PROCESS_S = 328.0
#: Heide 2025, Sec. 2.3: the optimum of their score and its figures (runtime on their machine).
PAPER = {
    "density_per_mm": 10.0,
    "cycle_s": 0.0125,
    "delta_ae_mm": 0.093,
    "feed_deviation_pct": 0.61,
    "runtime_s": 41.7,
    "process_s": PAPER_PROCESS_S,
    "score": 0.056,
}

_COL = {name: k for k, name in enumerate(COLUMNS)}
_RAPID_MM_MIN = 10000.0
_START_GAP_MM = 5.0


@dataclass(frozen=True, slots=True)
class SideMillingCut:
    """One straight side-milling (shoulder) pass along +x of a flat end mill.

    The block spans ``x in [start_gap_mm, start_gap_mm + block_length_mm]``,
    ``y in [-block_width_mm, 0]``, ``z in [-(ap_mm + floor_mm), 0]``. The tool tip moves at
    ``y = D/2 - ae_mm``, ``z = -ap_mm`` from ``x = 0`` to ``x = block_length_mm + 2 start_gap_mm``
    (one G1), so it takes ``ae_mm`` off the side face ``y = 0`` over the full depth ``ap_mm``
    and leaves a shoulder: a floor at ``z = -ap_mm`` and a wall at ``y = -ae_mm``. The material
    is on the right of the feed: down (climb) milling, M3.

    Attributes
    ----------
    block_length_mm
        Length of the block along the feed, mm.
    diameter_mm, flute_length_mm, flutes
        The tool: a flat (cylindrical) end mill, mm.
    ae_mm, ap_mm
        Nominal radial and axial depths of cut, mm.
    block_width_mm
        Width of the block across the feed, mm (> ``ae_mm``).
    floor_mm
        Material left below the floor of the cut, mm.
    start_gap_mm
        Clearance between the tool axis and the block at both ends of the pass, mm (> D/2).
    spindle_rpm
        Spindle speed, rpm (only the feed per tooth depends on it).
    """

    block_length_mm: float
    diameter_mm: float = 6.0
    flute_length_mm: float = 20.0
    flutes: int = 3
    ae_mm: float = 1.8
    ap_mm: float = 10.0
    block_width_mm: float = 5.0
    floor_mm: float = 2.0
    start_gap_mm: float = _START_GAP_MM
    spindle_rpm: float = 10000.0

    def __post_init__(self) -> None:
        if not all(map(math.isfinite, (*self._lengths_mm(), self.spindle_rpm))):
            raise ConfigError(f"{self!r}: every length and the spindle speed must be finite")
        radius = 0.5 * self.diameter_mm
        checks = (
            (self.diameter_mm > 0.0, f"diameter_mm={self.diameter_mm!r}; give a diameter > 0"),
            (
                0.0 < self.ae_mm <= self.diameter_mm,
                f"ae_mm={self.ae_mm!r}; give 0 < ae <= the diameter {self.diameter_mm} mm",
            ),
            (
                0.0 < self.ap_mm < self.flute_length_mm,
                f"ap_mm={self.ap_mm!r}; give 0 < ap < the flute length {self.flute_length_mm} mm",
            ),
            (
                self.block_width_mm > self.ae_mm,
                f"block_width_mm={self.block_width_mm!r}; give a width > ae = {self.ae_mm} mm",
            ),
            (self.floor_mm >= 0.0, f"floor_mm={self.floor_mm!r}; give a floor >= 0 mm"),
            (
                self.start_gap_mm > radius,
                f"start_gap_mm={self.start_gap_mm!r}; give a clearance > the radius {radius} mm",
            ),
            (
                self.block_length_mm > 2.0 * self.diameter_mm,
                f"block_length_mm={self.block_length_mm!r}; give a block longer than two tool "
                f"diameters ({2.0 * self.diameter_mm} mm) so the cut has a steady part",
            ),
            (self.flutes >= 1, f"flutes={self.flutes!r}; give at least 1 flute"),
            (self.spindle_rpm > 0.0, f"spindle_rpm={self.spindle_rpm!r}; give a speed > 0 rpm"),
        )
        for ok, message in checks:
            if not ok:
                raise ConfigError(message)

    def _lengths_mm(self) -> tuple[float, ...]:
        return (
            self.block_length_mm,
            self.diameter_mm,
            self.flute_length_mm,
            self.ae_mm,
            self.ap_mm,
            self.block_width_mm,
            self.floor_mm,
            self.start_gap_mm,
        )

    @classmethod
    def for_process_time(cls, process_s: float, feeds_mm_min: tuple[float, ...]) -> SideMillingCut:
        """The pass whose feed moves at all ``feeds_mm_min`` take ``process_s`` together.

        One pass per feed, all of the same length ``l``: ``sum_i l / vf_i = process_s``. For
        Heide 2025's 328 s and six feeds ``l = 1071 mm`` (a 1061 mm block): the six passes of
        one setting are the paper's study program.
        """
        if not (math.isfinite(process_s) and process_s > 0.0 and feeds_mm_min):
            raise ConfigError(
                f"process_s={process_s!r} with {len(feeds_mm_min)} feeds; give a time > 0 s "
                "and at least one feed"
            )
        pass_mm = process_s / sum(60.0 / vf for vf in feeds_mm_min)
        return cls(block_length_mm=pass_mm - 2.0 * _START_GAP_MM)

    @property
    def pass_length_mm(self) -> float:
        """Length of the feed move, mm."""
        return self.block_length_mm + 2.0 * self.start_gap_mm

    @property
    def tool_y_mm(self) -> float:
        """y of the tool axis, mm: ``D/2 - ae``."""
        return 0.5 * self.diameter_mm - self.ae_mm

    @property
    def steady_x_mm(self) -> tuple[float, float]:
        """Range of the tool axis' x over which the cut is steady, mm: one diameter inside."""
        return (
            self.start_gap_mm + self.diameter_mm,
            self.start_gap_mm + self.block_length_mm - self.diameter_mm,
        )

    def cutter(self) -> Cutter:
        """The flat end mill."""
        return Cutter.flat(self.diameter_mm, self.flute_length_mm, flutes=self.flutes)

    def stock(self, density_per_mm: float) -> DexelStock:
        """A fresh block at ``density_per_mm`` dexels per mm."""
        return DexelStock.box(
            (self.start_gap_mm, -self.block_width_mm, -(self.ap_mm + self.floor_mm)),
            (self.start_gap_mm + self.block_length_mm, 0.0, 0.0),
            density_per_mm,
        )

    def program(self, feed_mm_min: float) -> str:
        """The NC program of the pass at ``feed_mm_min`` (RS274NGC, mm)."""
        return (
            "G21 G90 G17 G94\n"
            f"S{self.spindle_rpm:.0f} M3\n"
            f"G0 X0 Y{self.tool_y_mm:.6f} Z{-self.ap_mm:.6f}\n"
            f"G1 X{self.pass_length_mm:.6f} F{feed_mm_min:.6g}\n"
            "M5\nM2\n"
        )


@dataclass(frozen=True, slots=True)
class RunSpec:
    """One setting of the study: dexel density (1/mm), cycle time (s), feed (mm/min)."""

    density_per_mm: float
    cycle_s: float
    feed_mm_min: float


@dataclass(frozen=True, slots=True)
class RunResult:
    """The metrics of one run (see the module notes).

    Attributes
    ----------
    spec
        The run's setting.
    delta_ae_mm
        Mean ``|ae - ae_nominal|`` over the steady steps, mm.
    delta_ae_max_mm
        Largest ``|ae - ae_nominal|`` over the steady steps, mm.
    feed_deviation_pct
        Mean ``|vf_rec - vf| / vf`` over the steady steps, percent.
    volume_deviation_pct
        Removed volume over the steady steps against a continuous cut's, signed, percent.
    runtime_s
        Wall time of the simulation loop, s.
    cpu_s
        CPU time of the simulation loop (this process), s.
    process_s
        Duration of the program, s.
    steps, steady_steps
        Simulated steps in all, and in the steady part.
    """

    spec: RunSpec
    delta_ae_mm: float
    delta_ae_max_mm: float
    feed_deviation_pct: float
    volume_deviation_pct: float
    runtime_s: float
    cpu_s: float
    process_s: float
    steps: int
    steady_steps: int


@dataclass(frozen=True, slots=True)
class DexelStudy:
    """A full-factorial study: every density x cycle time x feed on one side-milling pass.

    Attributes
    ----------
    densities_per_mm, cycles_s, feeds_mm_min
        The factor levels: 1/mm, s, mm/min (each > 0, no repeats).
    cut
        The pass every run simulates.
    """

    densities_per_mm: tuple[float, ...]
    cycles_s: tuple[float, ...]
    feeds_mm_min: tuple[float, ...]
    cut: SideMillingCut

    def __post_init__(self) -> None:
        for name, levels in (
            ("densities_per_mm", self.densities_per_mm),
            ("cycles_s", self.cycles_s),
            ("feeds_mm_min", self.feeds_mm_min),
        ):
            ok = all(math.isfinite(v) and v > 0.0 for v in levels)
            if not levels or not ok or len(set(levels)) != len(levels):
                raise ConfigError(
                    f"{name}={levels!r}; give at least one level, each finite, > 0 and distinct"
                )

    @classmethod
    def paper(cls) -> DexelStudy:
        """Heide 2025's 240 runs (Table 2), passes sized to their 328 s of process."""
        return cls(
            PAPER_DENSITIES_PER_MM,
            PAPER_CYCLES_S,
            PAPER_FEEDS_MM_MIN,
            SideMillingCut.for_process_time(PAPER_PROCESS_S, PAPER_FEEDS_MM_MIN),
        )

    @classmethod
    def quick(cls) -> DexelStudy:
        """A 24-run subset on a 30 mm block: three densities, four cycle times, two feeds."""
        return cls(
            (5.0, 10.0, 20.0),
            (0.00625, 0.0125, 0.05, 0.2),
            (480.0, 2880.0),
            SideMillingCut(block_length_mm=30.0),
        )

    def runs(self) -> list[RunSpec]:
        """Every setting, densities slowest, feeds fastest."""
        return [
            RunSpec(rho, cycle, feed)
            for rho, cycle, feed in product(self.densities_per_mm, self.cycles_s, self.feeds_mm_min)
        ]


def run_one(cut: SideMillingCut, spec: RunSpec) -> RunResult:
    """Simulate one run and measure it.

    Parameters
    ----------
    cut
        The pass.
    spec
        Density (1/mm), cycle time (s) and feed (mm/min).

    Returns
    -------
    RunResult
        Width-of-cut and feed deviations over the steady part, runtimes, steps.

    Raises
    ------
    ConfigError
        When the cycle time is too long for any step to fall in the steady part.
    """
    stock = cut.stock(spec.density_per_mm)
    cutters = {0: cut.cutter()}
    wall = time.perf_counter()
    cpu = time.process_time()
    segments = interpret_text(cut.program(spec.feed_mm_min), name="side_milling.ngc")
    chunks = list(
        simulate_cut(segments, stock, cutters, rapid_mm_min=_RAPID_MM_MIN, cycle_s=spec.cycle_s)
    )
    cpu = time.process_time() - cpu
    wall = time.perf_counter() - wall
    rows = np.concatenate(chunks)
    x = rows[:, _COL["x_mm"]]
    low, high = cut.steady_x_mm
    steady = (rows[:, _COL["contact"]] > 0) & (x >= low) & (x <= high)
    if not steady.any():
        raise ConfigError(
            f"cycle time {spec.cycle_s} s at {spec.feed_mm_min} mm/min leaves no step in the "
            f"steady part x in [{low}, {high}] mm; lengthen the block or shorten the cycle"
        )
    ae_error = np.abs(rows[steady, _COL["ae_mm"]] - cut.ae_mm)
    feed_error = np.abs(rows[steady, _COL["feed_mm_min"]] - spec.feed_mm_min)
    step_mm = spec.feed_mm_min / 60.0 * spec.cycle_s
    nominal_mm3 = cut.ae_mm * cut.ap_mm * step_mm * int(steady.sum())
    removed_mm3 = float(rows[steady, _COL["removed_mm3"]].sum())
    return RunResult(
        spec=spec,
        delta_ae_mm=float(ae_error.mean()),
        delta_ae_max_mm=float(ae_error.max()),
        feed_deviation_pct=float(feed_error.mean() / spec.feed_mm_min * 100.0),
        volume_deviation_pct=(removed_mm3 - nominal_mm3) / nominal_mm3 * 100.0,
        runtime_s=wall,
        cpu_s=cpu,
        process_s=float(rows[-1, _COL["t_s"]]),  # the last row is the program's end
        steps=int(rows.shape[0]),
        steady_steps=int(steady.sum()),
    )
