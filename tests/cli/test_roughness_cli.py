"""``cnctwin roughness fit`` and ``predict``: JSON keys, exact recovery, model files, errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cnctwin.cli.roughness import app
from cnctwin.errors import DataError

# A power law with known coefficients (b0 = 0.52; ap 0.4, S 0.05, fz 0.55, V 0.17).
TRUTH = {"ap_mm": 0.4, "spindle_rpm": 0.05, "fz_mm": 0.55, "vibration_g": 0.17}
B0 = 0.52


def invoke(*argv: str) -> tuple[int, str, BaseException | None]:
    result = CliRunner().invoke(app, list(argv))
    error = result.exception
    if error is not None and isinstance(error, SystemExit):
        error = None
    return result.exit_code, result.output, error


def _synthetic_csv(path: Path, rows: int = 20) -> Path:
    rng = np.random.default_rng(11)
    lines = ["cut,ap_mm,spindle_rpm,fz_mm,vibration_g,vibration_dt_g,ra_um"]
    for i in range(rows):
        ap, s, fz, v = (
            rng.uniform(1, 4),
            rng.uniform(3000, 9500),
            rng.uniform(0.05, 0.1),
            rng.uniform(1, 5),
        )
        ra = B0 * ap**0.4 * s**0.05 * fz**0.55 * v**0.17
        lines.append(f"{i},{ap!r},{s!r},{fz!r},{v!r},{v * 1.1!r},{ra!r}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_fit_json_recovers_a_synthetic_power_law(tmp_path: Path) -> None:
    data = _synthetic_csv(tmp_path / "cuts.csv")
    code, out, error = invoke("fit", str(data), "--json")
    assert error is None and code == 0
    assert out.count("\n") == 1
    report = json.loads(out)
    assert {"b0", "exponents", "r2", "mape_percent", "rmse", "target", "samples"} <= set(report)
    assert report["b0"] == pytest.approx(B0, rel=1e-9)
    assert report["ln_b0"] == pytest.approx(math.log(B0), abs=1e-9)
    assert list(report["exponents"]) == list(TRUTH)
    assert report["exponents"] == pytest.approx(TRUTH, abs=1e-10)
    assert report["r2"] == pytest.approx(1.0, abs=1e-12)
    assert report["mape_percent"] == pytest.approx(0.0, abs=1e-8)
    assert report["target"] == "ra_um" and report["samples"] == 20


def test_fit_other_columns_and_text_output(tmp_path: Path) -> None:
    data = _synthetic_csv(tmp_path / "cuts.csv")
    code, out, error = invoke("fit", str(data), "--features", "ap_mm,fz_mm,vibration_dt_g")
    assert error is None and code == 0
    assert "exponent of vibration_dt_g" in out and "MAPE" in out and "RMSE" in out


def test_predict_with_the_papers_eq24_model_file(tmp_path: Path) -> None:
    # Royandi 2026 Eq. 24: printed constant ln(b0) = 1.216292, exponents of ap, S, fz, V.
    model = tmp_path / "eq24.json"
    exponents = dict(zip(TRUTH, (0.389456, 0.004973, 0.551936, 0.173492), strict=True))
    model.write_text(
        json.dumps({"target": "ra_um", "b0": math.exp(1.216292), "exponents": exponents})
    )
    # Table 3, first cut: ap 1.5 mm, 5500 rpm, fz 0.1 mm, measured V 1.949 g, Ra 1.454 um.
    code, out, error = invoke(
        "predict", "--model", str(model), "--ap-mm", "1.5", "--rpm", "5500", "--fz-mm", "0.1",
        "--vib-g", "1.949", "--json",
    )  # fmt: skip
    assert error is None and code == 0
    expected = math.exp(1.216292) * 1.5**0.389456 * 5500**0.004973 * 0.1**0.551936 * 1.949**0.173492
    result = json.loads(out)
    assert result["ra_um"] == pytest.approx(expected, rel=1e-12)
    assert result["inputs"] == {
        "ap_mm": 1.5,
        "spindle_rpm": 5500.0,
        "fz_mm": 0.1,
        "vibration_g": 1.949,
    }


def test_fit_then_predict_round_trip_with_named_values(tmp_path: Path) -> None:
    data = _synthetic_csv(tmp_path / "cuts.csv")
    _, out, _ = invoke(
        "fit", str(data), "--features", "ap_mm,spindle_rpm,fz_mm,vibration_dt_g", "--json"
    )
    model = tmp_path / "model.json"
    model.write_text(out)
    code, out, error = invoke(
        "predict", "--model", str(model), "--ap-mm", "2", "--rpm", "6000", "--fz-mm", "0.08",
        "--value", "vibration_dt_g=3.3",
    )  # fmt: skip
    assert error is None and code == 0
    # vibration_dt_g = 1.1 V in the synthetic file, so the law is B0 1.1^-0.17 ... V_dt^0.17.
    expected = B0 * 2**0.4 * 6000**0.05 * 0.08**0.55 * 3.0**0.17
    assert out.startswith("ra_um = ")
    assert float(out.split("=")[1]) == pytest.approx(expected, rel=1e-3)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "empty; give a header row"),
        ("ap_mm,fz_mm,ra_um\n", "no column 'spindle_rpm', 'vibration_g' (the header has"),
        (
            "ap_mm,spindle_rpm,fz_mm,vibration_g,ra_um\n1,5500,0.1,2,1.2\n\n2,5500,abc,2,1.3\n",
            ":4: column fz_mm: 'abc' is not a number",
        ),
        (
            "ap_mm,spindle_rpm,fz_mm,vibration_g,ra_um\n1,5500,0.1,-2,1.2\n",
            ":2: column vibration_g: '-2'; the power law needs values > 0",
        ),
        (
            "ap_mm,spindle_rpm,fz_mm,vibration_g,ra_um\n1,5500,0.1\n",
            ":2: 3 cells, no value for column 'vibration_g'",
        ),
        ("ap_mm,spindle_rpm,fz_mm,vibration_g,ra_um\n", "no data rows after the header"),
        (
            "ap_mm,spindle_rpm,fz_mm,vibration_g,ra_um\n1,5500,0.1,2,1.2\n2,5500,0.1,2,1.3\n",
            "2 samples for 5 coefficients",
        ),
    ],
)
def test_fit_bad_csv_is_one_line(tmp_path: Path, text: str, message: str) -> None:
    data = tmp_path / "bad.csv"
    data.write_text(text)
    code, _, error = invoke("fit", str(data))
    assert isinstance(error, DataError), error
    assert message in str(error)
    assert "\n" not in str(error)
    if ":" in message[:3]:
        assert str(error).startswith(f"{data}:")


@pytest.mark.parametrize(
    ("model", "args", "message"),
    [
        ("not json", [], "not a JSON model file"),
        ('{"b0": "x", "exponents": {}}', [], "b0 is 'x'"),
        ('{"b0": 1.0, "exponents": {"ap_mm": "a"}}', [], "give a number per feature"),
        ('{"b0": -1.0, "exponents": {"ap_mm": 1.0}}', [], "b0=-1.0"),
        (
            '{"b0": 1.0, "exponents": {"ap_mm": 1.0, "q": 1}}',
            ["--ap-mm", "1"],
            "needs q; give --value q=...",
        ),
        ('{"b0": 1.0, "exponents": {"fz_mm": 1.0}}', [], "needs fz_mm; give --fz-mm"),
        ('{"b0": 1.0, "exponents": {"fz_mm": 1.0}}', ["--value", "fz_mm"], "give NAME=NUMBER"),
        ('{"b0": 1.0, "exponents": {"fz_mm": 1.0}}', ["--fz-mm", "-0.1"], "'fz_mm' is -0.1"),
    ],
)
def test_predict_errors_are_one_line(
    tmp_path: Path, model: str, args: list[str], message: str
) -> None:
    path = tmp_path / "model.json"
    path.write_text(model)
    _, _, error = invoke("predict", "--model", str(path), *args)
    assert isinstance(error, DataError), error
    assert message in str(error)
    assert "\n" not in str(error)


def test_fit_with_the_issue_column_names(tmp_path: Path) -> None:
    """``roughness fit DATA.csv --target Ra --features ap,S,fz,V --json`` (issue 5, item 8)."""
    source = _synthetic_csv(tmp_path / "cuts.csv").read_text().splitlines()
    names = {"ap_mm": "ap", "spindle_rpm": "S", "fz_mm": "fz", "vibration_g": "V", "ra_um": "Ra"}
    header = ",".join(names.get(name, name) for name in source[0].split(","))
    data = tmp_path / "short.csv"
    data.write_text("\n".join([header, *source[1:]]) + "\n")
    code, out, error = invoke("fit", str(data), "--target", "Ra", "--features", "ap,S,fz,V",
                              "--json")  # fmt: skip
    assert error is None and code == 0
    report = json.loads(out)
    assert {"b0", "exponents", "r2", "mape_percent", "rmse"} <= set(report)
    assert report["target"] == "Ra"
    assert report["b0"] == pytest.approx(B0, rel=1e-9)
    assert report["exponents"] == pytest.approx({names[k]: v for k, v in TRUTH.items()}, abs=1e-10)
    assert list(report["exponents"]) == ["ap", "S", "fz", "V"]
