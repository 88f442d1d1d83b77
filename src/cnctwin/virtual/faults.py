"""Fault and anomaly injection for the virtual machine.

* **Tool breakage** (:class:`~cnctwin.virtual.config.ToolBreakageFault`): at a time or program
  line the tool in the spindle loses ``lost_length_mm`` from its tip (default its whole fluted
  length). The machine goes on: it cuts its stock with the shortened tool, so the forces and the
  spindle load collapse where the stub no longer reaches the material.
* **Hole in the blank** (:class:`~cnctwin.virtual.config.HoleFault`): a box or a vertical
  cylinder of material is missing from the machine's own dexel stock (not from the twin's), so
  the forces drop to zero where the tool crosses it (Heide 2025, use case 1).
* **Accelerated wear** (:class:`~cnctwin.virtual.config.WearFault`): the cutting forces and
  torque are scaled by ``1 + g t_cut`` (``t_cut`` minutes of cutting since the start, ``g`` the
  growth per minute, capped at ``max_scale``); or, with a flank-wear rate, the tool carries a
  true flank wear VB that grows with the time in contact, and its wear land adds a rubbing
  torque to the spindle (:meth:`FaultInjector.rubbing_torque_nm`).
* **Chatter** (:class:`~cnctwin.virtual.config.ChatterFault`): a force rotating in the XY
  plane at the chatter frequency, ``amplitude_ratio`` times the mean force magnitude, is added to
  the forces while the tool cuts.

Units: mm, s, N (names say so); torque N m.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cnctwin.config import BoxStock
from cnctwin.geometry import AXES, DexelGrid, DexelStock, Engagement
from cnctwin.virtual.config import (
    ChatterFault,
    FaultConfig,
    HoleFault,
    ToolBreakageFault,
    WearFault,
)

__all__ = ["FaultEvent", "FaultInjector", "blank_with_holes"]

logger = logging.getLogger(__name__)

# Ray axis and transverse axes (x, y, z indices) of each dexel family (see geometry.dexel).
_FAMILY_AXES = {"z": (2, 0, 1), "x": (0, 1, 2), "y": (1, 0, 2)}

#: Flank wear at which the virtual tool's wear stops growing, mm (a land this wide is a
#: broken edge; it keeps the tangent law finite).
_VB_HELD_MM = 2.0


@dataclass(frozen=True, slots=True)
class FaultEvent:
    """A fault that became active.

    Attributes
    ----------
    t_s
        Machine time, s.
    kind
        ``"breakage"``, ``"wear"`` or ``"chatter"`` (holes are there from the start).
    line
        Program line executing at that time.
    detail
        One line for a log.
    """

    t_s: float
    kind: str
    line: int
    detail: str


def _hole_intervals(
    hole: HoleFault, axis: str, coords: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where the rays of a family cross a hole: (start, end) along the ray, mm; NaN if not."""
    ray, a, b = _FAMILY_AXES[axis]
    u, v = coords[:, 0], coords[:, 1]
    nan = np.full(u.shape, np.nan)
    if hole.shape == "box":
        assert hole.min_mm is not None and hole.max_mm is not None  # checked by the model
        lo, hi = hole.min_mm, hole.max_mm
        inside = (u >= lo[a]) & (u <= hi[a]) & (v >= lo[b]) & (v <= hi[b])
        return np.where(inside, lo[ray], nan), np.where(inside, hi[ray], nan)
    assert hole.center_mm is not None and hole.radius_mm is not None and hole.z_mm is not None
    cx, cy = hole.center_mm
    r = hole.radius_mm
    z0, z1 = hole.z_mm
    if axis == "z":  # u = x, v = y
        inside = (u - cx) ** 2 + (v - cy) ** 2 <= r * r
        return np.where(inside, z0, nan), np.where(inside, z1, nan)
    # x rays at (y, z), y rays at (x, z): a chord of the circle where z is inside the hole.
    offset = u - (cy if axis == "x" else cx)
    half2 = r * r - offset**2
    inside = (half2 >= 0.0) & (v >= z0) & (v <= z1)
    half = np.sqrt(np.where(inside, half2, 0.0))
    centre = cx if axis == "x" else cy
    return np.where(inside, centre - half, nan), np.where(inside, centre + half, nan)


