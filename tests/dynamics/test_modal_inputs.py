"""fit_modes refuses a band that is not finite and a mode count above MAX_MODES."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.dynamics.frf import FRF
from cnctwin.dynamics.modal import MAX_MODES, Mode, fit_modes, modal_frf
from cnctwin.errors import CnctwinError

OMEGA = 2 * math.pi * np.arange(1.0, 3000.0)
MODE = Mode.from_mck(0.3, 150.0, 2.0e7)  # kg, N s/m, N/m: 1300 Hz
FRF_ONE_MODE = FRF(OMEGA, modal_frf(OMEGA, [MODE]), "receptance")


@pytest.mark.parametrize(
    "band", [(0.0, math.inf), (math.nan, 3000.0), (-math.inf, 3000.0), (3000.0, 300.0)]
)
def test_a_band_that_is_not_finite_and_increasing_is_refused(band: tuple[float, float]) -> None:
    with pytest.raises(CnctwinError, match="band"):
        fit_modes(FRF_ONE_MODE, 1, omega_band=band)


@pytest.mark.parametrize("n_modes", [0, -1, MAX_MODES + 1, 10**12])
def test_a_mode_count_out_of_range_is_refused(n_modes: int) -> None:
    with pytest.raises(CnctwinError, match="n_modes"):
        fit_modes(FRF_ONE_MODE, n_modes)


def test_a_finite_band_still_fits() -> None:
    fit = fit_modes(FRF_ONE_MODE, 1, omega_band=(2 * math.pi * 500, 2 * math.pi * 2500))
    assert fit.modes[0].omega_n == pytest.approx(MODE.omega_n, rel=1e-3)
