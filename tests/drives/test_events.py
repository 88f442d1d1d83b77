"""Machining event signals (Christiand 2024, Eq. 15-18)."""

from __future__ import annotations

import numpy as np
import pytest

from cnctwin.drives import EventState, MachiningEvents, contact_from_collision_volume
from cnctwin.errors import DataError


def test_intervals_are_half_open_and_gate_is_the_product() -> None:
    t = np.arange(0.0, 1.0, 0.1)
    ev = MachiningEvents.from_intervals(
        t, spindle_s=[(0.0, 0.8)], feed_s=[(0.2, 0.7)], contact_s=[(0.3, 0.5), (0.6, 1.0)]
    )
    # Sample times 0.0 ... 0.9; each interval includes its start and excludes its end.
    assert ev.spindle_on.tolist() == [True] * 8 + [False] * 2
    assert ev.feed_on.tolist() == [False] * 2 + [True] * 5 + [False] * 3
    expected_gate = [0, 0, 0, 1, 1, 0, 1, 0, 0, 0]  # kappa psi phi, Eq. 15
    assert ev.load_gate().tolist() == expected_gate
    assert len(ev) == 10
    assert ev.at(3) == EventState(True, True, True)
    assert ev.at(5).load_gate == 0.0


def test_contact_from_collision_volume_uses_one_cubic_micrometre() -> None:
    # Eq. 18: kappa = 1 for V_c > 1 um^3 = 1e-18 m^3.
    volumes = np.array([0.0, 0.5e-18, 1e-18, 1.01e-18, 1e-12])
    assert contact_from_collision_volume(volumes).tolist() == [False, False, False, True, True]


def test_bad_signals_raise() -> None:
    with pytest.raises(DataError, match="feed_on"):
        MachiningEvents(np.ones(3, bool), np.ones(4, bool), np.ones(3, bool))
    with pytest.raises(DataError, match="0/1"):
        MachiningEvents(np.array([0, 2, 1]), np.ones(3), np.ones(3))
    with pytest.raises(DataError, match="start <= end"):
        MachiningEvents.from_intervals([0.0, 1.0], spindle_s=[(1.0, 0.5)])
