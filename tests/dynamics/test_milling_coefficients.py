"""Which cutting coefficients a stability file gives a milling roadmap: its own, else a
fallback material's (the machining configuration's ``[material]``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from cnctwin.dynamics import StabilityConfig, load_stability_config
from cnctwin.errors import ConfigError
from cnctwin.mechanics.materials import milling_materials

MODES = [{"direction": "x", "fn_hz": 922.0, "damping_ratio": 0.011, "stiffness_n_m": 1.34e6}]


def stability(**cut: Any) -> StabilityConfig:
    return StabilityConfig.model_validate({"modes": MODES, "cut": {"teeth": 2, **cut}})


def test_the_files_own_coefficients_win_over_the_fallback() -> None:
    names = list(milling_materials())
    own, fallback = names[0], names[1]
    chosen = stability(material=own).milling_coefficients(fallback)
    assert chosen == milling_materials()[own].coefficients
    given = stability(ktc_n_mm2=600.0, krc_n_mm2=200.0).milling_coefficients(fallback)
    # N/mm^2 to N/m^2: 600 N/mm^2 = 6e8 Pa (Insperger and Stepan 2004's slot).
    assert (given.ktc, given.krc) == pytest.approx((6.0e8, 2.0e8))


def test_without_coefficients_the_fallback_material_is_used() -> None:
    for name, entry in milling_materials().items():
        assert stability().milling_coefficients(name) == entry.coefficients


def test_refusals_say_what_to_give() -> None:
    with pytest.raises(ConfigError, match="'no-such-alloy' is not in the library; give cut.mat"):
        stability().milling_coefficients("no-such-alloy")
    with pytest.raises(ConfigError, match="give either material or both ktc_n_mm2 and krc_n"):
        stability(ktc_n_mm2=600.0).milling_coefficients(next(iter(milling_materials())))


def test_an_orthogonal_cut_has_no_milling_coefficients() -> None:
    example = Path(__file__).parents[2] / "examples" / "stability" / "orthogonal_2dof.toml"
    turning = load_stability_config(example)
    with pytest.raises(ConfigError, match="cut.operation is 'orthogonal'; a roadmap needs mill"):
        turning.milling_coefficients(next(iter(milling_materials())))
