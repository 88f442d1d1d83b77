"""The packaged materials library: every entry cited, values as published."""

from __future__ import annotations

from pathlib import Path

import pytest

from cnctwin.errors import ConfigError
from cnctwin.mechanics.materials import (
    kienzle_material,
    kienzle_materials,
    milling_material,
    milling_materials,
)


def test_aa6060_is_royandi_2026_section_4_2() -> None:
    k = milling_material("AA6060-T6").coefficients.to_n_mm()
    assert k["ktc_n_mm2"] == pytest.approx(745.1)
    assert k["krc_n_mm2"] == pytest.approx(360.98)
    assert k["kte_n_mm"] == pytest.approx(31.49)
    assert k["kre_n_mm"] == pytest.approx(21.85)


@pytest.mark.validation
def test_aa6060_values_appear_in_the_paper(shared_data: Path) -> None:
    # The seed paper's text (section 4.2) carries the four numbers.
    paper = shared_data.parent / "papers" / "royandi2026_milling_vibration_roughness.txt"
    if not paper.is_file():
        pytest.skip(f"{paper} is absent")
    text = paper.read_text(encoding="utf-8")
    for number in ("745.1", "360.98", "31.49", "21.85"):
        assert number in text


def test_every_entry_names_its_source() -> None:
    for entry in [*milling_materials().values(), *kienzle_materials().values()]:
        assert len(entry.source) > 40, entry.name
    for entry in kienzle_materials().values():
        assert 0.0 < entry.mc < 1.0
        assert 5e8 < entry.kc11_pa < 4e9


def test_kienzle_entries_requested_by_the_issue() -> None:
    names = set(kienzle_materials())
    assert {"C45", "42CrMo4", "16MnCr5", "S235JR"} <= names
    assert any("alumin" in n.lower() for n in names) and "GG-26" in names
    # Kienzle & Victor (1957): C45 kc1.1 = 2220 N/mm^2 with 1 - mc = 0.86.
    c45 = kienzle_material("c45")
    assert (c45.kc11_pa, 1 - c45.mc) == pytest.approx((2220e6, 0.86))


def test_unknown_names_list_the_valid_ones() -> None:
    with pytest.raises(ConfigError, match="AA6060-T6"):
        milling_material("unobtainium")
    with pytest.raises(ConfigError, match="C45"):
        kienzle_material("unobtainium")
