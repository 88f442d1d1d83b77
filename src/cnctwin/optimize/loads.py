"""The load of every step of a program, and the feed per tooth at which each limit is reached.

The mechanistic milling model (Altintas 2012, ch. 2, Eq. 2.10-2.13; the model of
:mod:`cnctwin.mechanics.milling`) charges every tooth element with

    dF = (Kc h + Ke) db,   h = f_z sin(phi) sin(kappa),

so at a fixed engagement (the contact intervals of a step, which the dexel cut finds from the
path alone) every force component, the torque and the chip thickness are affine in the feed
per tooth ``f_z``:

    F(phi; f_z) = f_z A(phi) + B(phi),   T(f_z) = f_z T1 + T0,   h_max = f_z r_h,

with ``B`` the edge (rubbing) part and ``r_h = max sin(phi) sin(kappa)`` over the engagement.
:func:`program_loads` cuts a program through the stock once and, per step in contact, evaluates
``A`` and ``B`` from two force evaluations (at the step's own ``f_z`` and at twice it: a tooth
feels its edge force only where it cuts a chip, so ``f_z = 0`` would miss ``B``); the largest
feed per tooth a limit allows then follows in closed form:

- force (peak over the revolution, or the per-revolution mean): ``|f A + B| <= F_max`` at every
  spindle angle is ``f^2 |A|^2 + 2 f A.B + |B|^2 - F_max^2 <= 0``, whose larger root is the
  limit (none when the edge force ``|B|`` alone exceeds ``F_max``);
- power ``P = T(f) omega <= P_max``: ``f <= (P_max / omega - T0) / T1``;
- chip thickness ``f r_h <= h_max``.

A runout (:meth:`~cnctwin.geometry.Cutter.tooth_radius_offsets_m`) clips the chip of a tooth at
zero and makes the relation only piecewise affine: the re-simulation of the optimised program
(:func:`cnctwin.optimize.optimize_program`) checks the limits either way.

Units: mm, mm/min, rpm, N, W, s in the names (the simulation layer's); SI inside the force model.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from cnctwin.errors import InputError
from cnctwin.geometry import Cutter, DexelStock
from cnctwin.mechanics import CuttingCoefficients, mean_forces, milling_forces
from cnctwin.nc import Segment
from cnctwin.simulation import CutStep, StepTable, immersion_intervals, simulate_cut

__all__ = ["FORCE_METRICS", "FeedLimits", "ProgramLoads", "force_feed_limit", "program_loads"]

#: What a force limit bounds: the largest resultant over a revolution, or the mean resultant.
FORCE_METRICS = ("peak", "mean")
_WAVEFORM_STEPS = 360  # spindle angles per revolution (1 degree), as cnctwin signals
_RAD_S_PER_RPM = math.pi / 30.0
#: Reference feed per tooth for a step whose own is 0 (spindle stopped), m.
_FZ_REFERENCE_M = 1e-4


@dataclass(frozen=True, slots=True)
class FeedLimits:
    """The limits a feed must respect; None leaves a quantity free.

    Attributes
    ----------
    max_force_n
        Largest force on the tool, N (> 0): the resultant's peak over a revolution
        (``force_metric="peak"``, what ``cnctwin signals`` reports as ``max_force_n``) or the
        per-revolution mean resultant (``"mean"``, ``max_mean_force_n``).
    max_power_w
        Largest mean cutting power, W (> 0).
    max_chip_mm
        Largest uncut chip thickness ``f_z sin(phi) sin(kappa)``, mm (> 0).
    force_metric
        ``"peak"`` or ``"mean"``.
    """

    max_force_n: float | None = None
    max_power_w: float | None = None
    max_chip_mm: float | None = None
    force_metric: Literal["peak", "mean"] = "peak"

    def __post_init__(self) -> None:
        for name in ("max_force_n", "max_power_w", "max_chip_mm"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0.0):
                raise InputError(f"{name}={value!r}: give a finite limit > 0")
        if self.force_metric not in FORCE_METRICS:
            raise InputError(
                f"force_metric={self.force_metric!r}: give one of {', '.join(FORCE_METRICS)}"
            )
        if self.max_force_n is None and self.max_power_w is None and self.max_chip_mm is None:
            raise InputError(
                "no limit given: give a force (N), a power (W) or a chip thickness (mm) limit"
            )


def force_feed_limit(a: NDArray[np.float64], b: NDArray[np.float64], max_force_n: float) -> float:
    """The largest feed per tooth at which ``|f a_k + b_k| <= max_force_n`` for every row k.

    Parameters
    ----------
    a
        (k, 3) force per unit feed per tooth, N/mm (the shear part of the force at each angle).
    b
        (k, 3) force at zero feed, N (the edge part).
    max_force_n
        The limit, N.

    Returns
    -------
    float
        Feed per tooth, mm: ``inf`` when the force does not grow with the feed and stays under
        the limit; 0 when the edge force alone exceeds it.
    """
    a2 = np.einsum("ij,ij->i", a, a)
    ab = np.einsum("ij,ij->i", a, b)
    c = np.einsum("ij,ij->i", b, b) - max_force_n**2
    if np.any(c > 0.0):
        return 0.0
    grows = a2 > 1e-300
    if not np.any(grows):
        return math.inf
    a2, ab, c = a2[grows], ab[grows], c[grows]
    root = (-ab + np.sqrt(np.maximum(ab * ab - a2 * c, 0.0))) / a2
    return float(max(np.min(root), 0.0))


@dataclass(frozen=True, eq=False)
class ProgramLoads:
    """Every step of a program cut through the stock, with its load and its feed limits.

    One row per step of :func:`~cnctwin.simulation.simulate_cut` (every segment end sampled,
    so every step belongs to one line). Columns of rows without contact hold 0 (loads) or
    ``inf`` (feed limits).

    Attributes
    ----------
    t_s, line, tool, rapid, contact
        Time (s), source line, tool number, rapid move, contact with the stock, per step.
    tcp_mm
        (n, 3) tool tip, machine coordinates, mm.
    spindle_rpm, feed_per_tooth_mm, flutes
        Commanded speed (rpm), feed per tooth of the step (mm) and the tool's teeth.
    peak_n, mean_n, power_w, chip_mm
        The step's peak and mean resultant force (N), mean cutting power (W) and largest
        chip thickness (mm) at its feed.
    fz_force_mm, fz_chip_mm
        The largest feed per tooth (mm) the force and the chip limit allow at the step's
        engagement (``inf``: not limited); a step whose contact is the tool's bottom face only
        (a plunge, no force in the milling model) holds its own feed per tooth.
    torque0_nm, torque1_nm_mm
        The mean cutting torque ``T = T0 + f_z T1`` (N m, N m per mm of feed per tooth).
    segments
        The interpreted program's segments, in order.
    """

    t_s: NDArray[np.float64]
    line: NDArray[np.int64]
    tool: NDArray[np.int64]
    rapid: NDArray[np.bool_]
    contact: NDArray[np.bool_]
    tcp_mm: NDArray[np.float64]
    spindle_rpm: NDArray[np.float64]
    feed_per_tooth_mm: NDArray[np.float64]
    flutes: NDArray[np.float64]
    peak_n: NDArray[np.float64]
    mean_n: NDArray[np.float64]
    power_w: NDArray[np.float64]
    chip_mm: NDArray[np.float64]
    fz_force_mm: NDArray[np.float64]
    fz_chip_mm: NDArray[np.float64]
    torque0_nm: NDArray[np.float64]
    torque1_nm_mm: NDArray[np.float64]
    segments: tuple[Segment, ...]

    def fz_power_mm(
        self, max_power_w: float | None, rows: NDArray[np.int64], spindle_rpm: float
    ) -> NDArray[np.float64]:
        """The largest feed per tooth (mm) a power limit (W) allows at the engagement of the
        steps ``rows``, at the speed ``spindle_rpm`` (rpm); ``inf`` where not limited."""
        out = np.full(rows.size, math.inf)
        omega = spindle_rpm * _RAD_S_PER_RPM
        if max_power_w is None or omega <= 0.0:
            return out
        cut = self.contact[rows]
        t1 = self.torque1_nm_mm[rows]
        room = max_power_w / omega - self.torque0_nm[rows]
        grows = cut & (t1 > 0.0)
        out[grows] = np.maximum(room[grows], 0.0) / t1[grows]
        out[cut & ~grows & (room < 0.0)] = 0.0
        return out


def program_loads(
    segments: Sequence[Segment],
    stock: DexelStock,
    cutters: Mapping[int, Cutter],
    coefficients: CuttingCoefficients,
    limits: FeedLimits,
    *,
    rapid_mm_min: float,
    cycle_s: float,
    segment_ends: str = "all",
) -> ProgramLoads:
    """Cut the stock along the segments; the load and the feed limits of every step.

    Parameters
    ----------
    segments
        The interpreted program.
    stock
        The stock (mm), cut in place.
    cutters
        Geometry of every tool the program uses, by tool number.
    coefficients
        Cutting coefficients of the workpiece material (Pa, N/m).
    limits
        The force and chip limits solved for per step (the power limit depends on the speed
        and is solved by :meth:`ProgramLoads.fz_power_mm`).
    rapid_mm_min
        The machine's rapid rate, mm/min.
    cycle_s
        Cycle time, s.
    segment_ends
        Which segment ends are steps (:func:`~cnctwin.simulation.simulate_cut`): ``"all"``
        (every step belongs to one line: the plan) or ``"kind"`` (as ``cnctwin simulate``
        and ``cnctwin signals`` sample: the check).

    Returns
    -------
    ProgramLoads
        One row per step.

    Raises
    ------
    cnctwin.errors.NCError
        When the program moves a tool that has no geometry.
    """
    pitch_z = stock.grid.pitch_mm[2]
    found: dict[int, tuple[float, ...]] = {}

    def observe(step: CutStep) -> None:
        found[step.index] = _step_load(step, coefficients, limits, pitch_z)

    table = StepTable()
    for rows in simulate_cut(
        segments, stock, cutters, rapid_mm_min=rapid_mm_min, cycle_s=cycle_s,
        on_step=observe, segment_ends=segment_ends,
    ):  # fmt: skip
        table.append(rows)
    n = len(table)
    loads = np.zeros((n, 8))
    loads[:, 4:6] = math.inf
    if found:
        at = np.fromiter(found, dtype=np.int64, count=len(found))
        loads[at] = np.array(list(found.values()))
    tool = table.column("tool").astype(np.int64)
    flutes = np.array([float(cutters[int(t)].flutes) if int(t) in cutters else 1.0 for t in tool])
    return ProgramLoads(
        t_s=table.column("t_s"),
        line=table.column("line").astype(np.int64),
        tool=tool,
        rapid=table.column("rapid") > 0,
        contact=table.column("contact") > 0,
        tcp_mm=np.column_stack([table.column(f"{a}_mm") for a in "xyz"]),
        spindle_rpm=table.column("spindle_rpm"),
        feed_per_tooth_mm=table.column("feed_per_tooth_mm"),
        flutes=flutes,
        peak_n=loads[:, 0],
        mean_n=loads[:, 1],
        power_w=loads[:, 2],
        chip_mm=loads[:, 3],
        fz_force_mm=loads[:, 4],
        fz_chip_mm=loads[:, 5],
        torque0_nm=loads[:, 6],
        torque1_nm_mm=loads[:, 7],
        segments=tuple(segments),
    )


def _step_load(
    step: CutStep, coefficients: CuttingCoefficients, limits: FeedLimits, pitch_z_mm: float
) -> tuple[float, ...]:
    """(peak N, mean N, power W, chip mm, fz force mm, fz chip mm, T0 N m, T1 N m/mm) of a
    step in contact (module notes)."""
    fz_mm = step.feed_per_tooth_mm
    engagement = step.engagement
    chip_per_fz = engagement.h_max_mm / fz_mm if fz_mm > 0.0 else 0.0
    fz_chip = math.inf
    if limits.max_chip_mm is not None and chip_per_fz > 0.0:
        fz_chip = limits.max_chip_mm / chip_per_fz
    cut = immersion_intervals(engagement, pitch_z_mm)
    if cut is None:
        # Bottom contact only (a plunge): the milling model knows no force there, so the step
        # holds its own feed per tooth (a plunge is never sped up).
        return (0.0, 0.0, 0.0, engagement.h_max_mm, fz_mm, fz_chip, 0.0, 0.0)
    omega = step.spindle_rpm * _RAD_S_PER_RPM
    ref_m = fz_mm * 1e-3 if fz_mm > 0.0 else _FZ_REFERENCE_M
    ref_mm = ref_m * 1e3
    cutter = step.cutter
    # Two positive feeds: a tooth charges its edge force only where it cuts a chip (h > 0),
    # so the force at f_z = 0 is not the edge part B of the cut.
    full = mean_forces(cutter, coefficients, cut, ref_m, omega)
    twice = mean_forces(cutter, coefficients, cut, 2.0 * ref_m, omega)
    torque1 = (twice.torque_nm - full.torque_nm) / ref_mm
    torque0 = full.torque_nm - torque1 * ref_mm
    fz_force = math.inf
    if limits.max_force_n is not None and limits.force_metric == "mean":
        one = np.array([[full.fx_n, full.fy_n, full.fz_n]])
        a = (np.array([[twice.fx_n, twice.fy_n, twice.fz_n]]) - one) / ref_mm
        fz_force = force_feed_limit(a, one - a * ref_mm, limits.max_force_n)
    wave = milling_forces(cutter, coefficients, cut, ref_m, omega, steps=_WAVEFORM_STEPS)
    if limits.max_force_n is not None and limits.force_metric == "peak":
        more = milling_forces(cutter, coefficients, cut, 2.0 * ref_m, omega, steps=_WAVEFORM_STEPS)
        one = np.column_stack((wave.fx_n, wave.fy_n, wave.fz_n))
        a = (np.column_stack((more.fx_n, more.fy_n, more.fz_n)) - one) / ref_mm
        fz_force = force_feed_limit(a, one - a * ref_mm, limits.max_force_n)
    at_fz = fz_mm > 0.0
    return (
        float(wave.resultant_n.max()) if at_fz else 0.0,
        full.resultant_n if at_fz else 0.0,
        full.power_w if at_fz else 0.0,
        engagement.h_max_mm,
        fz_force,
        fz_chip,
        torque0,
        torque1,
    )
