"""The materials library as a process engineer uses it: every entry sourced, the schema checked
with one-line errors, a user's own file, and the Kienzle-to-milling conversion against closed
forms (docs/materials.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cnctwin.errors import ConfigError
from cnctwin.geometry import Cutter
from cnctwin.mechanics import ImmersionIntervals, identify_coefficients, mean_forces
from cnctwin.mechanics.materials import (
    kienzle_milling_coefficients,
    load_materials,
    milling_entry_toml,
    packaged_materials,
)

REPO = Path(__file__).resolve().parents[2]
MEANS = REPO / "examples" / "materials" / "kistler_slot_means.csv"


def test_every_entry_states_source_conditions_and_checked_flag() -> None:
    library = packaged_materials()
    assert len(library.milling) >= 13 and len(library.kienzle) >= 6
    for entry in [*library.milling.values(), *library.kienzle.values()]:
        assert len(entry.source) > 40, entry.name
        assert len(entry.conditions) > 20, entry.name
        assert isinstance(entry.checked, bool), entry.name
    for entry in library.milling.values():
        k = entry.coefficients
        assert k.ktc > 0.0 and all(math.isfinite(v) for v in k.as_array()), entry.name
        if entry.derived:
            # A Kienzle entry gives the cutting force only: nothing radial or axial.
            assert (k.krc, k.kac, k.kre, k.kae) == (0.0, 0.0, 0.0, 0.0), entry.name
            assert "Kienzle" in entry.derived and "h_ref" in entry.derived, entry.name


def test_second_hand_values_are_flagged_and_keep_the_printed_numbers() -> None:
    library = packaged_materials()
    # Table 5 of the 2021 CJME review of aluminium milling force models, as printed there
    # (Ktc, Krc, Kac in N/mm^2; Kte, Kre, Kae in N/mm): row [190] and row [189].
    printed = {
        "AA7075-T6": (767.01, 168.8, 222.0, 27.7, 26.6, 0.7),
        "AA6082-T6": (631.0, 99.0, 273.0, 13.0, 10.0, 2.8),
        "AA6061-T6": (243.77, 113.5, 0.0, 7.53, 7.83, 0.0),
    }
    for name, values in printed.items():
        entry = library.milling_material(name)
        assert entry.coefficients.to_n_mm() == pytest.approx(
            dict(zip(entry.coefficients.to_n_mm(), values, strict=True))
        )
        assert not entry.checked and "10.1186/s10033-021-00536-9" in entry.source
    assert all(not k.checked for k in library.kienzle.values())


def test_the_conversion_is_kienzles_tangent_at_the_reference_thickness() -> None:
    # Kienzle: Fc/b = kc1.1 h^(1 - mc) (h in mm, N/mm). The linear model Ktc h + Kte must equal
    # it and its slope at h_ref, and stay within 6 % from h_ref/2 to 2 h_ref for mc <= 0.3.
    for entry in packaged_materials().kienzle.values():
        kc11, mc = entry.kc11_pa / 1e6, entry.mc
        for h_ref in (0.05, 0.1, 0.2):
            k = kienzle_milling_coefficients(entry.kc11_pa, mc, h_ref * 1e-3).to_n_mm()
            ktc, kte = k["ktc_n_mm2"], k["kte_n_mm"]
            assert ktc * h_ref + kte == pytest.approx(kc11 * h_ref ** (1 - mc), rel=1e-12)
            assert ktc == pytest.approx((1 - mc) * kc11 * h_ref**-mc, rel=1e-12)
            for h in np.linspace(h_ref / 2, 2 * h_ref, 31):
                kienzle = kc11 * h ** (1 - mc)
                assert abs((ktc * h + kte) / kienzle - 1) < 0.06, (entry.name, h)


def test_a_derived_entry_gives_kienzles_torque_in_a_slot_at_the_mean_chip_thickness() -> None:
    # Independent closed form: a slot's mean chip thickness is hm = 2 fz / pi; with Kienzle's
    # specific force at hm, each of N teeth is engaged half a turn with a mean cutting force
    # kc1.1 hm^(1 - mc) ap, so the mean torque is T = R N ap kc1.1 hm^(1 - mc) / 2.
    library = packaged_materials()
    c45 = library.kienzle_material("C45")
    derived = library.milling_material("C45-kienzle")
    h_ref_mm = 0.1
    fz_mm = h_ref_mm * math.pi / 2  # hm = h_ref
    diameter_mm, teeth, ap_mm = 16.0, 4, 2.0
    cutter = Cutter.flat(diameter_mm, 20.0, flutes=teeth, helix_rad=math.radians(30))
    cut = ImmersionIntervals.from_depths(cutter, diameter_mm * 1e-3, ap_mm * 1e-3, slices=40)
    mean = mean_forces(cutter, derived.coefficients, cut, fz_mm * 1e-3, 600.0)
    kc11_n_mm2 = c45.kc11_pa / 1e6
    force_n = kc11_n_mm2 * h_ref_mm ** (1 - c45.mc) * ap_mm  # per engaged tooth
    torque_nm = (diameter_mm / 2) * 1e-3 * teeth * force_n / 2
    assert mean.torque_nm == pytest.approx(torque_nm, rel=1e-6)
    assert mean.power_w == pytest.approx(torque_nm * 600.0, rel=1e-6)


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "mine.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_a_user_file_adds_entries_and_may_derive_from_its_own_kienzle(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        """
[kienzle."my-steel"]
kc11_n_mm2 = 2000
mc = 0.25
source = "Shop measurements, lathe 3, 2026 (turning, CNMG insert, 200 m/min)."
[milling."my-steel-mill"]
from_kienzle = "my-steel"
h_ref_mm = 0.08
[milling."my-alu"]
ktc_n_mm2 = 700
krc_n_mm2 = 210
source = "Our own dynamometer tests."
conditions = "3-flute carbide, 12 mm, 18000 rpm"
""",
    )
    library = load_materials(path)
    assert set(packaged_materials().milling) < set(library.milling)
    mine = library.milling_material("MY-ALU")
    assert mine.coefficients.ktc == pytest.approx(7e8) and mine.checked is False
    derived = library.milling_material("my-steel-mill")
    expected = kienzle_milling_coefficients(2000e6, 0.25, 0.08e-3)
    assert derived.coefficients == expected
    assert derived.source.startswith("Shop measurements")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (
            '[milling.x]\nktc_n_mm2 = 8e8\nkrc_n_mm2 = 1\nsource = "s"',
            r"\[milling\.\"x\"\] ktc_n_mm2 = 800000000\.0; give 0 < ktc_n_mm2 <= 20000 N/mm\^2",
        ),
        (
            '[milling.x]\nktc_n_mm2 = 800\nkrc_n_mm2 = "300"\nsource = "s"',
            r"krc_n_mm2 = '300' is not a number; give -20000 <= krc_n_mm2 <= 20000 N/mm\^2",
        ),
        (
            '[milling.x]\nktc_n_mm2 = 800\nkrc_n_mm2 = 300\nkte_n_mm = 5e4\nsource = "s"',
            r"kte_n_mm = 50000\.0; give -1000 <= kte_n_mm <= 1000 N/mm",
        ),
        ("[milling.x]\nktc_n_mm2 = 800\nkrc_n_mm2 = 300", r"misses 'source'"),
        (
            '[milling.x]\nktc_n_mm2 = 800\nkrc_n_mm2 = 300\nsource = "s"\nktc = 1',
            r"unknown key 'ktc'; valid keys: ktc_n_mm2",
        ),
        (
            '[milling.x]\nktc_n_mm2 = 800\nkrc_n_mm2 = 300\nsource = "s"\nchecked = "yes"',
            r"checked = 'yes'; give true or false",
        ),
        ('[kienzle.x]\nkc11_n_mm2 = 1800\nmc = 1.2\nsource = "s"', r"mc = 1\.2; give 0 <= mc"),
        (
            '[milling.x]\nfrom_kienzle = "nothing"\nh_ref_mm = 0.1',
            r"from_kienzle: no Kienzle material 'nothing'; valid: S235JR",
        ),
        ('[milling.x]\nfrom_kienzle = "C45"\nh_ref_mm = 10', r"h_ref_mm = 10; give 0 < h_ref_mm"),
        (
            '[milling."c45-KIENZLE"]\nfrom_kienzle = "C45"\nh_ref_mm = 0.1',
            r"is already in the library; give your entry another name",
        ),
        ("[turning.x]\nkc = 1", r"unknown tables \['turning'\]; valid: milling, kienzle"),
        ("[milling.x\n", r"mine\.toml: "),
    ],
)
def test_a_bad_user_file_is_one_line_naming_the_place_and_the_valid_range(
    tmp_path: Path, text: str, expected: str
) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(ConfigError, match=expected) as caught:
        load_materials(path)
    message = str(caught.value)
    assert "\n" not in message and str(path) in message


def test_a_missing_user_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="absent.toml"):
        load_materials(tmp_path / "absent.toml")


def _means() -> tuple[np.ndarray, np.ndarray]:
    rows = [line for line in MEANS.read_text().splitlines() if not line.startswith("#")]
    data = np.array([[float(v) for v in row.split(",")] for row in rows[1:]])
    return data[:, 0] * 1e-3, data[:, 1:]


def test_identify_output_round_trips_through_a_user_file(tmp_path: Path) -> None:
    # The documented way to add one's own: identify from mean forces, write the entry, load it.
    # Reference: the library's kistler entry, identified from the full dynamometer records
    # (tests/mechanics/test_kistler_validation.py); the example CSV is their per-feed means.
    feeds_m, forces_n = _means()
    fit = identify_coefficients(feeds_m, forces_n, teeth=2, depth_m=3e-3)
    text = milling_entry_toml(
        "shop slot", fit.coefficients, source="means of the Kistler records", conditions="slot"
    )
    library = load_materials(_write(tmp_path, text))
    loaded = library.milling_material("shop slot")
    assert loaded.checked and loaded.conditions == "slot"
    reference = packaged_materials().milling_material("kistler-slot-6000rpm").coefficients
    for key, value in loaded.coefficients.to_n_mm().items():
        assert value == pytest.approx(reference.to_n_mm()[key], rel=1e-3), key
    # 6 significant digits in the file: the loaded entry predicts the fit's forces.
    cutter = Cutter.flat(25.0, 30.0, flutes=2, helix_rad=math.radians(30))
    cut = ImmersionIntervals.from_angles(0.0, math.pi, 3e-3)
    for feed, predicted in zip(feeds_m, fit.predicted_n, strict=True):
        mean = mean_forces(cutter, loaded.coefficients, cut, float(feed), 600.0)
        assert (mean.fx_n, mean.fy_n, mean.fz_n) == pytest.approx(tuple(predicted), abs=1e-3)


def test_the_kistler_entry_reproduces_the_measured_mean_forces() -> None:
    # Real measurement (in-sample: the entry was identified from these records): the largest
    # force, Fy, within 5 % at every feed; Fx and Fz within 7.5 N (they level off above
    # 0.1 mm/tooth, which a linear model cannot follow).
    feeds_m, forces_n = _means()
    entry = packaged_materials().milling_material("kistler-slot-6000rpm")
    cutter = Cutter.flat(25.0, 30.0, flutes=2, helix_rad=math.radians(30))
    cut = ImmersionIntervals.from_angles(0.0, math.pi, 3e-3)
    for feed, measured in zip(feeds_m, forces_n, strict=True):
        mean = mean_forces(cutter, entry.coefficients, cut, float(feed), 600.0)
        assert mean.fy_n == pytest.approx(measured[1], rel=0.05)
        assert abs(mean.fx_n - measured[0]) < 7.5 and abs(mean.fz_n - measured[2]) < 7.5


# ISCAR's material-group table (ISO 513 / VDI 3323 groups), as printed in the 2017 turning
# catalogue, p. 558: entry -> (Kc1 N/mm^2, mc, group numbers). Read second-hand (page text).
ISCAR_2017 = {
    "stainless-austenitic": (2150.0, 0.20, "14"),
    "stainless-martensitic": (1875.0, 0.21, "12 and 13"),
    "GJS-ferritic": (1225.0, 0.25, "17"),
    "GJS-pearlitic": (1350.0, 0.28, "18"),
    "tool-steel-annealed": (2450.0, 0.23, "10"),
    "tool-steel-hardened": (2500.0, 0.23, "11"),
    "aluminium-wrought-hardenable": (800.0, 0.25, "22"),
    "aluminium-cast-AlSi": (700.0, 0.25, "23 and 24"),
    "aluminium-cast-AlSi-over-12": (750.0, 0.25, "25"),
    "brass": (700.0, 0.27, "27"),
    "copper-electrolytic": (700.0, 0.27, "28"),
    "titanium-CP": (1700.0, 0.23, "36"),
    "titanium-alpha-beta": (2110.0, 0.22, "37"),
    "nickel-cobalt-heat-resistant": (3300.0, 0.24, "33 to 35"),
}


@pytest.mark.parametrize("name", sorted(ISCAR_2017))
def test_an_iscar_group_entry_keeps_the_printed_numbers_and_states_its_source(name: str) -> None:
    # A transcription check (the numbers as printed, the place they were read), not an
    # independent one: no worked example accompanies the table in the copies read.
    kc1, mc, groups = ISCAR_2017[name]
    library = packaged_materials()
    entry = library.kienzle_material(name)
    assert entry.kc11_pa == pytest.approx(kc1 * 1e6, rel=1e-12) and entry.mc == mc
    assert not entry.checked
    source = " ".join(entry.source.split())
    assert "ISCAR" in source and "VDI 3323" in source and f"group No. {groups}," in source
    assert "katalog-tokarnyj-instrument-2017-page558" in source
    assert "Second-hand" in entry.note and "cut off" in entry.conditions
    # The derived milling entry: Kienzle's tangent at h_ref = 0.1 mm, tangential terms only.
    derived = library.milling_material(f"{name}-kienzle")
    assert derived.coefficients == kienzle_milling_coefficients(kc1 * 1e6, mc, 0.1e-3)
    assert derived.source == entry.source and not derived.checked


def test_the_titanium_notes_quantify_the_catalogues_disagreement() -> None:
    # ISCAR's 2022 boring-systems catalogue prints other titanium values (Kc1, mc): the notes
    # state how much less cutting force they give at h = 0.1 mm (Kienzle: kc1 h^(1 - mc)).
    printed_2022 = {"titanium-CP": (1160.0, 0.24), "titanium-alpha-beta": (1245.0, 0.24)}
    library = packaged_materials()
    for name, (kc1_2022, mc_2022) in printed_2022.items():
        kc1, mc, _ = ISCAR_2017[name]
        ratio = (kc1_2022 * 0.1 ** (1 - mc_2022)) / (kc1 * 0.1 ** (1 - mc))
        note = " ".join(library.kienzle_material(name).note.split())
        assert f"Kc1 = {kc1_2022:g} N/mm^2 and mc = {mc_2022:g}" in note
        assert f"give {round(100 * (1 - ratio))} % less cutting force" in note, (name, ratio)
