"""Machining event signals that gate the spindle drive (Christiand 2024, Eq. 15-18).

* spindle ``phi`` (Eq. 16): 1 while the spindle is on;
* feed ``psi`` (Eq. 17): 1 while the feed drives move;
* contact ``kappa`` (Eq. 18): 1 while the tool is in contact with the workpiece, which the paper
  detects as a tool-workpiece collision volume ``V_c > 1 um^3``.

The cutting torque reaches the rotor only when all three are 1 (Eq. 15: ``T_cut kappa psi phi``);
the spindle signal also switches the drive itself (see :mod:`cnctwin.drives.spindle`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cnctwin.errors import DataError

__all__ = [
    "CONTACT_VOLUME_THRESHOLD_M3",
    "EventState",
    "MachiningEvents",
    "contact_from_collision_volume",
]

CONTACT_VOLUME_THRESHOLD_M3 = 1e-18
"""Collision volume above which tool and workpiece are in contact: 1 um^3.

Christiand 2024, Eq. 18."""

Interval = tuple[float, float]


@dataclass(frozen=True, slots=True)
class EventState:
    """The three event signals at one instant (Christiand 2024, Eq. 16-18).

    Attributes
    ----------
    spindle_on
        Spindle signal ``phi``.
    feed_on
        Feed signal ``psi``.
    in_contact
        Contact signal ``kappa``.
    """

    spindle_on: bool = True
    feed_on: bool = True
    in_contact: bool = True

    @property
    def load_gate(self) -> float:
        """``kappa psi phi`` (Eq. 15): 1.0 when the cutting torque acts, else 0.0."""
        return float(self.spindle_on and self.feed_on and self.in_contact)


def _flags(name: str, value: ArrayLike, n: int | None) -> NDArray[np.bool_]:
    arr = np.asarray(value)
    if arr.ndim != 1 or (n is not None and arr.shape[0] != n):
        want = "1-D" if n is None else f"shape ({n},)"
        raise DataError(f"{name} has shape {arr.shape}; it must be {want}")
    if arr.dtype != np.bool_ and not np.all((arr == 0) | (arr == 1)):
        raise DataError(f"{name} has values other than 0/1 or False/True")
    return arr.astype(np.bool_)


@dataclass(frozen=True, slots=True, eq=False)
class MachiningEvents:
    """Event signals sampled on a time grid, one boolean per sample and signal.

    Parameters
    ----------
    spindle_on
        Spindle signal ``phi`` (Eq. 16).
    feed_on
        Feed signal ``psi`` (Eq. 17).
    in_contact
        Contact signal ``kappa`` (Eq. 18).

    Raises
    ------
    DataError
        If the arrays are not 1-D booleans (or 0/1) of one length.
    """

    spindle_on: NDArray[np.bool_]
    feed_on: NDArray[np.bool_]
    in_contact: NDArray[np.bool_]

    def __post_init__(self) -> None:
        spindle = _flags("spindle_on", self.spindle_on, None)
        n = spindle.shape[0]
        object.__setattr__(self, "spindle_on", spindle)
        object.__setattr__(self, "feed_on", _flags("feed_on", self.feed_on, n))
        object.__setattr__(self, "in_contact", _flags("in_contact", self.in_contact, n))

    def __len__(self) -> int:
        return int(self.spindle_on.shape[0])

    def load_gate(self) -> NDArray[np.float64]:
        """``kappa psi phi`` per sample (Eq. 15): 1.0 where the cutting torque acts, else 0.0."""
        return (self.spindle_on & self.feed_on & self.in_contact).astype(np.float64)

    def at(self, k: int) -> EventState:
        """The signals at sample ``k``."""
        return EventState(bool(self.spindle_on[k]), bool(self.feed_on[k]), bool(self.in_contact[k]))

    @classmethod
    def constant(
        cls, n: int, spindle_on: bool = True, feed_on: bool = True, in_contact: bool = True
    ) -> MachiningEvents:
        """``n`` samples of constant signals (default: all on)."""
        return cls(np.full(n, spindle_on), np.full(n, feed_on), np.full(n, in_contact))

    @classmethod
    def from_intervals(
        cls,
        t_s: ArrayLike,
        spindle_s: Sequence[Interval] = (),
        feed_s: Sequence[Interval] = (),
        contact_s: Sequence[Interval] = (),
    ) -> MachiningEvents:
        """Signals that are on during the given time intervals and off elsewhere.

        Parameters
        ----------
        t_s
            Sample times, s (1-D).
        spindle_s, feed_s, contact_s
            ``(start, end)`` intervals in s, each half-open ``start <= t < end``, for the
            spindle, feed and contact signals.

        Returns
        -------
        MachiningEvents
            The three signals on the grid ``t_s``.
        """
        t = np.asarray(t_s, dtype=np.float64)
        if t.ndim != 1:
            raise DataError(f"t_s has shape {t.shape}; it must be 1-D")

        def on_during(name: str, intervals: Sequence[Interval]) -> NDArray[np.bool_]:
            flags = np.zeros(t.shape, dtype=np.bool_)
            for start, end in intervals:
                if not (np.isfinite(start) and end >= start):
                    raise DataError(f"{name} interval ({start!r}, {end!r}); it needs start <= end")
                flags |= (t >= start) & (t < end)
            return flags

        return cls(
            on_during("spindle_s", spindle_s),
            on_during("feed_s", feed_s),
            on_during("contact_s", contact_s),
        )


def contact_from_collision_volume(
    volume_m3: ArrayLike, threshold_m3: float = CONTACT_VOLUME_THRESHOLD_M3
) -> NDArray[np.bool_]:
    """Contact signal from the tool-workpiece collision volume (Christiand 2024, Eq. 18).

    Parameters
    ----------
    volume_m3
        Collision (intersection) volume of tool and workpiece, m^3.
    threshold_m3
        Volume above which they are in contact, m^3 (default 1 um^3, as in the paper).

    Returns
    -------
    numpy.ndarray of bool
        ``kappa``: True where ``volume_m3 > threshold_m3``.
    """
    return np.asarray(volume_m3, dtype=np.float64) > threshold_m3
