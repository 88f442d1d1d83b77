"""Coefficient identification (Altintas' linear regression of mean forces)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cnctwin.errors import DataError
from cnctwin.geometry import Cutter
from cnctwin.mechanics import (
    CuttingCoefficients,
    ImmersionIntervals,
    immersion_angles,
    milling_forces,
)
from cnctwin.mechanics.identification import identify_coefficients

TRUE = CuttingCoefficients.from_n_mm(700.0, 250.0, 120.0, 20.0, 15.0, 8.0)
FEEDS = np.array([0.02, 0.04, 0.06, 0.08, 0.10]) * 1e-3


def _waveform_means(cutter: Cutter, cut: ImmersionIntervals) -> np.ndarray:
    means = []
    for c in FEEDS:
        m = milling_forces(cutter, TRUE, cut, c, 600.0, steps=720).mean()
        means.append((m.fx_n, m.fy_n, m.fz_n))
    return np.array(means)


@pytest.mark.parametrize(("width", "down"), [(0.010, False), (0.005, True), (0.003, False)])
def test_recovers_the_coefficients_of_simulated_cuts(width: float, down: bool) -> None:
    # Means taken from simulated waveforms (helix, 40 slices, 720 angles), not from the closed
    # form that the identification inverts: the coefficients come back within 0.5 %.
    cutter = Cutter.flat(10.0, 20.0, flutes=3, helix_rad=0.5)
    cut = ImmersionIntervals.from_depths(cutter, width, 0.002, down_milling=down, slices=40)
    entry, exit_ = immersion_angles(0.010, width, down)
    fit = identify_coefficients(
        FEEDS, _waveform_means(cutter, cut), teeth=3, depth_m=0.002, entry_rad=entry, exit_rad=exit_
    )
    np.testing.assert_allclose(fit.coefficients.as_array(), TRUE.as_array(), rtol=5e-3)
    assert np.all(fit.r_squared > 0.9999)
    assert np.all(np.abs(fit.relative_residuals) < 1e-3)


def test_slot_fit_is_the_textbook_regression() -> None:
    # Altintas 2012, ch. 2, slot: Ktc = 4 a1y / (N a), Kte = pi a0y / (N a),
    # Krc = -4 a1x / (N a), Kre = -pi a0x / (N a), with Fz = -Fa: Kac = -pi a1z / (N a),
    # Kae = -2 a0z / (N a). Noisy forces: the fit still follows those formulas.
    rng = np.random.default_rng(7)
    cutter = Cutter.flat(12.0, 20.0, flutes=2, helix_rad=0.5)
    forces = _waveform_means(cutter, ImmersionIntervals.from_angles(0.0, math.pi, 0.003, slices=30))
    forces += rng.normal(0.0, 2.0, forces.shape)
    fit = identify_coefficients(FEEDS, forces, teeth=2, depth_m=0.003)
    (a1x, a1y, a1z), (a0x, a0y, a0z) = fit.slopes_n_m, fit.intercepts_n
    na = 2 * 0.003
    expected = [4 * a1y / na, -4 * a1x / na, -math.pi * a1z / na]
    expected += [math.pi * a0y / na, -math.pi * a0x / na, -2 * a0z / na]
    np.testing.assert_allclose(fit.coefficients.as_array(), expected, rtol=1e-10)
    # Goodness of fit: R^2 from its definition, residuals that sum to zero per axis.
    res = fit.residuals_n
    r2 = 1 - np.sum(res**2, axis=0) / np.sum((forces - forces.mean(axis=0)) ** 2, axis=0)
    np.testing.assert_allclose(fit.r_squared, r2)
    np.testing.assert_allclose(res.sum(axis=0), 0.0, atol=1e-9)
    assert np.all(fit.r_squared < 1.0)


@pytest.mark.parametrize(
    ("feeds", "forces"),
    [
        (np.array([0.05e-3]), np.zeros((1, 3))),
        (np.array([0.05e-3, 0.05e-3]), np.zeros((2, 3))),
        (np.array([0.05e-3, 0.1e-3]), np.zeros((3, 3))),
        (np.array([0.05e-3, -0.1e-3]), np.zeros((2, 3))),
    ],
)
def test_underdetermined_data_is_a_data_error(feeds: np.ndarray, forces: np.ndarray) -> None:
    with pytest.raises(DataError):
        identify_coefficients(feeds, forces, teeth=2, depth_m=0.003)