def blank_with_holes(
    stock: BoxStock, density_per_mm: float, holes: Sequence[HoleFault]
) -> DexelStock:
    """The blank of the virtual machine: a box of stock with holes (material missing).

    Parameters
    ----------
    stock
        The box, machine coordinates, mm.
    density_per_mm
        Dexels per mm.
    holes
        Boxes and vertical cylinders of missing material, machine coordinates, mm.

    Returns
    -------
    DexelStock
        The tri-dexel blank; along every ray the box's interval less the holes' intervals
        (closed form per ray, loaded with :meth:`DexelStock.load`).
    """
    if not holes:
        return DexelStock.box(stock.min_mm, stock.max_mm, density_per_mm)
    grid = DexelGrid.from_box(stock.min_mm, stock.max_mm, density_per_mm)
    blank = DexelStock(grid)
    for axis in AXES:
        ray = _FAMILY_AXES[axis][0]
        lo, hi = grid.origin_mm[ray], grid.origin_mm[ray] + grid.size_mm[ray]
        coords = grid.ray_coordinates_mm(axis)
        n = coords.shape[0]
        cuts = [_hole_intervals(hole, axis, coords) for hole in holes]
        starts = np.column_stack([c[0] for c in cuts])
        ends = np.column_stack([c[1] for c in cuts])
        hit = np.flatnonzero(np.any(np.isfinite(starts), axis=1))
        counts = np.ones(n, dtype=np.int64)
        pieces: dict[int, list[tuple[float, float]]] = {}
        for r in hit.tolist():
            material = [(lo, hi)]
            for a, b in zip(starts[r], ends[r], strict=True):
                if not math.isfinite(a):
                    continue
                material = [
                    piece
                    for s, e in material
                    for piece in ((s, min(e, a)), (max(s, b), e))
                    if piece[1] > piece[0]
                ]
            pieces[r] = material
            counts[r] = len(material)
        intervals = np.empty((int(counts.sum()), 2))
        first = np.cumsum(counts) - counts
        plain = np.setdiff1d(np.arange(n), hit, assume_unique=True)
        intervals[first[plain]] = (lo, hi)
        for r, material in pieces.items():
            if material:
                intervals[first[r] : first[r] + len(material)] = material
        blank.load(axis, counts, intervals)
    logger.info(
        "blank with %d hole(s): %.1f mm^3 of %.1f mm^3 missing",
        len(holes),
        np.prod(np.subtract(stock.max_mm, stock.min_mm)) - blank.volume_mm3(),
        float(np.prod(np.subtract(stock.max_mm, stock.min_mm))),
    )
    return blank


