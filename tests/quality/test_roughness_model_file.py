"""The power-law model file: what ``roughness fit --json`` writes, read back, and refusals."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from cnctwin.errors import DataError
from cnctwin.quality.roughness import read_power_law_model


def test_model_file_round_trip(tmp_path: Path) -> None:
    # Royandi 2026, Eq. 24: ln(b0) = 1.216292 with the exponents of ap, S, fz and V.
    exponents = {"ap_mm": 0.125, "spindle_rpm": -0.372, "fz_mm": 0.442, "vibration_g": 0.273}
    path = tmp_path / "model.json"
    path.write_text(json.dumps({"b0": 3.374, "exponents": exponents, "r2": 0.9}))
    model = read_power_law_model(path)
    assert model.b0 == 3.374 and dict(model.exponents) == exponents
    assert model.target == "ra_um" and model.features == tuple(exponents)
    features = {"ap_mm": 2.0, "spindle_rpm": 1000.0, "fz_mm": 0.1, "vibration_g": 1.5}
    expected = 3.374 * 2.0**0.125 * 1000.0**-0.372 * 0.1**0.442 * 1.5**0.273
    assert float(model.predict(features)) == pytest.approx(expected, rel=1e-12)
    path.write_text(json.dumps({"b0": 1, "exponents": {"x": 1}, "target": "rz_um"}))
    assert read_power_law_model(path).target == "rz_um"
    path.write_text(json.dumps({"b0": 1, "exponents": {"x": 1}}))
    assert read_power_law_model(path, "ra").target == "ra"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{not json", "not a JSON model file"),
        ("[1, 2]", "not a roughness model"),
        ('{"b0": true, "exponents": {"x": 1}}', "b0 is True; give a number"),
        ('{"b0": 1, "exponents": {"x": "1"}}', "exponents is {'x': '1'}; give a number per"),
        ('{"b0": 1, "exponents": {"x": 1}, "target": 3}', "target is 3; give a name"),
        ('{"b0": -1, "exponents": {"x": 1}}', "b0=-1.0; give a finite constant > 0"),
        ('{"b0": 1, "exponents": {}}', "needs at least one feature exponent"),
    ],
)
def test_bad_model_files_name_the_file_and_the_fault(
    tmp_path: Path, text: str, message: str
) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(DataError) as caught:
        read_power_law_model(path)
    assert str(caught.value).startswith(f"{path}: ") and message in str(caught.value)
