"""The process-damping model file (``chatter calibrate-damping --json``), read back."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from cnctwin.dynamics.process_damping import read_damping_model
from cnctwin.errors import DataError


def test_royandi_fits_read_back_give_eq_17_to_19(tmp_path: Path) -> None:
    # Royandi 2026, Eq. 17-19 as the calibration's JSON rows (rpm, N, N, mm).
    rows = [
        {"spindle_rpm": 9500, "a_n": 1.20e4, "b_n": 3.10e5, "a0_mm": 0.46, "mape_percent": 3},
        {"spindle_rpm": 5500, "a_n": 2.10e3, "b_n": 6.10e5, "a0_mm": 0.42},
        {"spindle_rpm": 7500, "a_n": 6.20e3, "b_n": 1.25e5, "a0_mm": 0.50},
    ]
    path = tmp_path / "damping.json"
    path.write_text(json.dumps({"fits": rows, "axis": "y"}))
    model = read_damping_model(path)
    assert [round(f.spindle_rad_s * 30.0 / math.pi) for f in model.fits] == [5500, 7500, 9500]
    depth_m = 1.0e-3
    for rpm, a, b, a0_mm in ((5500, 2.10e3, 6.10e5, 0.42), (7500, 6.20e3, 1.25e5, 0.50)):
        expected = a + b * math.exp(-1.0 / a0_mm)
        assert model.gamma_n(depth_m, rpm * math.pi / 30.0) == pytest.approx(expected, rel=1e-12)
    # Halfway between 5500 and 7500 rpm, A, B and a0 are interpolated linearly (Sec. 6.4).
    a, b, a0_mm = (2.10e3 + 6.20e3) / 2, (6.10e5 + 1.25e5) / 2, (0.42 + 0.50) / 2
    gamma = model.gamma_n(depth_m, 6500 * math.pi / 30.0)
    assert gamma == pytest.approx(a + b * math.exp(-1.0 / a0_mm), rel=1e-12)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{oops", "not a damping model (JSONDecodeError"),
        ('{"rows": []}', "not a damping model (KeyError: 'fits')"),
        ('{"fits": [{"spindle_rpm": 5500, "a_n": 1, "b_n": 2}]}', "(KeyError: 'a0_mm')"),
        ('{"fits": [{"spindle_rpm": "x", "a_n": 1, "b_n": 2, "a0_mm": 1}]}', "(ValueError"),
        ('{"fits": []}', "needs at least one fitted speed"),
    ],
)
def test_bad_files_name_the_file_and_the_fault(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(DataError) as caught:
        read_damping_model(path)
    assert str(caught.value).startswith(f"{path}: ") and message in str(caught.value)