class FaultInjector:
    """The timed faults of a virtual machine (breakage, wear, chatter) and their state.

    Parameters
    ----------
    faults
        The ``[[virtual.faults]]`` entries; holes are ignored here (they shape the blank,
        :func:`blank_with_holes`).
    """

    def __init__(self, faults: Sequence[FaultConfig]) -> None:
        self._pending: list[ToolBreakageFault | WearFault | ChatterFault] = [
            f for f in faults if not isinstance(f, HoleFault)
        ]
        self._wear: list[tuple[WearFault, list[float]]] = []  # fault, [cut time s]
        self._chatter: list[ChatterFault] = []
        self._broken: dict[int, float | None] = {}  # tool -> lost length (None: whole flutes)
        self.events: list[FaultEvent] = []

    def update(self, t_s: float, line: int, tool: int, dt_s: float, cutting: bool) -> None:
        """Start the faults due at machine time ``t_s`` (s) or program ``line``; count cut time.

        Parameters
        ----------
        t_s
            Machine time at the end of the tick, s.
        line
            Program line executing.
        tool
            Tool in the spindle.
        dt_s
            Length of the tick, s.
        cutting
            Whether the tool cut material during the tick.
        """
        if self._pending:
            due = [
                f
                for f in self._pending
                if (f.at_s is not None and t_s >= f.at_s)
                or (f.at_line is not None and line == f.at_line)
                or (f.at_s is None and f.at_line is None)
            ]
            for fault in due:
                self._pending.remove(fault)
                self._start(fault, t_s, line, tool)
        if cutting:
            for _, cut_time in self._wear:
                cut_time[0] += dt_s

    def _start(
        self, fault: ToolBreakageFault | WearFault | ChatterFault, t_s: float, line: int, tool: int
    ) -> None:
        if isinstance(fault, ToolBreakageFault):
            self._broken[tool] = fault.lost_length_mm
            lost = (
                "its fluted length"
                if fault.lost_length_mm is None
                else (f"{fault.lost_length_mm} mm")
            )
            detail = f"tool T{tool} broke: lost {lost}"
        elif isinstance(fault, WearFault):
            self._wear.append((fault, [0.0]))
            detail = f"accelerated wear: +{fault.load_growth_per_min:g}/min of cutting"
            if fault.vb_rate_mm_min is not None:
                detail += (
                    f", flank wear from {fault.vb0_mm:g} mm at {fault.vb_rate_mm_min:g} mm/min"
                )
        else:
            self._chatter.append(fault)
            detail = f"chatter at {fault.frequency_hz:g} Hz, {fault.amplitude_ratio:g} x force"
        event = FaultEvent(t_s, fault.kind, line, detail)
        self.events.append(event)
        logger.info("t=%.4f s line %d: %s", t_s, line, detail)

    def lost_length_mm(self, tool: int, flute_length_mm: float) -> float:
        """Length (mm) missing from the tip of ``tool``: 0 if intact."""
        if tool not in self._broken:
            return 0.0
        lost = self._broken[tool]
        return flute_length_mm if lost is None else min(lost, flute_length_mm)

    def load_scale(self) -> float:
        """Factor on the cutting forces and torque from accelerated wear (1: none)."""
        scale = 1.0
        for fault, cut_time in self._wear:
            scale *= min(1.0 + fault.load_growth_per_min * cut_time[0] / 60.0, fault.max_scale)
        return scale

    def flank_wear_mm(self) -> float:
        """The tool's true flank wear VB, mm (0 without a flank-wear fault; the largest of
        several).

        ``dVB/dt = r (1 + (VB/VBref)^2)`` over the minutes in contact ``t`` integrates to
        ``VB = VBref tan(atan(VB0/VBref) + r t / VBref)``, held at 2 mm.
        """
        wear = 0.0
        for fault, cut_time in self._wear:
            if fault.vb_rate_mm_min is None:
                continue
            ref = fault.vb_ref_mm
            angle = math.atan(fault.vb0_mm / ref) + fault.vb_rate_mm_min * cut_time[0] / 60.0 / ref
            held = math.atan(_VB_HELD_MM / ref)
            wear = max(wear, _VB_HELD_MM if angle >= held else ref * math.tan(angle))
        return wear

    def rubbing_torque_nm(self, engagement: Engagement, flutes: int) -> float:
        """Mean spindle torque the flank wear land adds over a revolution, N m.

        The tangential edge force per mm of engaged edge grows by ``k VB`` (N/mm,
        ``k = edge_force_n_mm2``): the edge-force term of the mechanistic model (Altintas 2012,
        ch. 2) with a worn edge. Over a revolution each of the ``flutes`` teeth spends the
        contact angles ``phi`` of every slice (height ``dz``, radius ``r``) in the cut, so the
        mean torque is ``flutes / (2 pi) * sum(k VB phi dz r)`` (N mm).
        """
        rubbing = 0.0
        for fault, _ in self._wear:
            if fault.vb_rate_mm_min is not None:
                rubbing = max(rubbing, fault.edge_force_n_mm2)
        if rubbing == 0.0 or not engagement.contact or engagement.interval_slice.size == 0:
            return 0.0
        k = engagement.interval_slice
        angle = engagement.interval_end_rad - engagement.interval_start_rad
        arm = float(np.sum(angle * engagement.slice_dz_mm[k] * engagement.slice_radius_mm[k]))
        return flutes / (2.0 * math.pi) * rubbing * self.flank_wear_mm() * arm * 1e-3

    def vibration_n(self, t_s: float, force_n: float) -> tuple[float, float]:
        """Chatter force (x, y) in N at machine time ``t_s`` (s) for a mean force of ``force_n``."""
        fx = fy = 0.0
        for fault in self._chatter:
            if fault.until_s is not None and t_s > fault.until_s:
                continue
            phase = 2.0 * math.pi * fault.frequency_hz * t_s
            amplitude = fault.amplitude_ratio * force_n
            fx += amplitude * math.cos(phase)
            fy += amplitude * math.sin(phase)
        return fx, fy
