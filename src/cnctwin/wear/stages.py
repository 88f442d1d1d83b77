"""Wear stages, notifications and remaining useful life (Christiand 2024, section 6.3).

The wear curve of a tool is split into four stages (Alhadeff et al., after Christiand 2024):
I slow initial wear, II rapid initial wear, III steady-state wear, IV rapid wear before
failure. The user sets the wear at which stages II-IV begin and, optionally, when a normal
tool reaches them; a notification is raised when the estimate enters a stage, flagged as
early when that happens before the expected time. Units: wear in mm, time in s, material
removed in mm^3.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from cnctwin.errors import InputError
from cnctwin.wear.ekf import LogisticWear

__all__ = ["RemainingLife", "StageEvent", "StageMonitor", "remaining_life"]

STAGE_NAMES = (
    "I slow initial wear",
    "II rapid initial wear",
    "III steady-state wear",
    "IV rapid wear before failure",
)


@dataclass(frozen=True, slots=True)
class StageEvent:
    """The estimate entered a wear stage.

    Attributes
    ----------
    stage
        2, 3 or 4.
    time_s
        When it happened, s.
    vb_mm
        The wear estimate then, mm.
    expected_s
        When a normal tool enters this stage, s (``nan`` if not given).
    early
        True when ``time_s < expected_s``: wear runs faster than normal.
    """

    stage: int
    time_s: float
    vb_mm: float
    expected_s: float
    early: bool

    @property
    def message(self) -> str:
        """One line for the operator."""
        text = (
            f"tool entered stage {STAGE_NAMES[self.stage - 1]} at {self.time_s:.1f} s "
            f"(VB {self.vb_mm:.3f} mm)"
        )
        if self.early:
            text += f", {self.expected_s - self.time_s:.1f} s earlier than normal"
        return text


class StageMonitor:
    """Turns a stream of wear estimates into stage notifications.

    Parameters
    ----------
    boundaries_mm
        Wear at which stages II, III and IV begin, mm, strictly increasing.
    expected_entry_s
        When a normal tool enters stages II, III and IV, s; ``None`` to skip the early check.
    """

    def __init__(
        self, boundaries_mm: Sequence[float], expected_entry_s: Sequence[float] | None = None
    ) -> None:
        bounds = _floats(boundaries_mm, "boundaries_mm")
        if len(bounds) != 3 or not (0 < bounds[0] < bounds[1] < bounds[2] < math.inf):
            raise InputError(
                "boundaries_mm must be three increasing positive wear values (entry of "
                f"stages II, III, IV); got {tuple(boundaries_mm)!r}"
            )
        expected = (
            (math.nan,) * 3
            if expected_entry_s is None
            else _floats(expected_entry_s, "expected_entry_s")
        )
        if len(expected) != 3:
            raise InputError(f"expected_entry_s needs 3 times, s; got {expected_entry_s!r}")
        self.boundaries_mm = bounds
        self.expected_entry_s = expected
        self.stage = 1

    def update(self, time_s: float, vb_mm: float) -> list[StageEvent]:
        """Feed one estimate; return the stages entered (several if the wear jumped)."""
        events = []
        while self.stage < 4 and vb_mm >= self.boundaries_mm[self.stage - 1]:
            self.stage += 1
            expected = self.expected_entry_s[self.stage - 2]
            events.append(StageEvent(self.stage, time_s, vb_mm, expected, time_s < expected))
        return events


@dataclass(frozen=True, slots=True)
class RemainingLife:
    """Material (and time) left before the wear reaches a limit.

    Attributes
    ----------
    material_mm3
        Material that can still be removed, mm^3 (``inf`` if the limit is never reached).
    material_low_mm3, material_high_mm3
        The same for the estimate plus and minus ``sigmas`` standard deviations.
    time_s, time_low_s, time_high_s
        The same divided by the removal rate, s (``nan`` without a rate).
    """

    material_mm3: float
    material_low_mm3: float
    material_high_mm3: float
    time_s: float
    time_low_s: float
    time_high_s: float


def remaining_life(
    law: LogisticWear,
    vb_mm: float,
    var_mm2: float,
    limit_mm: float,
    *,
    removal_rate_mm3_s: float | None = None,
    sigmas: float = 2.0,
) -> RemainingLife:
    """Remaining useful life to a wear limit under the logistic law, with its spread.

    The material is :meth:`LogisticWear.material_to_reach_mm3` from the estimate; the band
    comes from the estimate moved by ``sigmas`` standard deviations (a more worn tool has
    less life left).

    Parameters
    ----------
    law
        Wear propagation.
    vb_mm, var_mm2
        Current estimate and its variance.
    limit_mm
        Wear limit, mm (below the law's saturation).
    removal_rate_mm3_s
        Planned material removal rate to convert material into time, mm^3/s.
    sigmas
        Width of the band in standard deviations (finite, >= 0).

    Raises
    ------
    InputError
        If ``limit_mm`` is outside (0, the law's saturation), ``vb_mm`` or ``var_mm2`` is not
        finite, or ``sigmas`` is negative or not finite.
    """
    if not (0 < limit_mm < law.vb_max_mm):
        raise InputError(f"limit_mm must lie in (0, vb_max_mm={law.vb_max_mm}); got {limit_mm!r}")
    for name, value in (("vb_mm", vb_mm), ("var_mm2", var_mm2)):
        if not math.isfinite(value):
            raise InputError(f"{name} {value!r}: give a finite estimate")
    if not (math.isfinite(sigmas) and sigmas >= 0.0):
        raise InputError(f"sigmas {sigmas!r}: give a finite number of standard deviations >= 0")
    spread = sigmas * math.sqrt(max(var_mm2, 0.0))
    floor = 1e-6 * law.vb_max_mm
    mid = law.material_to_reach_mm3(max(vb_mm, floor), limit_mm)
    low = law.material_to_reach_mm3(max(vb_mm + spread, floor), limit_mm)
    high = law.material_to_reach_mm3(max(vb_mm - spread, floor), limit_mm)
    if removal_rate_mm3_s is None or removal_rate_mm3_s <= 0:
        times = (math.nan, math.nan, math.nan)
    else:
        times = (mid / removal_rate_mm3_s, low / removal_rate_mm3_s, high / removal_rate_mm3_s)
    return RemainingLife(mid, low, high, *times)


def _floats(values: Sequence[float], name: str) -> tuple[float, ...]:
    """``values`` as a tuple of floats; InputError naming ``name`` when one is not a number."""
    try:
        return tuple(float(v) for v in values)
    except (TypeError, ValueError):
        raise InputError(f"{name} {values!r}: give a sequence of numbers") from None
